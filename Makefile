# lfsam — the two commands for a newcomer: `make demo` and `make test`.
# Each creates .venv in the repo if needed and installs everything by itself.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.lfsam-installed

.PHONY: install demo test lint bench bench-guard clean system-deps gpu-deps gpu-env gpu-check gpu-track

install: $(STAMP)

# torch + torchvision first; then Meta's sam2, whose build imports torch, without build isolation
# and without its optional CUDA extension; then this package with its dev extras. pip does not
# compile every installed file (--no-compile: half of a fresh install's time went to modules
# lfsam never imports); tools/compile_bytecode.py writes the bytecode of what lfsam imports.
PIP_INSTALL := $(PY) -m pip install --quiet --no-compile
$(STAMP): pyproject.toml constraints.txt
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PIP_INSTALL) --upgrade "pip>=23" setuptools wheel
	$(PIP_INSTALL) -c constraints.txt torch torchvision
	SAM2_BUILD_CUDA=0 SAM2_BUILD_ALLOW_ERRORS=1 $(PIP_INSTALL) --no-build-isolation -c constraints.txt sam2
	$(PIP_INSTALL) -c constraints.txt -e ".[dev]"
	@# the viewer moved to Qt 6: a PyQt5 left in an older .venv would still be picked by qtpy
	-@$(PY) -m pip uninstall --quiet -y PyQt5 PyQt5-Qt5 PyQt5-sip >/dev/null 2>&1
	$(PY) tools/compile_bytecode.py
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/lfsam demo --out demo_output

test: $(STAMP) system-deps
	$(VENV)/bin/ruff check .
	$(VENV)/bin/lint-imports
	@# bytecode written for whatever a test imports first (PYTHONDONTWRITEBYTECODE unset for it)
	env -u PYTHONDONTWRITEBYTECODE xvfb-run -a $(VENV)/bin/python -m pytest -q -n 2 --dist worksteal

lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/lint-imports

bench: $(STAMP)
	$(VENV)/bin/python benchmarks/run_all.py

# The default commands a user runs, timed whole in fresh processes (median of 3) beside the
# figures recorded in docs/performance.md ("Speed guard"); run it alone.
bench-guard: $(STAMP)
	$(VENV)/bin/python benchmarks/guard.py

# System packages the viewer tests need (napari under a virtual X display with Mesa's OpenGL;
# Qt's offscreen platform has no OpenGL). Installed with apt-get only when some are missing.
SYSTEM_DEPS := xvfb xauth libgl1-mesa-dri libglx-mesa0 libegl1 libxcb-icccm4 libxcb-image0 \
	libxcb-keysyms1 libxcb-randr0 libxcb-render-util0 libxcb-xinerama0 libxcb-xfixes0 \
	libxcb-shape0 libxkbcommon-x11-0 libxcb-cursor0 libdbus-1-3

system-deps:
	@if ! command -v dpkg-query >/dev/null 2>&1; then \
		command -v xvfb-run >/dev/null 2>&1 || { echo "make: xvfb-run not found; install Xvfb, xauth, Mesa GL and the Qt xcb libraries (see README)" >&2; exit 1; }; \
		echo "system-deps: no dpkg here; using the xvfb-run found on PATH"; exit 0; \
	fi; \
	missing=$$(for p in $(SYSTEM_DEPS); do dpkg-query -W -f='$${Status}\n' $$p 2>/dev/null | grep -q 'install ok installed' || echo $$p; done); \
	if [ -z "$$missing" ]; then echo "system-deps: all present"; exit 0; fi; \
	missing=$$(echo $$missing); \
	if [ "$$(id -u)" != 0 ]; then echo "make: missing system packages: $$missing; run as root: apt-get install $$missing" >&2; exit 1; fi; \
	echo "system-deps: installing $$missing"; \
	apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing >/dev/null

# A GPU machine has no package registry (docs/performance.md, "GPU (H100)"). Here, with one:
# `make gpu-deps` fills gpu-deps/ (ignored by git, at most 60 MiB) with wheels of everything such
# a machine lacks besides its own CUDA PyTorch and scientific base (tools/gpu_deps.py: sam2 built
# without its CUDA extension, hydra-core, omegaconf, iopath, pycocotools, transformers, timm,
# pytest, ...; never torch), pinned in gpu-deps/constraints.txt, for the Pythons in GPU_PYTHONS.
GPU_PYTHONS ?= 3.11,3.12,3.13
gpu-deps: $(STAMP)
	$(PY) tools/gpu_deps.py --out gpu-deps --pythons $(GPU_PYTHONS)

# There, with gpu-deps/ carried along: `make gpu-check` makes a venv that sees the machine's own
# CUDA PyTorch (--system-site-packages of GPU_PYTHON, plus a .pth naming GPU_PYTHON's own
# site-packages, as a GPU image's python3 is often itself a venv, e.g. /opt/torch/.venv, whose
# packages a venv made from it would not see; GPU_VENV= installs into GPU_PYTHON's own
# environment instead), installs lfsam and exactly the wheels carried (no registry, and no
# dependency resolution that could touch the machine's torch and its CUDA packages), checks
# that torch sees the GPU, then runs the CUDA-marked tests and the GPU benchmark (with its
# profile), which writes its numbers to docs/gpu_results.json, and times the tracker's search
# for lost objects at the full size (issue 47: whole frame and the search's own share).
GPU_PYTHON ?= python3
GPU_VENV ?= .venv-gpu
GPU_PY := $(if $(GPU_VENV),$(GPU_VENV)/bin/python,$(GPU_PYTHON))
SITE_DIR := import sysconfig; print(sysconfig.get_path('purelib'))
SITE_DIRS := import sysconfig; print(*sorted({sysconfig.get_path(k) for k in ('purelib', 'platlib')}), sep=chr(10))
CUDA_OK := import sys, torch; ok = torch.cuda.is_available(); \
	print('torch', torch.__version__, '| CUDA build', torch.version.cuda, '| GPU:', \
	torch.cuda.get_device_name(0) if ok else 'none visible'); sys.exit(0 if ok else 1)
gpu-env:
	@test -f gpu-deps/constraints.txt || { echo "gpu-check: no gpu-deps/ here: run make gpu-deps" \
	  "on a machine with a package registry and bring the folder along" >&2; exit 1; }
	-nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv
	$(if $(GPU_VENV),test -x $(GPU_PY) || { $(GPU_PYTHON) -m venv --system-site-packages $(GPU_VENV) \
	  && $(GPU_PYTHON) -c "$(SITE_DIRS)" > "$$($(GPU_PY) -c "$(SITE_DIR)")/gpu_python_site.pth"; })
	@$(GPU_PY) -c "$(CUDA_OK)" || { echo "gpu-check: $(GPU_PY) has no torch that sees a CUDA" \
	  "GPU (no GPU, a CPU build, or a torch outside GPU_PYTHON's site-packages: set GPU_PYTHON)" >&2; exit 1; }
	$(GPU_PY) -m pip install --quiet --no-index --find-links gpu-deps --no-deps \
	  -r gpu-deps/constraints.txt -e .
	$(GPU_PY) -c "import lfsam, sam2, transformers, timm, pycocotools, pytest; print('gpu-check: lfsam', lfsam.__version__, 'from', lfsam.__file__)"

gpu-check: gpu-env
	$(GPU_PY) -m pytest -q -m cuda -rs $$(grep -l "pytest.mark.cuda" tests/test_*.py)
	$(GPU_PY) benchmarks/bench_gpu.py --profile --json docs/gpu_results.json
	$(MAKE) --no-print-directory gpu-track

# The tracker's search for lost objects at the full size, on the GPU (issue 47's cost split:
# the whole frame and the search's own share); `make gpu-track GPU_TRACK_SEEDS=1301,1701`
# runs it alone after `make gpu-env`.
GPU_TRACK_SEEDS ?= 1301
gpu-track: gpu-env
	$(GPU_PY) benchmarks/bench_tracking.py --device cuda --size 480x640 --min-pixels 2500 \
	  --frames 8 --seeds $(GPU_TRACK_SEEDS) --jitter 0 --modes search,before --repeat 2 \
	  --stages --ops \
	  $(if $(GPU_TRACK_JSON),--json $(GPU_TRACK_JSON))

clean:
	rm -rf $(VENV) $(GPU_VENV) gpu-deps demo_output .pytest_cache
