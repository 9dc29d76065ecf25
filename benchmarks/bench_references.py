"""Automatic mode from several reference views (issue 16; docs/design.md section 8).

Two parts, each printing its table:

* ``speed`` — SAM 2.1 hiera-small with random weights (untrained: for timing only), automatic
  mode with ground-truth disparity on a synthetic scene *without* hidden objects, run with
  ``--references center`` (the paper's setting) and then with each extra mode. Prints the
  seconds of each run, its ratio to ``center`` (target <= 1.10), the points the extra views'
  generator was asked at, the masks it added, whether every label equals the ``center`` run's
  (target: identical), and how many views were encoded. Each run encodes every view it needs
  once (no cache shared between runs); after an untimed warm-up the modes run ``--rounds``
  times in alternation and each counts its fastest run. Two regimes (``--answers``):

  - ``random``: SAM 2's own answers. Untrained, its generator keeps no mask at the paper's
    thresholds, so the ``center`` run is little more than one view's generator: a degenerate
    regime in which every extra encode and generator point counts in full.
  - ``oracle``: SAM 2 computes everything it would (every encode, the generator over every
    point asked, every refinement decode), but the generator's masks are the ground truth's
    regions under the points asked (what a trained generator finds on these scenes; the same
    construction as the video-baseline tests). This is the regime of a real run: the center
    finds the objects, and every view is encoded and refined.

* ``quality`` — the oracle with ground-truth disparity on synthetic scenes *with* hidden objects
  (objects the center view cannot see): object recall (target 1.0 with ``corners``, below 1.0
  with ``center``), AA and UE (target: no worse than ``center``) per mode, and how many
  ground-truth objects more than one predicted object covers (an object found twice).
  Seeds whose scene cannot hide the objects asked for are skipped, with a note.

Usage::

    python benchmarks/bench_references.py [--parts speed,quality] [--answers random,oracle]
        [--grid 5x5] [--size 240x320] [--points-per-side N]
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
from lfsam.pipeline.references import uncovered_points
from lfsam.segmenters import load_segmenter
from lfsam.segmenters.oracle import OracleSegmenter
from lfsam.segmenters.sam2.backend import Sam2Segmenter
from lfsam.synth import generate_scene


class Sam2CostOracleAnswers(Sam2Segmenter):
    """SAM 2 doing all its work, with the ground truth's regions as the generator's masks."""

    oracle: OracleSegmenter

    def encode(self, images, keys=None):
        embeddings = super().encode(images, keys)
        for embedding in embeddings:
            embedding.oracle = self.oracle.encode(images[:1], keys=[embedding.key])[0]
        return embeddings

    def generate(self, embedding, image, points=None):
        super().generate(embedding, image, points=points)  # SAM 2's cost, answers discarded
        return self.oracle.generate(embedding.oracle, image, points=points)


def _pair(text: str) -> tuple[int, int]:
    a, b = text.lower().split("x")
    return int(a), int(b)


def _seeds(text: str) -> list[int]:
    """``"0-3,7"`` -> ``[0, 1, 2, 3, 7]``."""
    seeds: list[int] = []
    for part in text.split(","):
        first, _, last = part.partition("-")
        seeds += list(range(int(first), int(last or first) + 1))
    return seeds


def _options(references: str) -> SegmentOptions:
    """A batch run of the automatic mode from ``references``, the paper's pipeline."""
    return SegmentOptions(run=RunOptions(references=references, progress=False))


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


def speed(args: argparse.Namespace, answers: str) -> None:
    lf = generate_scene(grid=args.grid, size=args.size, seed=args.seed, num_objects=args.objects)
    # batch runs: no decoder state kept with the embeddings (each view is decoded once)
    amg = {"points_per_side": args.points_per_side} if args.points_per_side else None
    segmenter = load_segmenter(args.model, random_weights=True, device=args.device,
                               keep_decoder_state=False, amg_options=amg)
    if answers == "oracle":
        sam2 = segmenter
        segmenter = Sam2CostOracleAnswers(sam2.model, amg_options=sam2.amg_options,
                                          keep_decoder_state=False)
        segmenter.oracle = OracleSegmenter(lf, device=args.device)
    # Untimed warm-up (first-call costs: kernels, allocator): one view encoded and the
    # generator over 64 points, so that the first timed mode does not pay for it.
    center = lf.center
    warm = segmenter.encode(lf.views[center][None], keys=[center])[0]
    nowhere = np.zeros(lf.view_shape, dtype=bool)
    segmenter.generate(warm, lf.views[center], points=uncovered_points(8, nowhere))
    asked = _count_generator_points(segmenter)
    points_per_side = int(getattr(segmenter, "amg_options", {}).get("points_per_side") or 32)
    print(f"\nspeed ({answers} answers): {args.model} (random weights) on {args.device}; "
          f"{args.grid[0]}x{args.grid[1]} views of {args.size[0]}x{args.size[1]}, "
          f"{args.objects} objects, no hidden ones; ground-truth disparity; generator grid "
          f"{points_per_side}x{points_per_side}", flush=True)
    # ``--rounds`` passes over the modes, alternating (center, corners, ..., center, corners,
    # ...): each mode's time is its fastest round, so that drift and first-run costs on a busy
    # 2-core machine do not favour the mode that runs later.
    modes = ["center", *args.modes]
    times: dict[str, list[float]] = {mode: [] for mode in modes}
    results, counts = {}, {}
    for round_index in range(args.rounds):
        for mode in modes:
            asked.clear()
            start = time.perf_counter()
            result = segment(lf, model=segmenter, disparity="gt", options=_options(mode))
            times[mode].append(time.perf_counter() - start)
            results[mode] = result
            counts[mode] = (sum(1 for n in asked if n is not None),
                            sum(n for n in asked if n is not None))
            print(f"  round {round_index + 1}, {mode}: {times[mode][-1]:.1f} s, "
                  f"{result.num_masks} masks", flush=True)
    base_seconds, base = min(times["center"]), results["center"]
    rows = []
    for mode in modes:
        result, seconds = results[mode], min(times[mode])
        same = np.array_equal(result.labels, base.labels)
        rows.append((mode, seconds, seconds / base_seconds, result.num_masks,
                     result.num_masks - base.num_masks, *counts[mode], same,
                     result.meta.get("views_encoded")))
    print(f"\n(fastest of {args.rounds} alternating rounds)")
    print("\n| references | seconds | ratio to center | masks | added | extra views asked "
          "| points asked there | labels equal center | views encoded |")
    print("|---|---|---|---|---|---|---|---|---|")
    for mode, seconds, ratio, masks, added, views, points, same, encoded in rows:
        print(f"| {mode} | {seconds:.1f} | {ratio:.3f} | {masks} | {added} | {views} | {points} "
              f"| {'yes' if same else 'NO'} | {encoded} |")
    print(f"(a full grid in an extra view is {points_per_side ** 2} points)")


def _found_twice(result, lf) -> int:
    """Ground-truth objects that more than one predicted object covers most of (each predicted
    object is assigned to the ground-truth label under most of its pixels)."""
    owners = [int(np.bincount(lf.labels[result.labels == entry["id"]]).argmax())
              for entry in result.meta["objects"]]
    counts = np.bincount(owners) if owners else np.zeros(1, dtype=int)
    return int(np.maximum(counts[1:] - 1, 0).sum())


def quality(args: argparse.Namespace) -> None:
    grid = args.quality_grid
    print(f"\nquality: oracle, ground-truth disparity; {grid[0]}x{grid[1]} views of "
          f"{args.quality_size[0]}x{args.quality_size[1]}, {args.hidden} hidden objects per "
          f"scene, seeds {args.quality_seeds}", flush=True)
    modes = ["center", *args.modes]
    scores: dict[str, list[dict]] = {mode: [] for mode in modes}
    twice: dict[str, int] = dict.fromkeys(modes, 0)
    used = []
    for seed in args.quality_seeds:
        try:
            lf = generate_scene(grid=grid, size=args.quality_size, seed=seed,
                                hidden_objects=args.hidden)
        except LfsamError as error:  # the generator could not hide that many objects
            print(f"  seed {seed} skipped: {error}", flush=True)
            continue
        used.append(seed)
        for mode in modes:
            segmenter = load_segmenter("oracle", lightfield=lf, device="cpu")
            result = segment(lf, model=segmenter, disparity="gt", options=_options(mode))
            scores[mode].append(evaluate_result(result, lf, device="cpu"))
            twice[mode] += _found_twice(result, lf)
    print(f"\n{len(used)} scenes, {len(used) * args.hidden} hidden objects; means over scenes")
    print("\n| references | recall | scenes with recall 1 | AA | UE | SIoU "
          "| SIoU (center-present masks) | objects found twice |")
    print("|---|---|---|---|---|---|---|---|")
    for mode in modes:
        mean = {k: float(np.mean([s[k] for s in scores[mode]]))
                for k in ("recall", "aa", "ue", "siou", "siou_center")}
        perfect = sum(s["recall"] == 1.0 for s in scores[mode])
        print(f"| {mode} | {mean['recall']:.3f} | {perfect} / {len(used)} | {mean['aa']:.4f} "
              f"| {mean['ue']:.4f} | {mean['siou']:.4f} | {mean['siou_center']:.4f} "
              f"| {twice[mode]} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="speed,quality")
    parser.add_argument("--answers", default="random,oracle",
                        help="speed regimes: SAM 2's own answers, and/or the ground truth's")
    parser.add_argument("--modes", default="corners,ring",
                        help="extra modes compared with center, comma-separated")
    parser.add_argument("--grid", type=_pair, default=(5, 5), help="speed part")
    parser.add_argument("--size", type=_pair, default=(240, 320), help="speed part")
    parser.add_argument("--objects", type=int, default=6, help="speed part")
    parser.add_argument("--points-per-side", type=int, default=None,
                        help="speed part: the generator's grid (default: the model's own)")
    parser.add_argument("--model", default="sam2.1-hiera-small")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--rounds", type=int, default=2,
                        help="speed part: alternating passes over the modes; fastest counts")
    parser.add_argument("--quality-grid", type=_pair, default=(5, 5))
    parser.add_argument("--quality-size", type=_pair, default=(96, 128))
    parser.add_argument("--quality-seeds", default="0-13",
                        help="quality part: seeds, comma-separated or a range A-B")
    parser.add_argument("--hidden", type=int, default=2)
    args = parser.parse_args()
    args.modes = [m for m in args.modes.split(",") if m and m != "center"]
    args.quality_seeds = _seeds(args.quality_seeds)
    parts = args.parts.split(",")
    if "speed" in parts:
        for answers in args.answers.split(","):
            speed(args, answers)
    if "quality" in parts:
        quality(args)
    print("bench_references: done", flush=True)


if __name__ == "__main__":
    main()
