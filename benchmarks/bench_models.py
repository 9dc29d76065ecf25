"""On-device speed: EdgeTAM against SAM 2's Hiera models (issue 34; docs/performance.md).

Three parts, each printing its table; random weights throughout (speed does not depend on the
weights), CPU, every ratio measured within one run:

* ``encoder`` — one image-encoder pass per view (a 240x320 view, resized to the model's
  1024x1024 input): median of ``--repeats`` after a warm-up, for EdgeTAM and SAM 2.1 Hiera-T
  (and ``--models``). Target: EdgeTAM >= 3.5x faster than Hiera-T.
* ``pipeline`` — ``lfsam.segment`` on a 9x9 light field of 240x320 with 16 clicks (one per
  object, ``bench_sparse.click_prompts``) and disparity estimated from the views, refining
  ``sparse`` (13 views) and ``all`` views, with EdgeTAM (the segmenter built once, untimed; an
  untimed warm-up run first): seconds per setting and every stage's seconds, in float32 and in
  bfloat16 autocast (``--precision bfloat16``; fast on CPUs with native bfloat16). Targets:
  sparse <= 15 s, all <= 60 s.
* ``cli`` — ``lfsam segment SCENE --point X,Y --random-weights`` in a fresh process on a 5x5
  light field of 240x320 (model building and reading included, as a user runs it), EdgeTAM
  against ``sam2.1-hiera-tiny``, median of ``--cli-repeats``. Target: EdgeTAM >= 2.5x faster.

Usage::

    python benchmarks/bench_models.py [--parts encoder,pipeline,cli] [--repeats 3]
        [--settings sparse,all] [--precisions float32,bfloat16] [--cli-repeats 1] [--threads N]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from bench_sparse import click_prompts
from lfsam.api import RunOptions, SegmentOptions, segment
from lfsam.io import write_lightfield
from lfsam.pipeline import PipelineConfig
from lfsam.pipeline.sparse import check_refine_views
from lfsam.segmenters import load_segmenter
from lfsam.synth import generate_scene

EDGETAM = "edgetam"
HIERA_T = "sam2.1-hiera-tiny"


def encoder_part(args: argparse.Namespace) -> None:
    view = generate_scene(grid=(1, 1), size=(240, 320), seed=0).views[0, 0][None]
    seconds: dict[str, float] = {}
    print(f"\n## encoder: one pass per 240x320 view, median of {args.repeats} after a warm-up\n")
    params: dict[str, float] = {}
    runs = [(EDGETAM, "float32"), (HIERA_T, "float32"), *((m, "float32") for m in args.models),
            *((EDGETAM, p) for p in args.precisions if p != "float32")]
    for name, precision in runs:
        segmenter = load_segmenter(name, random_weights=True, device="cpu", precision=precision)
        name = name if precision == "float32" else f"{name} ({precision})"
        segmenter.encode(view)  # warm-up
        times = []
        for _ in range(args.repeats):
            start = time.perf_counter()
            segmenter.encode(view)
            times.append(time.perf_counter() - start)
        seconds[name] = statistics.median(times)
        params[name] = segmenter.describe()["params"] / 1e6
    print("| model | params (M) | s per view | speed-up vs Hiera-T |")
    print("|---|---|---|---|")
    for name, took in seconds.items():
        print(f"| {name} | {params[name]:.1f} | {took:.3f} | {seconds[HIERA_T] / took:.2f}x |")
    print(f"\nEdgeTAM encoder speed-up over Hiera-T: {seconds[HIERA_T] / seconds[EDGETAM]:.2f}x "
          "(target >= 3.5x)")


def pipeline_part(args: argparse.Namespace) -> None:
    def scene():  # a fresh light field per run: nothing estimated is carried over
        return generate_scene(grid=(9, 9), size=(240, 320), seed=0, num_objects=15)

    lf = scene()
    prompts = click_prompts(lf, 16)
    def run(refine_views, segmenter):
        options = SegmentOptions(pipeline=PipelineConfig(refine_views=refine_views),
                                 run=RunOptions(progress=False))
        light = scene()
        start = time.perf_counter()
        result = segment(light, prompts, model=segmenter, disparity="estimate", options=options)
        return result, time.perf_counter() - start

    print(f"\n## pipeline: EdgeTAM, 9x9 views of 240x320, {len(prompts)} clicks, estimated "
          "disparity, end to end (after a warm-up)\n")
    print("| precision | refine views | views encoded | seconds | target | stages (s) |")
    print("|---|---|---|---|---|---|")
    targets = {"sparse": 15.0, "all": 60.0}
    for precision in args.precisions:
        segmenter = load_segmenter(EDGETAM, random_weights=True, device="cpu",
                                   keep_decoder_state=False, precision=precision)
        run(1, segmenter)  # untimed warm-up
        for setting in args.settings:
            result, took = run(check_refine_views(setting), segmenter)
            stages = ", ".join(f"{k} {v:.2f}" for k, v in result.timings.items()
                               if k != "total")
            target = targets.get(str(setting))
            print(f"| {precision} | {setting} | {result.meta['views_encoded']} | {took:.1f} | "
                  f"{f'<= {target:g}' if target else '-'} | {stages} |", flush=True)


def cli_part(args: argparse.Namespace) -> None:
    lf = generate_scene(grid=(5, 5), size=(240, 320), seed=0, num_objects=4)
    click = click_prompts(lf, 1)[0].points[0]
    with tempfile.TemporaryDirectory() as tmp:
        scene = Path(tmp) / "scene"
        write_lightfield(lf, scene)
        lfsam = [sys.executable, "-m", "lfsam.cli.main"]
        seconds: dict[str, float] = {}
        print(f"\n## cli: `lfsam segment` on 5x5 views of 240x320, one click, fresh process, "
              f"median of {args.cli_repeats}\n")
        print("| model | seconds | vs Hiera-T |")
        print("|---|---|---|")
        runs = [(HIERA_T, "float32"), *((EDGETAM, p) for p in args.precisions)]
        for name, precision in runs:
            label = name if precision == "float32" else f"{name} ({precision})"
            times = []
            for _ in range(args.cli_repeats):
                cmd = [*lfsam, "segment", str(scene), "--point", f"{click.x:.0f},{click.y:.0f}",
                       "--model", name, "--random-weights", "--device", "cpu", "--quiet",
                       "--precision", precision, "--out", str(Path(tmp) / f"{name}.npz")]
                start = time.perf_counter()
                subprocess.run(cmd, check=True, capture_output=True)
                times.append(time.perf_counter() - start)
            seconds[label] = statistics.median(times)
            vs = f"{seconds[HIERA_T] / seconds[label]:.2f}x"
            print(f"| {label} | {seconds[label]:.1f} | {vs} |", flush=True)
        print(f"\nEdgeTAM end-to-end speed-up over Hiera-T: "
              f"{seconds[HIERA_T] / seconds[EDGETAM]:.2f}x (target >= 2.5x)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="encoder,pipeline,cli")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--models", default="", help="more models for the encoder table")
    parser.add_argument("--settings", default="sparse,all")
    parser.add_argument("--precisions", default="float32,bfloat16",
                        help="EdgeTAM's arithmetic in the encoder and pipeline parts")
    parser.add_argument("--cli-repeats", type=int, default=1)
    parser.add_argument("--threads", type=int, default=0, help="torch threads (0: default)")
    args = parser.parse_args()
    args.models = [m for m in args.models.split(",") if m]
    args.settings = args.settings.split(",")
    args.precisions = args.precisions.split(",")
    if args.threads:
        torch.set_num_threads(args.threads)
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads, numpy {np.__version__}")
    parts = args.parts.split(",")
    if "encoder" in parts:
        encoder_part(args)
    if "pipeline" in parts:
        pipeline_part(args)
    if "cli" in parts:
        cli_part(args)


if __name__ == "__main__":
    main()
