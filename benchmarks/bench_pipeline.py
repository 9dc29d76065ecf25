"""Benchmark of the LFSAM pipeline (issue 5; docs/design.md section 7 targets).

Three parts, each printing its numbers:

* ``quality`` — oracle segmenter on synthetic scenes with ground truth: every ablation row and
  occluding mode, with ground-truth and estimated disparity, next to the scores of the
  ground-truth label field itself (targets: SIoU >= 0.97 x ceiling, LPP <= 1.03 x ceiling,
  AA >= 0.99, C >= 0.97).
* ``speed`` — ``sam2.1-hiera-small`` with random weights (untrained: for timing only) on
  9x9x240x320 with 16 point prompts: total, encoder time, their ratio (target <= 1.25), ms per
  mask per view, peak RSS.
* ``memory`` — 200 masks on 9x9x480x640 with the oracle: peak RSS above the light field and
  segmenter (target <= 2 GB), run in a fresh process.

Usage::

    python benchmarks/bench_pipeline.py [--parts quality,speed,memory] [--model NAME]
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time

import numpy as np
import torch


def _rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def quality(args: argparse.Namespace) -> None:
    from lfsam.api import RunOptions, SegmentOptions, segment
    from lfsam.metrics import evaluate_labels
    from lfsam.metrics.report import format_metrics_table
    from lfsam.pipeline import PipelineConfig
    from lfsam.segmenters import load_segmenter
    from lfsam.synth import generate_scene

    settings = [
        ("none (no ref, no occ)", PipelineConfig.from_ablation("none")),
        ("ref", PipelineConfig.from_ablation("ref")),
        ("ref+occ (paper)", PipelineConfig.from_ablation("ref+occ")),
        ("ref+geometric occ", PipelineConfig(occlusion="geometric")),
        ("ref+both occ", PipelineConfig(occlusion="both")),
    ]
    scenes = [
        generate_scene(grid=(9, 9), size=(120, 160), seed=0, num_objects=6),
        generate_scene(grid=(9, 9), size=(120, 160), seed=1, num_objects=8),
        generate_scene(grid=(5, 7), size=(120, 160), seed=2, num_objects=6,
                       disparity_range=(-3.0, 3.0)),
    ]
    keys = ("siou", "lpp", "aa", "ue", "coverage")
    for disparity in ("gt", "estimate"):
        rows = []
        sums = {name: {k: 0.0 for k in keys} for name, _ in settings}
        ceiling = {k: 0.0 for k in keys}
        for lf in scenes:
            ceil = evaluate_labels(lf.labels, lf)
            for k in keys:
                ceiling[k] += ceil[k] / len(scenes)
            for name, config in settings:
                result = segment(
                    lf, model=load_segmenter("oracle", lightfield=lf), disparity=disparity,
                    options=SegmentOptions(pipeline=config, run=RunOptions(progress=False)),
                )
                scores = evaluate_labels(result.labels, lf)
                for k in keys:
                    sums[name][k] += scores[k] / len(scenes)
        for name, _ in settings:
            rows.append((name, sums[name]))
        rows.append(("ground-truth labels (ceiling)", ceiling))
        print(f"\n## Oracle segmenter, {disparity} disparity, mean of {len(scenes)} scenes\n")
        print(format_metrics_table(rows))
        paper = sums["ref+occ (paper)"]
        checks = {
            "SIoU >= 0.97 x ceiling": paper["siou"] >= 0.97 * ceiling["siou"],
            "LPP <= 1.03 x ceiling": paper["lpp"] <= 1.03 * ceiling["lpp"],
            "AA >= 0.99": paper["aa"] >= 0.99,
            "C >= 0.97": paper["coverage"] >= 0.97,
        }
        print("targets (ref+occ):", ", ".join(f"{k}: {'met' if v else 'MISSED'}"
                                            for k, v in checks.items()))


def speed(args: argparse.Namespace) -> None:
    from lfsam.api import RunOptions, SegmentOptions, make_prompts, segment
    from lfsam.segmenters import load_segmenter
    from lfsam.synth import generate_scene

    grid = tuple(int(x) for x in args.grid.split("x"))
    size = tuple(int(x) for x in args.size.split("x"))
    lf = generate_scene(grid=grid, size=size, seed=0, num_objects=8)
    rss_before = _rss_mb()
    # a batch run: no decoder state kept with the embeddings (each view is decoded once)
    segmenter = load_segmenter(args.model, random_weights=True, keep_decoder_state=False)
    height, width = size
    side = int(np.ceil(np.sqrt(args.prompts)))
    xs = np.linspace(width * 0.1, width * 0.9, side)
    ys = np.linspace(height * 0.1, height * 0.9, side)
    points = [(float(x), float(y)) for y in ys for x in xs][: args.prompts]
    # Encoder alone: one pass over every view, the unavoidable cost.
    start = time.perf_counter()
    for st in lf.view_indices():
        segmenter.encode(lf.views[st][None], keys=[st])
    encoder_alone = time.perf_counter() - start
    segmenter.encode_calls = 0
    result = segment(
        lf, make_prompts(points), model=segmenter, disparity="gt",
        options=SegmentOptions(run=RunOptions(progress=False)),
    )
    total = result.timings["total"]
    print(f"\n## Speed: {args.model} (random weights), {grid[0]}x{grid[1]} views of "
          f"{size[0]}x{size[1]}, {result.num_masks} point prompts, device {segmenter.device}, "
          f"torch threads {torch.get_num_threads()}\n")
    print(f"total                        {total:8.2f} s")
    for stage, seconds in sorted(result.timings.items()):
        if stage != "total":
            print(f"  {stage:26s} {seconds:8.2f} s")
    print(f"encoder alone, one pass/view {encoder_alone:8.2f} s")
    print(f"total / encoder alone        {total / encoder_alone:8.3f}   (target <= 1.25)")
    print(f"views encoded                {result.meta['views_encoded']:8d}   "
          f"(views: {lf.num_views})")
    print(f"ms per mask per view (T)     {result.ms_per_mask_view:8.2f} ms")
    print(f"peak RSS                     {_rss_mb():8.0f} MB (before model: {rss_before:.0f} MB)")


def _memory_child(masks_count: int) -> None:
    """Runs in a fresh process: 200 oracle masks on 9x9x480x640; prints JSON."""
    from lfsam.api import RunOptions, SegmentOptions, segment
    from lfsam.lightfield import LightField
    from lfsam.pipeline import PipelineConfig
    from lfsam.segmenters import load_segmenter

    s_count = t_count = 9
    height, width, d = 480, 640, 1.0
    rows, cols = 10, masks_count // 10
    u = np.arange(height)[:, None]
    v = np.arange(width)[None, :]
    rng = np.random.default_rng(0)
    texture = rng.integers(0, 256, size=(height + 16, width + 16, 3), dtype=np.uint8)
    views = np.empty((s_count, t_count, height, width, 3), dtype=np.uint8)
    labels = np.empty((s_count, t_count, height, width), dtype=np.int32)
    for s in range(s_count):
        for t in range(t_count):
            # A fronto-parallel plane at disparity d: view (s, t) sees center pixel (u, v) at
            # (u - d ds, v - d dt), so it shows center content at (u + d ds, v + d dt).
            cu = u + int(d * (s - 4))
            cv = v + int(d * (t - 4))
            views[s, t] = texture[cu + 8, cv + 8]
            block = (np.clip(cu, 0, height - 1) * rows // height) * cols + (
                np.clip(cv, 0, width - 1) * cols // width
            )
            labels[s, t] = block + 1
    lf = LightField(views, disparity=np.full((height, width), d, np.float32), labels=labels)
    segmenter = load_segmenter("oracle", lightfield=lf)
    base = _rss_mb()
    start = time.perf_counter()
    # automatic mode with the center view's disparity; a 2048 MB in-memory embedding budget
    # (LightFieldPredictor's default, the budget this benchmark has always run with)
    result = segment(
        lf, None, model=segmenter, disparity=lf.center_disparity,
        options=SegmentOptions(
            pipeline=PipelineConfig(), run=RunOptions(memory_budget_mb=2048.0, progress=False)
        ),
    )
    print(json.dumps({
        "masks": result.num_masks, "seconds": time.perf_counter() - start,
        "rss_before_mb": base, "rss_peak_mb": _rss_mb(),
    }))


def memory(args: argparse.Namespace) -> None:
    out = subprocess.run(
        [sys.executable, __file__, "--memory-child", str(args.masks)],
        check=True, capture_output=True, text=True,
    )
    stats = json.loads(out.stdout.strip().splitlines()[-1])
    added = stats["rss_peak_mb"] - stats["rss_before_mb"]
    print(f"\n## Memory: {stats['masks']} masks on 9x9x480x640 (oracle, ref+occ)\n")
    print(f"peak RSS {stats['rss_peak_mb']:.0f} MB; before the run (light field + segmenter) "
          f"{stats['rss_before_mb']:.0f} MB; added by the run {added:.0f} MB "
          f"(target <= 2048 MB); {stats['seconds']:.1f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--parts", default="quality,speed,memory")
    parser.add_argument("--model", default="sam2.1-hiera-small")
    parser.add_argument("--grid", default="9x9")
    parser.add_argument("--size", default="240x320")
    parser.add_argument("--prompts", type=int, default=16)
    parser.add_argument("--masks", type=int, default=200)
    parser.add_argument("--memory-child", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.memory_child:
        _memory_child(args.memory_child)
        return
    parts = {"quality": quality, "speed": speed, "memory": memory}
    for name in args.parts.split(","):
        parts[name](args)


if __name__ == "__main__":
    main()
