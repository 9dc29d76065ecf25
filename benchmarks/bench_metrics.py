"""Time the paper's metrics (SIoU, LPP, AA, UE, C) on a light field of realistic size.

Target (issue #6): 200 masks on a 9x9x480x640 light field in under 30 s on a 2-core CPU.

The scene is a stack of fronto-parallel rectangles at random disparities, drawn far to near in
every view with the package's convention (a center pixel ``(u, v)`` with disparity ``d`` is seen in
view ``(s, t)`` at ``(u - d (s - s_c), v - d (t - t_c))``), so it has occlusions and borders. The
prediction is the ground truth with its ids shuffled and a few views relabelled.

Run: ``.venv/bin/python benchmarks/bench_metrics.py [--grid 9x9] [--size 480x640] [--masks 200]
[--threads N]``
"""

from __future__ import annotations

import argparse
import resource
import time

import numpy as np
import torch

from lfsam.lightfield import LightField
from lfsam.metrics import evaluate_labels


def make_scene(grid: tuple[int, int], size: tuple[int, int], masks: int, seed: int = 0):
    """Ground-truth labels and disparity of rectangles at random depths, every view."""
    rng = np.random.default_rng(seed)
    s_count, t_count = grid
    height, width = size
    s_c, t_c = s_count // 2, t_count // 2
    labels = np.zeros((s_count, t_count, height, width), np.int32)
    disparity = np.zeros((s_count, t_count, height, width), np.float32)
    depth = np.sort(rng.uniform(-1.5, 1.5, masks))  # far (small d) first
    top = rng.integers(0, height - 8, masks)
    left = rng.integers(0, width - 8, masks)
    tall = rng.integers(8, height // 4, masks)
    wide = rng.integers(8, width // 4, masks)
    rows = np.arange(height)[:, None]
    cols = np.arange(width)[None, :]
    for n in range(masks):
        d = depth[n]
        for s in range(s_count):
            for t in range(t_count):
                u0 = top[n] - d * (s - s_c)
                v0 = left[n] - d * (t - t_c)
                inside = (rows >= u0) & (rows < u0 + tall[n]) & (cols >= v0) & (cols < v0 + wide[n])
                labels[s, t][inside] = n + 1
                disparity[s, t][inside] = d
    return labels, disparity


def main() -> None:
    """Build the scene, time :func:`lfsam.metrics.evaluate_labels`, print the seconds."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", default="9x9")
    parser.add_argument("--size", default="480x640")
    parser.add_argument("--masks", type=int, default=200)
    parser.add_argument("--device", default=None)
    parser.add_argument(
        "--threads", type=int, default=None,
        help="torch CPU threads (default: torch's); 1 is far faster on a CPU shared with others",
    )
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    grid = tuple(int(x) for x in args.grid.split("x"))
    size = tuple(int(x) for x in args.size.split("x"))
    start = time.perf_counter()
    labels, disparity = make_scene(grid, size, args.masks)
    views = np.zeros((*labels.shape, 3), np.uint8)
    gt = LightField(views, disparity=disparity, labels=labels)
    rng = np.random.default_rng(1)
    ids = np.concatenate([[0], rng.permutation(args.masks) + 1000])
    predicted = ids[labels]
    predicted[0, 0][predicted[0, 0] > 0] += 10_000  # an inconsistent corner view
    print(f"scene built in {time.perf_counter() - start:.1f} s", flush=True)
    rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    start = time.perf_counter()
    metrics = evaluate_labels(predicted, gt, device=args.device)
    seconds = time.perf_counter() - start
    rss_after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    shown = ", ".join(f"{k} {v:.4f}" for k, v in metrics.items() if v is not None)
    print(f"metrics: {shown}")
    print(
        f"bench_metrics: {args.masks} masks on {grid[0]}x{grid[1]}x{size[0]}x{size[1]}: "
        f"{seconds:.2f} s with {torch.get_num_threads()} torch thread(s) (target < 30 s); "
        f"peak RSS {rss_before:.0f} MB before, {rss_after:.0f} MB after"
    )


if __name__ == "__main__":
    main()
