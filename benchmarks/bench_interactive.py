"""Interactive latency of :class:`lfsam.predictor.LightFieldPredictor` (issue 13).

SAM 2.1 hiera-small with random weights (the speed is that of the trained model), a synthetic
light field (default 9x9 views of 240x320), embeddings cached (in memory, after a first pass that
is timed as the cold start). Prints, each measured in this run:

* the clicked view's latency (a new object's mask in its own view; target <= 0.15 s on a 2-core
  CPU),
* the coarse masks in all views (propagation + occluding; target <= 0.3 s),
* the refined masks in all views: ms per view and the ratio to one decoder call,
* the cold start (the first click's view encoded, then every view encoded for the first
  refined answer),
* the edit of 1 object out of 20 against a single-object run (target: no slower).

Run: ``python benchmarks/bench_interactive.py [--grid 9x9] [--size 240x320] [--device cpu]``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from lfsam.predictor import LightFieldPredictor
from lfsam.segmenters import load_segmenter
from lfsam.segmenters.base import Prompts
from lfsam.synth import generate_scene


def _pair(text: str) -> tuple[int, int]:
    a, b = text.lower().split("x")
    return int(a), int(b)


def _timed(fn, repeats: int = 3) -> float:
    """Median wall-clock seconds of ``fn()`` over ``repeats`` runs."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", type=_pair, default=(9, 9))
    parser.add_argument("--size", type=_pair, default=(240, 320))
    parser.add_argument("--model", default="sam2.1-hiera-small")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--objects", type=int, default=20)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    lf = generate_scene(grid=args.grid, size=args.size, seed=args.seed)
    height, width = lf.view_shape
    segmenter = load_segmenter(args.model, random_weights=True, device=args.device)
    predictor = LightFieldPredictor(segmenter, memory_budget_mb=1e9)
    predictor.set_lightfield(lf, disparity="gt")
    rng = np.random.default_rng(args.seed)
    clicks = rng.uniform([8, 8], [width - 9, height - 9], size=(args.objects + 8, 2))
    other_view = (0, args.grid[1] - 1)

    # Cold start: the first click encodes its view; the first refined answer encodes the rest.
    predictor.add_prompts(1, points=[clicks[0]], view=lf.center)
    start = time.perf_counter()
    predictor.predict_reference(1)
    cold_click = time.perf_counter() - start
    start = time.perf_counter()
    predictor.predict([1])
    cold_all = time.perf_counter() - start
    assert predictor.views_encoded == lf.num_views

    # Warm: every view's embedding is cached. A new object each time (nothing reused).
    state = {"next": 100}

    def new_object(view=lf.center) -> int:
        state["next"] += 1
        obj = state["next"]
        predictor.add_prompts(obj, points=[clicks[obj % len(clicks)]], view=view)
        return obj

    click = _timed(lambda: predictor.predict_reference(new_object()), args.repeats)
    click_other = _timed(lambda: predictor.predict_reference(new_object(other_view)), args.repeats)

    def coarse() -> None:
        obj = new_object()
        predictor.predict_reference(obj)
        start = time.perf_counter()
        predictor.predict_coarse([obj])
        coarse_times.append(time.perf_counter() - start)

    coarse_times: list[float] = []
    for _ in range(args.repeats):
        coarse()
    coarse_s = statistics.median(coarse_times)

    refine_times: list[float] = []
    for _ in range(args.repeats):
        obj = new_object()
        predictor.predict_coarse([obj])
        start = time.perf_counter()
        predictor.predict([obj])
        refine_times.append(time.perf_counter() - start)
    refine_s = statistics.median(refine_times)
    views = lf.num_views - 1
    embedding = predictor.embedding((0, 0))
    one = Prompts(points=[[[width / 2, height / 2]]], point_labels=[[1]],
                  boxes=[[width / 4, height / 4, width / 2, height / 2]])
    decoder_call = _timed(lambda: segmenter.predict(embedding, one), args.repeats * 3)

    # 20 objects, then one of them edited (a negative click): only it is recomputed. Against
    # it, the single-object run: a new object with the same final prompts, from its clicks to
    # its refined masks in every view (the same work for that object; the edit also repaints
    # the 20 objects' labels). Interleaved, one pair per repeat.
    for k in range(args.objects):
        predictor.add_prompts(1000 + k, points=[clicks[k]])
    predictor.predict()
    single_times, edit_times = [], []
    for k in range(args.repeats):
        positive, negative = clicks[k], clicks[-1 - k]
        predictor.add_prompts(900, points=[positive, negative], labels=[1, 0])
        start = time.perf_counter()
        predictor.predict([900])
        single_times.append(time.perf_counter() - start)
        predictor.remove_object(900)
        predictor.add_prompts(1000 + k, points=[negative], labels=[0])
        start = time.perf_counter()
        predictor.predict()
        edit_times.append(time.perf_counter() - start)
    single = statistics.median(single_times)
    edit = statistics.median(edit_times)

    rows = [
        ("clicked view (center), warm", f"{click:.3f} s", "<= 0.15 s"),
        (f"clicked view {other_view}, warm", f"{click_other:.3f} s", "<= 0.15 s"),
        ("coarse masks, all views", f"{coarse_s:.3f} s", "<= 0.3 s"),
        ("refined masks, all views", f"{refine_s:.3f} s", ""),
        ("  per view", f"{1000 * refine_s / views:.1f} ms", ""),
        ("  one decoder call (point + box)", f"{1000 * decoder_call:.1f} ms", ""),
        ("  per view / decoder call", f"{refine_s / views / decoder_call:.2f}", ""),
        ("cold start: first click (1 view encoded)", f"{cold_click:.2f} s", ""),
        (f"cold start: all views refined ({lf.num_views} encoded)", f"{cold_all:.2f} s", ""),
        ("single-object run, clicks to refined (warm)", f"{single:.3f} s", ""),
        (f"edit 1 of {args.objects} objects, to refined", f"{edit:.3f} s", "<= single run"),
        ("  edit / single-object run", f"{edit / single:.2f}", "<= 1"),
    ]
    print(
        f"# bench_interactive: {args.model} (random weights), {args.grid[0]}x{args.grid[1]} "
        f"views of {height}x{width}, device {segmenter.device}, median of {args.repeats}"
    )
    print("| measure | value | target |")
    print("|---|---|---|")
    for name, value, target in rows:
        print(f"| {name} | {value} | {target} |")


if __name__ == "__main__":
    main()
