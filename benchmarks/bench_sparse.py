"""Refining a few views instead of all (issue 24; docs/design.md section 3.7).

Two parts, each printing its table:

* ``accuracy`` — the oracle on 9x9 synthetic scenes (240x320 by default), automatic mode, for
  each ``--refine-views`` setting (``all``, ``sparse``, N in {5, 9, 13, 25}) with ground-truth
  disparity, and ``--estimate-settings`` (``all``, ``sparse``) with estimated disparity too,
  over ``--seeds`` scenes and ``--hidden`` scenes with a hidden object (found from the corner
  views, ``--references corners``): views encoded, mean and worst
  per-view IoU against the ground truth (:func:`lfsam.metrics.accuracy.per_view_iou`, the mean
  over seeds of each scene's mean and the worst view of any scene), SIoU and coverage. Targets
  (issue 24): ``sparse`` with estimated disparity reaches a mean per-view IoU >= 0.99 and no
  more than 0.005 below ``all``.
* ``speed`` — SAM 2.1 Hiera-S with random weights (untrained: for timing only) on the CPU, one
  9x9 scene, ``--prompts`` clicks (one per ground-truth object, in the center view), estimated
  disparity: end-to-end seconds of ``lfsam.segment`` per setting (the segmenter is built once),
  views encoded, and the speed-up over ``all`` (target for ``sparse``: >= 4.5x), after an
  untimed warm-up run.

Usage::

    python benchmarks/bench_sparse.py [--parts accuracy,speed] [--seeds 10] [--size 240x320]
        [--settings all,sparse,5,9,13,25] [--model sam2.1-hiera-small] [--prompts 16]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from lfsam.api import RunOptions, SegmentOptions, segment
from lfsam.errors import LfsamError
from lfsam.metrics import evaluate_result
from lfsam.metrics.accuracy import per_view_iou
from lfsam.pipeline import PipelineConfig
from lfsam.pipeline.sparse import check_refine_views
from lfsam.prompts import ObjectPrompts, PointPrompt
from lfsam.segmenters import load_segmenter
from lfsam.synth import generate_scene


def parse_size(text: str) -> tuple[int, int]:
    height, width = (int(x) for x in text.lower().split("x"))
    return height, width


def run(lf, settings, disparity, references="center", model="oracle", prompts=None):
    """One segmentation with ``refine_views=settings``; returns (result, seconds)."""
    options = SegmentOptions(
        pipeline=PipelineConfig(refine_views=settings),
        run=RunOptions(references=references, progress=False),
    )
    start = time.perf_counter()
    result = segment(lf, prompts, model=model, disparity=disparity, options=options)
    return result, time.perf_counter() - start


def accuracy_part(args: argparse.Namespace) -> None:
    size = parse_size(args.size)
    print(f"\n## accuracy: oracle, automatic, 9x9 views of {size[0]}x{size[1]}, "
          f"seeds 0..{args.seeds - 1} + {args.hidden} scenes with a hidden object (--references "
          "corners)\n")
    print("| disparity | refine views | views encoded | mean vIoU | worst vIoU | SIoU | C | s |")
    print("|---|---|---|---|---|---|---|---|")
    scenes = []
    for seed in range(args.seeds):
        scenes.append((generate_scene(grid=(9, 9), size=size, seed=seed), "center"))
    hidden = 0
    seed = 1000
    while hidden < args.hidden and seed < 1000 + 4 * max(args.hidden, 1):
        try:
            lf = generate_scene(grid=(9, 9), size=size, seed=seed, hidden_objects=1)
        except LfsamError as exc:  # the scene cannot hide an object
            print(f"(seed {seed} skipped: {exc})", file=sys.stderr)
        else:
            scenes.append((lf, "corners"))
            hidden += 1
        seed += 1
    summary = {}
    for disparity in args.disparities.split(","):
        for settings in args.settings:
            if disparity == "estimate" and settings not in args.estimate_settings:
                continue
            means, worsts, sious, covers, encoded, seconds = [], [], [], [], [], []
            for lf, references in scenes:
                result, took = run(lf, settings, disparity, references)
                acc = per_view_iou(result.labels, lf.labels, _references(result))
                metrics = evaluate_result(result, lf, device="cpu")
                means.append(acc.mean)
                worsts.append(acc.worst)
                sious.append(metrics["siou"])
                covers.append(metrics["coverage"])
                encoded.append(result.meta["views_encoded"])
                seconds.append(took)
            summary[(disparity, settings)] = float(np.mean(means))
            print(
                f"| {disparity} | {settings} | {np.mean(encoded):.1f} | {np.mean(means):.4f} | "
                f"{np.min(worsts):.4f} | {np.mean(sious):.4f} | {np.mean(covers):.4f} | "
                f"{np.mean(seconds):.2f} |",
                flush=True,
            )
    for disparity in args.disparities.split(","):
        if (disparity, "all") in summary and (disparity, "sparse") in summary:
            gap = summary[(disparity, "all")] - summary[(disparity, "sparse")]
            print(f"\n{disparity} disparity: sparse mean vIoU {summary[(disparity, 'sparse')]:.4f}"
                  f" (target >= 0.99), {gap:.4f} below all (target <= 0.005)")


def _references(result) -> dict[int, tuple[int, int]]:
    return {
        int(entry["id"]): tuple(entry["reference_view"])
        for entry in result.meta.get("objects", [])
        if "reference_view" in entry
    }


def click_prompts(lf, count: int) -> list[ObjectPrompts]:
    """One click per ground-truth object in the center view (its deepest pixel), up to
    ``count``, largest objects first."""
    from scipy import ndimage

    labels = lf.labels[lf.center]
    ids, areas = np.unique(labels[labels > 0], return_counts=True)
    prompts = []
    for label in ids[np.argsort(-areas)][:count]:
        depth = ndimage.distance_transform_edt(labels == label)
        u, v = np.unravel_index(np.argmax(depth), depth.shape)
        prompts.append(ObjectPrompts(len(prompts) + 1, (PointPrompt(float(v), float(u)),)))
    return prompts


def speed_part(args: argparse.Namespace) -> None:
    size = parse_size(args.size)
    lf = generate_scene(grid=(9, 9), size=size, seed=0, num_objects=args.prompts - 1)
    prompts = click_prompts(lf, args.prompts)
    segmenter = load_segmenter(args.model, lightfield=lf, random_weights=True, device="cpu",
                               keep_decoder_state=False)
    # untimed warm-up (first-call costs of torch and the model): the smallest setting
    run(lf, 1, "estimate", model=segmenter, prompts=prompts)
    print(f"\n## speed: {args.model}, random weights, CPU, 9x9 views of {size[0]}x{size[1]}, "
          f"{len(prompts)} prompts, estimated disparity (after an untimed warm-up)\n")
    print("| refine views | views encoded | seconds | speed-up vs all |")
    print("|---|---|---|---|")
    seconds = {}
    for settings in args.settings:
        result, took = run(lf, settings, "estimate", model=segmenter, prompts=prompts)
        seconds[settings] = took
        base = seconds.get("all")
        ratio = f"{base / took:.2f}x" if base else "-"
        print(f"| {settings} | {result.meta['views_encoded']} | {took:.1f} | {ratio} |",
              flush=True)
    if "all" in seconds and "sparse" in seconds:
        print(f"\nsparse speed-up over all: {seconds['all'] / seconds['sparse']:.2f}x "
              "(target >= 4.5x)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="accuracy,speed")
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--size", default="240x320")
    parser.add_argument("--settings", default="all,sparse,5,9,13,25")
    parser.add_argument("--disparities", default="estimate,gt")
    parser.add_argument("--hidden", type=int, default=5, help="scenes with a hidden object")
    parser.add_argument(
        "--estimate-settings", default="all,sparse",
        help="settings run with estimated disparity too (every setting runs with ground truth)",
    )
    parser.add_argument("--model", default="sam2.1-hiera-small")
    parser.add_argument("--prompts", type=int, default=16)
    args = parser.parse_args()
    args.settings = [check_refine_views(s) for s in args.settings.split(",")]
    args.estimate_settings = [check_refine_views(s) for s in args.estimate_settings.split(",")]
    parts = args.parts.split(",")
    if "accuracy" in parts:
        accuracy_part(args)
    if "speed" in parts:
        speed_part(args)


if __name__ == "__main__":
    main()
