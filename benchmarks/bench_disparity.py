"""Disparity benchmark (issue 3): ours vs a plain single-scale structure tensor.

Prints MSE x 100 and BadPix(0.07) (percent of pixels with |error| > 0.07) against ground truth
on generated scenes with disparities of about +-1 and +-3 px per view and on
../shared/data/hci_antinous, a border band of 8 pixels excluded for every method, plus the
time of each: ours (default: with the edge-aware refinement), ours without the refinement (to
show that it helps), and the plain single-scale structure tensor. Then the time of ours on
9x9x480x640 light fields (range found from the data, and a given +-3 range).

When plenpy is importable (the NumPy structure tensor the paper's authors used; not a dependency
of lfsam: ``pip install plenpy "setuptools<81"``), its ``LightField.get_disparity()`` with its
defaults (structure tensor, TV-L1 fusion), clipped to the same range, is measured side by side.

Usage: python benchmarks/bench_disparity.py [--size 240x320] [--timing-size 480x640] [--no-real]
"""

from __future__ import annotations

import argparse
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


def plenpy_disparity(views: np.ndarray, disparity_range: tuple[float, float]) -> np.ndarray | None:
    """plenpy's default structure-tensor disparity of the center view, or None without plenpy."""
    try:
        from plenpy.lightfields import LightField as PlenpyLightField
    except ImportError:
        return None
    # plenpy's axes are (view row, view column, row, column, channel), like ours
    field = PlenpyLightField(views.astype(np.float32) / 255.0)
    disparity, _ = field.get_disparity(vmin=disparity_range[0], vmax=disparity_range[1])
    return np.asarray(disparity, dtype=np.float32)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="240x320", help="synthetic view size, rows x columns")
    parser.add_argument("--timing-size", default="480x640",
                        help="view size of the 9x9 timing runs, rows x columns")
    parser.add_argument("--no-real", action="store_true", help="skip hci_antinous")
    args = parser.parse_args()
    size = tuple(int(x) for x in args.size.split("x"))
    timing_size = tuple(int(x) for x in args.timing_size.split("x"))
    torch.set_num_threads(2)
    cases = [
        ("synthetic +-1", generate_scene(grid=(9, 9), size=size, seed=10,
                                         disparity_range=(-1.0, 1.0))),
        ("synthetic +-3", generate_scene(grid=(9, 9), size=size, seed=11,
                                         disparity_range=(-3.0, 3.0))),
    ]
    if args.no_real:
        pass
    elif SHARED.is_dir():
        from lfsam.io import read_lightfield

        cases.append(("hci_antinous", read_lightfield(SHARED)))
    else:
        print(f"(skipping antinous: {SHARED} not found)")
    try:
        import plenpy  # noqa: F401
    except ImportError:
        print('(plenpy not installed: pip install plenpy "setuptools<81" to compare with it)')
    print(f"{'scene':16s} {'method':12s} {'MSEx100':>10s} {'BadPix%':>8s} {'seconds':>8s}")
    for name, lf in cases:
        truth = lf.center_disparity
        start = time.perf_counter()
        ours = estimate_disparity(lf)
        ours_s = time.perf_counter() - start
        start = time.perf_counter()
        unrefined = estimate_disparity(lf, ours.disparity_range, edge_refinement=False)
        unrefined_s = time.perf_counter() - start
        start = time.perf_counter()
        # the baseline is clipped to the range ours searched (plenpy clips to vmin, vmax)
        plain = estimate_disparity_baseline(lf, disparity_range=ours.disparity_range)
        plain_s = time.perf_counter() - start
        mse_o, bad_o = scores(ours.disparity, truth)
        mse_p, bad_p = scores(plain.disparity, truth)
        mse_u, bad_u = scores(unrefined.disparity, truth)
        print(f"{name:16s} {'ours':12s} {mse_o:10.3f} {bad_o:8.2f} {ours_s:8.2f}")
        print(f"{name:16s} {'ours no-edge':12s} {mse_u:10.3f} {bad_u:8.2f} {unrefined_s:8.2f}")
        print(f"{name:16s} {'plain ST':12s} {mse_p:10.3f} {bad_p:8.2f} {plain_s:8.2f}")
        start = time.perf_counter()
        plen = plenpy_disparity(lf.views, ours.disparity_range)
        plen_s = time.perf_counter() - start
        if plen is not None:
            mse_q, bad_q = scores(plen, truth)
            print(f"{name:16s} {'plenpy':12s} {mse_q:10.3f} {bad_q:8.2f} {plen_s:8.2f}")
            print(f"{name:16s} ratio ours/plenpy: MSE {mse_o / mse_q:.2f}, BadPix "
                  f"{bad_o / bad_q:.2f}, time {ours_s / plen_s:.2f}")
        print(f"{name:16s} ratio ours/plain: MSE {mse_o / mse_p:.2f} (target <= 0.25 at +-3), "
              f"BadPix {bad_o / bad_p:.2f} (target <= 0.5 at +-3); range searched "
              f"{ours.disparity_range[0]:g}..{ours.disparity_range[1]:g}")
    views = np.random.default_rng(0).integers(0, 256, size=(9, 9, *timing_size, 3), dtype=np.uint8)
    for given in (None, (-3.0, 3.0)):
        start = time.perf_counter()
        estimate = estimate_disparity(views, given, device="cpu")
        lo, hi = estimate.disparity_range
        print(f"ours on 9x9x{timing_size[0]}x{timing_size[1]} (random texture, "
              f"range {lo:g}..{hi:g} "
              f"{'given' if given else 'found'}, {len(estimate.meta['candidates'])} candidates): "
              f"{time.perf_counter() - start:.2f} s (target < 10 s)")


if __name__ == "__main__":
    main()
