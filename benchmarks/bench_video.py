"""Light-field video (issue 25; docs/design.md section 10): the cost of tracking.

Two parts, each printing its table:

* ``speed`` — a synthetic 9x9 video (``--size``, ``--frames``), ground-truth disparity, for each
  model (``--models``: the oracle tracks with constrained prompts, a SAM 2 model with random
  weights with SAM 2's video memory) and each ``--refine-views`` setting: milliseconds per
  frame of tracking (``track_video`` from one click per object on frame 0, result written to
  disk) against segmenting each frame on its own (``lfsam.segment`` from one ground-truth click
  per object visible in that frame's center view; labels kept in memory only). Target (issue
  25): tracking costs at most 10% more than independent frames.
* ``memory`` — peak resident memory (``ru_maxrss``) of a fresh process tracking a 5x5 video of
  F frames with ``--memory-model`` (default the tiny SAM 2: its video memory), for each F in
  ``--memory-frames`` (target: flat in F).

Usage::

    python benchmarks/bench_video.py [--parts speed,memory] [--size 96x128] [--grid 9x9]
        [--frames 6] [--models oracle,sam2-tiny-test] [--settings all,sparse]
        [--memory-frames 3,6,12]
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from lfsam.api import RunOptions, SegmentOptions, segment
from lfsam.pipeline import PipelineConfig
from lfsam.prompts import ObjectPrompts, PointPrompt
from lfsam.segmenters import load_segmenter
from lfsam.video import read_video
from lfsam.video.synth import generate_video, write_video_frames
from lfsam.video.track import track_video


def parse_size(text: str) -> tuple[int, int]:
    height, width = (int(x) for x in text.lower().split("x"))
    return height, width


def clicks(lf) -> list[ObjectPrompts]:
    """One click per ground-truth object in the center view (its deepest pixel)."""
    from scipy import ndimage

    labels = lf.labels[lf.center]
    prompts = []
    for label in np.unique(labels[labels > 0]):
        depth = ndimage.distance_transform_edt(labels == label)
        u, v = np.unravel_index(np.argmax(depth), depth.shape)
        prompts.append(ObjectPrompts(int(label), (PointPrompt(float(v), float(u)),)))
    return prompts


def make_video(folder: Path, size, frames: int, grid=(9, 9)):
    write_video_frames(generate_video(grid=grid, size=size, frames=frames, seed=0,
                                      num_objects=3), folder)
    return read_video(folder)


def options(settings: str) -> SegmentOptions:
    return SegmentOptions(pipeline=PipelineConfig(refine_views=settings),
                          run=RunOptions(progress=False))


def model_for(name: str, lf):
    if name == "oracle":
        return "oracle"
    return load_segmenter(name, lightfield=lf, random_weights=True, device="cpu",
                          keep_decoder_state=False)


def speed_part(args: argparse.Namespace, work: Path) -> None:
    size = parse_size(args.size)
    grid = parse_size(args.grid)
    video = make_video(work / "clip", size, args.frames, grid=grid)
    print(f"\n## speed: {grid[0]}x{grid[1]} views of {size[0]}x{size[1]}, {args.frames} frames, "
          "3 objects, "
          "ground-truth disparity, CPU\n")
    print("| model | refine views | tracking | ms/frame tracked | ms/frame independent | "
          "tracked / independent |")
    print("|---|---|---|---|---|---|")
    for name in args.models:
        first = video.frame(0)
        model = model_for(name, first)
        for settings in args.settings:
            out = work / f"out_{name}_{settings}"
            start = time.perf_counter()
            result = track_video(video, clicks(first), out, model=model, disparity="gt",
                                 options=options(settings))
            tracked = (time.perf_counter() - start) / len(video)
            start = time.perf_counter()
            for lf in video:
                segment(lf, clicks(lf), model=model, disparity="gt", options=options(settings))
            alone = (time.perf_counter() - start) / len(video)
            print(f"| {name} | {settings} | {result.meta['tracking']} | {1000 * tracked:.0f} | "
                  f"{1000 * alone:.0f} | {tracked / alone:.3f} |", flush=True)
    print("\ntracked / independent: target <= 1.10")


def child(args: argparse.Namespace, work: Path) -> None:
    """Track a video of ``args.frames`` frames; print the peak RSS in MiB as JSON."""
    video = make_video(work / "clip", parse_size(args.size), args.frames, grid=(5, 5))
    first = video.frame(0)
    track_video(video, clicks(first), work / "out", model=model_for(args.memory_model, first),
                disparity="gt", options=options("all"))
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps({"frames": args.frames, "peak_rss_mib": peak}))


def memory_part(args: argparse.Namespace) -> None:
    print(f"\n## memory: peak RSS of a fresh process tracking 5x5 views of {args.size} "
          f"({args.memory_model})\n")
    print("| frames | peak RSS (MiB) |")
    print("|---|---|")
    peaks = []
    for frames in args.memory_frames:
        run = subprocess.run(
            [sys.executable, __file__, "--child", "--frames", str(frames), "--size", args.size,
             "--memory-model", args.memory_model], capture_output=True, text=True, check=True)
        peak = json.loads(run.stdout.strip().splitlines()[-1])["peak_rss_mib"]
        peaks.append(peak)
        print(f"| {frames} | {peak:.0f} |", flush=True)
    print(f"\npeak RSS growth from {args.memory_frames[0]} to {args.memory_frames[-1]} frames: "
          f"{peaks[-1] - peaks[0]:+.0f} MiB (target: flat)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--parts", default="speed,memory")
    parser.add_argument("--size", default="96x128")
    parser.add_argument("--grid", default="9x9", help="views of the speed part")
    parser.add_argument("--frames", type=int, default=6)
    parser.add_argument("--models", default="oracle,sam2-tiny-test")
    parser.add_argument("--settings", default="all,sparse")
    parser.add_argument("--memory-frames", default="3,6,12")
    parser.add_argument("--memory-model", default="sam2-tiny-test")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    args.models = args.models.split(",")
    args.settings = args.settings.split(",")
    args.memory_frames = [int(x) for x in args.memory_frames.split(",")]
    with tempfile.TemporaryDirectory() as folder:
        work = Path(folder)
        if args.child:
            child(args, work)
            return
        parts = args.parts.split(",")
        if "speed" in parts:
            speed_part(args, work)
        if "memory" in parts:
            memory_part(args)


if __name__ == "__main__":
    main()
