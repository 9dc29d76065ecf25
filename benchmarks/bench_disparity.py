"""Disparity benchmark (issue 3): ours vs a plain single-scale structure tensor.

Prints MSE x 100 and BadPix(0.07) (percent of pixels with |error| > 0.07) against ground truth
on generated scenes with disparities of about +-1 and +-3 px per view and on
../shared/data/hci_antinous, a border band of 8 pixels excluded for both methods, plus the
time of each, and the time of ours on a 9x9x480x640 light field.

Usage: python benchmarks/bench_disparity.py
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import torch

from lfsam.disparity import estimate_disparity
from lfsam.disparity.baseline import estimate_disparity_baseline
from lfsam.synth import generate_scene

BORDER = 8
SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "hci_antinous"


def scores(estimate: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """MSE x 100 and BadPix(0.07) in percent over finite ground truth, border excluded."""
    err = (estimate - truth)[BORDER:-BORDER, BORDER:-BORDER]
    err = err[np.isfinite(err)]
    return 100.0 * float(np.mean(err**2)), 100.0 * float(np.mean(np.abs(err) > 0.07))


def main() -> None:
    torch.set_num_threads(2)
    cases = [
        ("synthetic +-1", generate_scene(grid=(9, 9), size=(240, 320), seed=10,
                                         disparity_range=(-1.0, 1.0))),
        ("synthetic +-3", generate_scene(grid=(9, 9), size=(240, 320), seed=11,
                                         disparity_range=(-3.0, 3.0))),
    ]
    if SHARED.is_dir():
        from lfsam.io import read_lightfield

        cases.append(("hci_antinous", read_lightfield(SHARED)))
    else:
        print(f"(skipping antinous: {SHARED} not found)")
    print(f"{'scene':16s} {'method':12s} {'MSEx100':>10s} {'BadPix%':>8s} {'seconds':>8s}")
    for name, lf in cases:
        truth = lf.center_disparity
        for method, run in (("ours", lambda lf=lf: estimate_disparity(lf).disparity),
                            ("plain ST", lambda lf=lf: estimate_disparity_baseline(lf))):
            start = time.perf_counter()
            out = run()
            seconds = time.perf_counter() - start
            out = getattr(out, "disparity", out)
            mse, bad = scores(np.asarray(out), truth)
            print(f"{name:16s} {method:12s} {mse:10.3f} {bad:8.2f} {seconds:8.2f}")
    views = np.random.default_rng(0).integers(0, 256, size=(9, 9, 480, 640, 3), dtype=np.uint8)
    start = time.perf_counter()
    estimate_disparity(views)
    print(f"ours on 9x9x480x640 (random texture): {time.perf_counter() - start:.2f} s "
          "(target < 10 s)")


if __name__ == "__main__":
    main()
