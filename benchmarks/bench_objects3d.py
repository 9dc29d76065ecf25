"""Objects in 3D (issue 37; docs/design.md section 11): depth accuracy and cost.

Two parts, each printing its table:

- ``synthetic``: held-out synthetic 9x9 scenes (seeds 100, 101, ...; objects only, the background
  wall unlabelled) with their ground-truth labels as the result, the default estimator's
  disparity and the scene's camera. Per object: the relative error of its median depth (the PLY
  target: <= 1 %) and of its centroid's depth (the ``lfsam objects`` target: <= 2 %) against the
  exact points of the ground truth; the worst and the median over all objects; seconds for
  ``objects_in_3d`` (the disparity estimate included) and for the ground-truth disparity.
- ``hci``: HCI antinous (``../shared/data/hci_antinous``, skipped when absent): BadPix(0.07) and
  BadPix(0.03) of the default estimator over all pixels and over the pixels kept at the
  confidence threshold (:data:`lfsam.spatial.MIN_CONFIDENCE`), the share kept, and the share of
  gross errors left out (8-pixel border excluded, as the benchmark).

Run::

    python benchmarks/bench_objects3d.py [--scenes 5] [--size 240x320] [--device cpu]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

from lfsam.camera import back_project, camera_of
from lfsam.disparity import estimate_disparity
from lfsam.io import read_lightfield
from lfsam.objects3d import objects_in_3d
from lfsam.result import SegmentationResult
from lfsam.spatial import MIN_CONFIDENCE
from lfsam.synth import generate_scene

HCI = Path(__file__).resolve().parents[2] / "shared" / "data" / "hci_antinous"


def _sync(device: str) -> None:
    if device.startswith("cuda"):
        torch.cuda.synchronize()


def synthetic(scenes: int, size: tuple[int, int], device: str) -> None:
    median_errors, centroid_errors, seconds, gt_seconds = [], [], [], []
    for seed in range(100, 100 + scenes):
        lf = generate_scene(grid=(9, 9), size=size, seed=seed, num_objects=6,
                            label_background=False)
        camera = camera_of(lf.meta)
        result = SegmentationResult(labels=lf.labels)
        _sync(device)
        start = time.perf_counter()
        found = objects_in_3d(result, lf, device=device)
        _sync(device)
        seconds.append(time.perf_counter() - start)
        start = time.perf_counter()
        objects_in_3d(result, lf, disparity="gt", device=device)
        gt_seconds.append(time.perf_counter() - start)
        center = lf.labels[lf.center]
        for measure in found.measures:
            rows, cols = np.nonzero(center == measure.object_id)
            truth = back_project(rows, cols, lf.disparity[lf.center][rows, cols], camera,
                                 lf.view_shape)
            median_errors.append(abs(measure.median_depth_m / np.median(truth[:, 2]) - 1))
            centroid_errors.append(abs(measure.centroid_m[2] / truth[:, 2].mean() - 1))
    median_errors, centroid_errors = np.array(median_errors), np.array(centroid_errors)
    print(f"\nsynthetic: {scenes} held-out 9x9 scenes of {size[0]}x{size[1]} (seeds 100-"
          f"{99 + scenes}), {len(median_errors)} objects, estimated disparity, device {device}")
    print("| quantity | median | worst | target |")
    print("|---|---|---|---|")
    print(f"| median depth relative error | {100 * np.median(median_errors):.3f} % | "
          f"{100 * median_errors.max():.3f} % | <= 1 % "
          f"({int((median_errors <= 0.01).sum())}/{len(median_errors)} met) |")
    print(f"| centroid depth relative error | {100 * np.median(centroid_errors):.3f} % | "
          f"{100 * centroid_errors.max():.3f} % | <= 2 % "
          f"({int((centroid_errors <= 0.02).sum())}/{len(centroid_errors)} met) |")
    print(f"| seconds per scene, estimate | {np.median(seconds):.2f} | {max(seconds):.2f} | |")
    print(f"| seconds per scene, gt disparity | {np.median(gt_seconds):.3f} | "
          f"{max(gt_seconds):.3f} | |")


def hci(device: str) -> None:
    if not HCI.is_dir():
        print(f"\nhci: skipped, {HCI} not found")
        return
    lf = read_lightfield(HCI)
    _sync(device)
    start = time.perf_counter()
    estimate = estimate_disparity(lf, device=device)
    _sync(device)
    took = time.perf_counter() - start
    truth = lf.disparity if lf.disparity.ndim == 2 else lf.disparity[lf.center]
    border = 8
    error = np.abs(estimate.disparity - truth)[border:-border, border:-border]
    confidence = estimate.confidence[border:-border, border:-border]
    kept = confidence >= MIN_CONFIDENCE
    bad = error > 0.07
    print(f"\nhci: antinous, default estimator on {device}: {took:.1f} s")
    print("| pixels | share | BadPix(0.07) | BadPix(0.03) |")
    print("|---|---|---|---|")
    print(f"| all | 100 % | {100 * bad.mean():.2f} % | {100 * (error > 0.03).mean():.2f} % |")
    print(f"| confidence >= {MIN_CONFIDENCE} | {100 * kept.mean():.1f} % | "
          f"{100 * bad[kept].mean():.2f} % | {100 * (error[kept] > 0.03).mean():.2f} % |")
    print(f"gross errors (> 0.07) left out by the threshold: "
          f"{100 * (bad & ~kept).sum() / max(bad.sum(), 1):.1f} %; target BadPix(0.07) <= 5 % "
          "over all pixels of held-out HCI scenes")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="synthetic,hci")
    parser.add_argument("--scenes", type=int, default=5)
    parser.add_argument("--size", default="240x320", help="rows x columns of the views")
    parser.add_argument("--device", default="cpu")
    args = parser.parse_args(argv)
    size = tuple(int(v) for v in args.size.split("x"))
    print(f"bench_objects3d: torch {torch.__version__}, {torch.get_num_threads()} threads")
    parts = args.parts.split(",")
    if "synthetic" in parts:
        synthetic(args.scenes, size, args.device)
    if "hci" in parts:
        hci(args.device)


if __name__ == "__main__":
    main()
