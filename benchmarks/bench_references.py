"""Automatic mode from several reference views (issue 16; docs/design.md section 8).

Two parts, each printing its table:

* ``speed`` — SAM 2.1 hiera-small with random weights (untrained: for timing only), automatic
  mode with ground-truth disparity on a synthetic scene *without* hidden objects, run with
  ``--references center`` (the paper's setting) and then with each extra mode. Prints the
  seconds of each run, its ratio to ``center`` (target <= 1.10), the points the extra views'
  generator was asked at, the masks it added, and whether every label equals the ``center``
  run's (target: identical). Each run encodes every view once (no cache shared between runs).
* ``quality`` — the oracle with ground-truth disparity on synthetic scenes *with* hidden objects
  (objects the center view cannot see): object recall (target 1.0 with ``corners``, below 1.0
  with ``center``), AA and UE (target: no worse than ``center``) per mode.

Usage::

    python benchmarks/bench_references.py [--parts speed,quality] [--grid 5x5] [--size 240x320]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from lfsam.api import run_segmentation
from lfsam.metrics import evaluate_result
from lfsam.segmenters import load_segmenter
from lfsam.synth import generate_scene


def _pair(text: str) -> tuple[int, int]:
    a, b = text.lower().split("x")
    return int(a), int(b)


def _count_generator_points(segmenter) -> list[int | None]:
    """Wrap ``segmenter.generate`` to record how many points each call asks at (None: the
    generator's own full grid, i.e. the center view)."""
    asked: list[int | None] = []
    generate = segmenter.generate

    def counting(embedding, image, points=None):
        asked.append(None if points is None else len(points))
        return generate(embedding, image, points=points)

    segmenter.generate = counting
    return asked


def speed(args: argparse.Namespace) -> None:
    lf = generate_scene(grid=args.grid, size=args.size, seed=args.seed, num_objects=args.objects)
    segmenter = load_segmenter(args.model, random_weights=True, device=args.device)
    asked = _count_generator_points(segmenter)
    points_per_side = int(getattr(segmenter, "amg_options", {}).get("points_per_side") or 32)
    print(f"speed: {args.model} (random weights) on {args.device}; {args.grid[0]}x{args.grid[1]} "
          f"views of {args.size[0]}x{args.size[1]}, {args.objects} objects, no hidden ones; "
          f"ground-truth disparity; generator grid {points_per_side}x{points_per_side}",
          flush=True)
    rows = []
    base = None
    for mode in ["center", *args.modes]:
        asked.clear()
        start = time.perf_counter()
        result = run_segmentation(lf, segmenter=segmenter, disparity="gt", references=mode,
                                  progress=False)
        seconds = time.perf_counter() - start
        if base is None:
            base = (seconds, result)
        extra_points = sum(n for n in asked if n is not None)
        extra_views = sum(1 for n in asked if n is not None)
        same = np.array_equal(result.labels, base[1].labels)
        rows.append((mode, seconds, seconds / base[0], result.num_masks,
                     result.num_masks - base[1].num_masks, extra_views, extra_points, same,
                     result.meta.get("views_encoded")))
        print(f"  {mode}: {seconds:.1f} s, {result.num_masks} masks", flush=True)
    print("\n| references | seconds | ratio to center | masks | added | extra views asked "
          "| points asked there | labels equal center | views encoded |")
    print("|---|---|---|---|---|---|---|---|---|")
    for mode, seconds, ratio, masks, added, views, points, same, encoded in rows:
        print(f"| {mode} | {seconds:.1f} | {ratio:.3f} | {masks} | {added} | {views} | {points} "
              f"| {'yes' if same else 'NO'} | {encoded} |")
    print(f"(a full grid in an extra view is {points_per_side ** 2} points)")


def quality(args: argparse.Namespace) -> None:
    grid = args.quality_grid
    print(f"\nquality: oracle, ground-truth disparity; {grid[0]}x{grid[1]} views of "
          f"{args.quality_size[0]}x{args.quality_size[1]}, seeds {args.quality_seeds}, "
          f"{args.hidden} hidden objects each", flush=True)
    modes = ["center", *args.modes]
    scores: dict[str, list[dict]] = {mode: [] for mode in modes}
    for seed in args.quality_seeds:
        lf = generate_scene(grid=grid, size=args.quality_size, seed=seed,
                            hidden_objects=args.hidden)
        for mode in modes:
            segmenter = load_segmenter("oracle", lightfield=lf, device="cpu")
            result = run_segmentation(lf, segmenter=segmenter, disparity="gt", references=mode,
                                      progress=False)
            scores[mode].append(evaluate_result(result, lf, device="cpu"))
    print("\n| references | recall | AA | UE | SIoU | SIoU (center-present masks) |")
    print("|---|---|---|---|---|---|")
    for mode in modes:
        mean = {k: float(np.mean([s[k] for s in scores[mode]]))
                for k in ("recall", "aa", "ue", "siou", "siou_center")}
        print(f"| {mode} | {mean['recall']:.3f} | {mean['aa']:.4f} | {mean['ue']:.4f} "
              f"| {mean['siou']:.4f} | {mean['siou_center']:.4f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="speed,quality")
    parser.add_argument("--modes", default="corners,ring",
                        help="extra modes compared with center, comma-separated")
    parser.add_argument("--grid", type=_pair, default=(5, 5), help="speed part")
    parser.add_argument("--size", type=_pair, default=(240, 320), help="speed part")
    parser.add_argument("--objects", type=int, default=6, help="speed part")
    parser.add_argument("--model", default="sam2.1-hiera-small")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quality-grid", type=_pair, default=(5, 5))
    parser.add_argument("--quality-size", type=_pair, default=(96, 128))
    parser.add_argument("--quality-seeds", default="0,1,2")
    parser.add_argument("--hidden", type=int, default=2)
    args = parser.parse_args()
    args.modes = [m for m in args.modes.split(",") if m and m != "center"]
    args.quality_seeds = [int(s) for s in args.quality_seeds.split(",")]
    parts = args.parts.split(",")
    if "speed" in parts:
        speed(args)
    if "quality" in parts:
        quality(args)
    print("bench_references: done", flush=True)


if __name__ == "__main__":
    main()
