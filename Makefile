# lfsam — the two commands for a newcomer: `make demo` and `make test`.
# Each creates .venv in the repo if needed and installs everything by itself.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.lfsam-installed

.PHONY: install demo test lint bench clean system-deps gpu-check

install: $(STAMP)

# torch + torchvision first; then Meta's sam2, whose build imports torch, without build isolation
# and without its optional CUDA extension; then this package with its dev extras.
$(STAMP): pyproject.toml constraints.txt
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade "pip>=23" setuptools wheel
	$(PY) -m pip install --quiet -c constraints.txt torch torchvision
	SAM2_BUILD_CUDA=0 SAM2_BUILD_ALLOW_ERRORS=1 $(PY) -m pip install --quiet --no-build-isolation -c constraints.txt sam2
	$(PY) -m pip install --quiet -c constraints.txt -e ".[dev]"
	@# the viewer moved to Qt 6: a PyQt5 left in an older .venv would still be picked by qtpy
	-@$(PY) -m pip uninstall --quiet -y PyQt5 PyQt5-Qt5 PyQt5-sip >/dev/null 2>&1
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/lfsam demo --out demo_output

test: $(STAMP) system-deps
	$(VENV)/bin/ruff check .
	$(VENV)/bin/lint-imports
	xvfb-run -a $(VENV)/bin/python -m pytest -q

lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/lint-imports

bench: $(STAMP)
	$(VENV)/bin/python benchmarks/run_all.py

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

# On a CUDA machine: check that the installed torch sees the GPU (PyPI's Linux torch wheels are
# CUDA builds; if the driver is too old for them, reinstall torch from the PyTorch index named
# by TORCH_CUDA_INDEX, e.g. make gpu-check TORCH_CUDA_INDEX=https://download.pytorch.org/whl/cu126),
# then the CUDA-marked tests and the GPU benchmark (docs/performance.md, "GPU (H100)").
TORCH_CUDA_INDEX ?=
CUDA_OK := import sys, torch; ok = torch.cuda.is_available(); \
	print('torch', torch.__version__, '| CUDA build', torch.version.cuda, '| GPU:', \
	torch.cuda.get_device_name(0) if ok else 'none visible'); sys.exit(0 if ok else 1)
gpu-check: $(STAMP)
	-nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv
	@$(PY) -c "$(CUDA_OK)" || { \
	  if [ -n "$(TORCH_CUDA_INDEX)" ]; then \
	    $(PY) -m pip uninstall --quiet -y torch torchvision && \
	    $(PY) -m pip install --quiet --index-url "$(TORCH_CUDA_INDEX)" -c constraints.txt \
	      torch torchvision && $(PY) -c "$(CUDA_OK)"; \
	  else \
	    echo "gpu-check: this torch sees no CUDA GPU (no GPU, or a driver older than its CUDA);" \
	      "rerun with TORCH_CUDA_INDEX=https://download.pytorch.org/whl/cuXYZ" >&2; exit 1; \
	  fi; }
	$(VENV)/bin/python -m pytest -q -m cuda -rs
	$(VENV)/bin/python benchmarks/bench_gpu.py

clean:
	rm -rf $(VENV) demo_output .pytest_cache
