# lfsam — the two commands for a newcomer: `make demo` and `make test`.
# Each creates .venv in the repo if needed and installs everything by itself.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.lfsam-installed

.PHONY: install demo test lint bench clean

install: $(STAMP)

# torch + torchvision first; then Meta's sam2, whose build imports torch, without build isolation
# and without its optional CUDA extension; then this package with its dev extras.
$(STAMP): pyproject.toml constraints.txt
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade "pip>=23" setuptools wheel
	$(PY) -m pip install --quiet -c constraints.txt torch torchvision
	SAM2_BUILD_CUDA=0 SAM2_BUILD_ALLOW_ERRORS=1 $(PY) -m pip install --quiet --no-build-isolation -c constraints.txt sam2
	$(PY) -m pip install --quiet -c constraints.txt -e ".[dev]"
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/lfsam demo --out demo_output

test: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks
	$(VENV)/bin/python -m pytest -q

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests benchmarks

bench: $(STAMP)
	$(VENV)/bin/python benchmarks/run_all.py

clean:
	rm -rf $(VENV) demo_output .pytest_cache
