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
        start = time.perf_counter()
        ours = estimate_disparity(lf)
        ours_s = time.perf_counter() - start
        start = time.perf_counter()
        # the baseline is clipped to the range ours searched (plenpy clips to vmin, vmax)
        plain = estimate_disparity_baseline(lf, disparity_range=ours.disparity_range)
        plain_s = time.perf_counter() - start
        mse_o, bad_o = scores(ours.disparity, truth)
        mse_p, bad_p = scores(plain.disparity, truth)
        print(f"{name:16s} {'ours':12s} {mse_o:10.3f} {bad_o:8.2f} {ours_s:8.2f}")
        print(f"{name:16s} {'plain ST':12s} {mse_p:10.3f} {bad_p:8.2f} {plain_s:8.2f}")
        print(f"{name:16s} ratio ours/plain: MSE {mse_o / mse_p:.2f} (target <= 0.25 at +-3), "
              f"BadPix {bad_o / bad_p:.2f} (target <= 0.5 at +-3); range searched "
              f"{ours.disparity_range[0]:g}..{ours.disparity_range[1]:g}")
    views = np.random.default_rng(0).integers(0, 256, size=(9, 9, 480, 640, 3), dtype=np.uint8)
    start = time.perf_counter()
    estimate_disparity(views, device="cpu")
    print(f"ours on 9x9x480x640 (random texture): {time.perf_counter() - start:.2f} s "
          "(target < 10 s)")


if __name__ == "__main__":
    main()
