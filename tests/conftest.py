"""Shared test fixtures."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import settings

# Property tests draw the same examples every run (``derandomize``), so `make test` and CI
# pass or fail alike on every machine (a fresh draw found a new counterexample in CI's clean
# clone: tests/test_mask_disparity.py); `HYPOTHESIS_PROFILE=explore make test` draws fresh
# random examples each run to look for more (keep any found as an ``@example``).
settings.register_profile("repeatable", derandomize=True, print_blob=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "repeatable"))

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"

# OpenMP threads that sleep while they wait (as `import lfsam` sets it; set here too in case a
# test module imports torch first): spinning threads of two processes starve each other.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

# `make test` runs the suite in two worker processes (pytest-xdist, `-n 2 --dist worksteal`), one
# per core of the 2-core machines it runs on: each worker, and every process a test starts,
# computes with one thread, so the two workers never compete for a core (docs/performance.md,
# "`make test` in two processes").
if os.environ.get("PYTEST_XDIST_WORKER"):
    for variable in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[variable] = "1"
    import torch

    torch.set_num_threads(1)


@pytest.fixture
def shared_data() -> Path:
    """``../shared/data`` next to the repo; skips the test with a message when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real light fields not found at {SHARED_DATA} (only present beside the repo)")
    return SHARED_DATA


def pytest_collection_modifyitems(config, items):
    """Tests marked ``cuda`` need a CUDA GPU: skipped with a note without one (make gpu-check)."""
    import torch

    if torch.cuda.is_available():
        return
    skip = pytest.mark.skip(reason="needs a CUDA GPU (run `make gpu-check` on a GPU machine)")
    for item in items:
        if "cuda" in item.keywords:
            item.add_marker(skip)
