"""The GPU batch path at the paper's scale, against the SAM 2 video baseline (issue 18).

Paper section 4 (Table 1, metric T of section 4.1): 15.2 ms per mask per view for LFSAM and 108.5
for SAM 2 video tracking (7.1x) with Hiera-S on a V100. Target on one H100: the whole 9x9 light
field of 480x640 views with 100 masks in under 1.5 s end to end.

Setting: SAM 2.1 Hiera-S with random weights (speed does not depend on the weights), a synthetic
light field (:func:`lfsam.synth.generate_scene`) and N positive point prompts on the center view,
one at the deepest pixel of each of the N largest regions (when the scene has fewer regions than
N, further points are drawn inside the regions, seeded; duplicates only add objects). Views are
encoded in batches of ``--encode-batch``; on CUDA with bfloat16 support everything runs under
bf16 autocast (lfsam's :func:`~lfsam.segmenters.sam2.build.inference_context`).

Measured in one run, after a warm-up (one batched encoder pass, the video predictor built, and on
CUDA one untimed LFSAM run):

- LFSAM end to end (``lfsam.segment`` with ``RunOptions(method="lfsam")``, ground-truth disparity
  as in the paper's timing; the disparity estimate's own time is printed on a separate row): the
  best of ``--repeats`` runs. ms per mask per view = total seconds / (N x views); encoder share =
  the ``encode`` stage / total; peak GPU memory = ``torch.cuda.max_memory_allocated`` over the
  run.
- The SAM 2 video baseline (``RunOptions(method="video-baseline")``, starting on the center view
  with the same prompts) on the same light field. Tracking all N objects would take ceil(N / 15)
  passes over all views, each costing the frame encodes plus memory attention per object per
  frame; to keep this affordable the baseline is timed on one pass of the first
  ``--baseline-objects`` prompts (default 15, the authors' objects per pass), and its ms per mask
  per view = that pass's total seconds / (objects x views). A full run's figure differs only by
  its last, partial pass. ``--baseline-objects 0`` times all N (ceil(N / 15) passes).

``--profile`` adds one LFSAM run under ``torch.profiler`` and prints its kernel launches, host
synchronisations, host-device copies and the GPU's busy time (docs/performance.md, "GPU (H100)");
on CUDA, one more run of each click case under the profiler too.

The real-time cases of issue 44 (``--cases``; ``gpu_cases.py`` beside this script has the
details): ``click-sparse`` and ``click-all`` (one click on the same light field, end to end,
``--refine-views sparse`` / all views; targets on an H100: 0.1 s and 0.3 s), ``stream`` and
``stream-estimate`` (a live stream of ``--stream-grid`` views of ``--stream-size`` landing at
``--stream-rate`` per second, ``--stream-model`` with its video memory, 3 objects,
``--refine-views 1``, ``--latest``; ground-truth disparity or estimated per frame; targets: 30
frames processed per second with a p95 latency of 60 ms, and 15 per second). ``--json PATH``
writes every number (and the targets) as JSON (docs/gpu_results.json beside the table in
docs/performance.md). ``--smoke`` runs every case at a tiny size with the tiny test models, on
any device, in seconds: the check that the script works before it reaches a GPU.

The batched decoder (issue 44; docs/design.md section 3.5): ``--cross-view off`` decodes view by
view (the default on CUDA decodes the prompts of each batch of views together), and
``--compile-decoder reduce-overhead`` compiles the cross-view decoder pass into CUDA graphs;
compare runs on the same machine.

Run on a GPU (``make gpu-check`` runs this)::

    python benchmarks/bench_gpu.py

and on a CPU at a small size (under 5 minutes on 2 cores): ``python benchmarks/bench_gpu.py
--device cpu --quick``, or every case in seconds: ``python benchmarks/bench_gpu.py --device cpu
--smoke --json /tmp/gpu.json``. The same table is printed either way.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import resource
import sys
import time
from pathlib import Path

import numpy as np
import torch

from lfsam.api import RunOptions, SegmentOptions, segment
from lfsam.baseline import video_predictor_for
from lfsam.disparity import resolve_disparity
from lfsam.pipeline import PipelineConfig
from lfsam.segmenters import Prompts, load_segmenter
from lfsam.segmenters.sam2.build import autocast_dtype, resolve_device
from lfsam.synth import generate_scene

FULL = {"grid": "9x9", "size": "480x640", "prompts": 100}
QUICK = {"grid": "3x3", "size": "120x160", "prompts": 4}
SMOKE = {"grid": "3x3", "size": "32x48", "prompts": 2}
CASES = ("click-sparse", "click-all", "stream", "stream-estimate")
#: Issue 44's targets on one H100 (seconds, frames per second).
TARGETS = {"paper_total_s": 1.0, "paper_kernel_launches": 10000, "paper_synchronisations": 100,
           "click_sparse_s": 0.1, "click_all_s": 0.3, "stream_per_second": 30,
           "stream_p95_latency_s": 0.060, "stream_estimate_per_second": 15}


def prompt_points(labels: np.ndarray, count: int, seed: int = 0) -> np.ndarray:
    """``count`` points ``(x, y)``: the deepest pixel of each of the largest regions, then
    seeded random pixels inside the regions (deeper than 2 px where possible) when there are
    fewer regions than ``count``."""
    from scipy.ndimage import distance_transform_edt

    ids, areas = np.unique(labels, return_counts=True)
    order = ids[np.argsort(-areas, kind="stable")]
    points = []
    inner = np.zeros(labels.shape, dtype=bool)
    for label in order:
        depth = distance_transform_edt(np.pad(labels == label, 1))[1:-1, 1:-1]
        inner |= depth > 2
        if len(points) < count:
            row, col = np.unravel_index(np.argmax(depth), depth.shape)
            points.append((float(col), float(row)))
    if len(points) < count:
        rows, cols = np.nonzero(inner if inner.any() else np.ones_like(inner))
        pick = np.random.default_rng(seed).choice(len(rows), count - len(points), replace=False)
        points += [(float(cols[i]), float(rows[i])) for i in pick]
    return np.array(points, dtype=np.float32)


def _sync(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def _reset_peak(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)
        torch.cuda.reset_peak_memory_stats(device)


def _peak_gib(device: torch.device) -> float | None:
    if device.type != "cuda":
        return None
    return torch.cuda.max_memory_allocated(device) / 2**30


def _timed(device: torch.device, fn):
    _sync(device)
    start = time.perf_counter()
    out = fn()
    _sync(device)
    return out, time.perf_counter() - start


def profile_run(fn, device: torch.device, label: str = "one LFSAM run") -> dict[str, float]:
    """Run ``fn`` once under ``torch.profiler`` and print what the host and the GPU did:
    kernel launches, stream and device synchronisations, host-device copies (calls), the
    run's wall time under the profiler, the GPU's busy time (self device time of all events)
    and the share of it in ``aten::copy_`` (dtype casts and moves). ``sync_points`` counts, on
    any device, the operators that make the host wait for a GPU (a value read back by
    ``.item()``/``bool()``, ``nonzero`` and boolean indexing, ``unique``, ``masked_select``):
    a CPU run shows how many the code would make (copies to the host by ``.cpu()`` are not
    operators on a CPU and are not in it)."""
    from torch.autograd import DeviceType
    from torch.profiler import ProfilerActivity, profile

    activities = [ProfilerActivity.CPU]
    if device.type == "cuda":
        activities.append(ProfilerActivity.CUDA)
    with profile(activities=activities) as prof:
        _, wall = _timed(device, fn)
    events = prof.key_averages()

    def calls(*names: str) -> int:
        return sum(e.count for e in events if e.key in names)

    on_gpu = [e for e in events if getattr(e, "device_type", None) == DeviceType.CUDA]
    busy = sum(e.self_device_time_total for e in on_gpu) / 1e6  # the kernels themselves
    copies = sum(e.self_device_time_total for e in events if e.key == "aten::copy_") / 1e6
    numbers = {
        "wall_s": wall,
        "kernel_launches": calls("cudaLaunchKernel", "cuLaunchKernelEx", "cuLaunchKernel"),
        "synchronisations": calls("cudaStreamSynchronize", "cudaDeviceSynchronize"),
        "copies": calls("cudaMemcpyAsync", "cudaMemcpy"),
        "sync_points": calls("aten::_local_scalar_dense", "aten::nonzero", "aten::_unique2",
                             "aten::unique_consecutive", "aten::masked_select"),
        "gpu_busy_s": busy,
    }
    print(f"\nprofile of {label}: {wall:.2f} s under the profiler; "
          f"{numbers['kernel_launches']} kernel launches, {numbers['synchronisations']} "
          f"synchronisations, {numbers['copies']} host-device copies, "
          f"{numbers['sync_points']} operators that wait for the device; GPU busy {busy:.2f} s "
          f"({100 * copies / busy if busy else 0:.0f} % of it in aten::copy_)", flush=True)
    return numbers


def _pairs(text: str) -> tuple[int, int]:
    a, b = (int(v) for v in text.lower().split("x"))
    return a, b


def main(argv: list[str] | None = None) -> dict[str, float]:
    """Parse the options, run both methods, print the table; returns its numbers."""
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    parser.add_argument("--device", default=None, help="cuda, cpu, mps; default the best")
    parser.add_argument("--quick", action="store_true",
                        help=f"small setting for a CPU: {QUICK} unless given explicitly")
    parser.add_argument("--grid", default=None, help=f"views, rows x columns ({FULL['grid']})")
    parser.add_argument("--size", default=None, help=f"view size, rows x columns ({FULL['size']})")
    parser.add_argument("--prompts", type=int, default=None,
                        help=f"N point prompts ({FULL['prompts']})")
    parser.add_argument("--model", default="sam2.1-hiera-small")
    parser.add_argument("--encode-batch", type=int, default=None,
                        help="views per image-encoder batch (default 16 on CUDA, 1 elsewhere)")
    parser.add_argument("--repeats", type=int, default=None,
                        help="LFSAM runs, the fastest kept (default 3 on CUDA, 1 elsewhere)")
    parser.add_argument("--baseline-objects", type=int, default=None,
                        help="objects the baseline is timed on (one pass; 0 = all N; default "
                        "15, or 1 with --quick)")
    parser.add_argument("--no-baseline", action="store_true", help="skip the video baseline")
    parser.add_argument("--no-estimate", action="store_true",
                        help="skip timing the disparity estimate (always skipped with --quick)")
    parser.add_argument("--seed", type=int, default=0, help="scene seed")
    parser.add_argument("--cross-view", choices=("auto", "on", "off"), default="auto",
                        help="decode the prompts of a batch of views together (issue 44; auto: "
                        "on CUDA only)")
    parser.add_argument("--compile-decoder", default=None, metavar="MODE",
                        help="torch.compile the cross-view decoder pass: reduce-overhead (CUDA "
                        "graphs), default, max-autotune or eager")
    parser.add_argument("--profile", action="store_true",
                        help="one more LFSAM run under torch.profiler: kernel launches, host "
                        "synchronisations, copies and the GPU's busy time")
    parser.add_argument("--cases", default=",".join(CASES),
                        help="the real-time cases to run after the paper's setting, of "
                        + ", ".join(CASES) + " (or none)")
    parser.add_argument("--stream-model", default=None, help="default edgetam")
    parser.add_argument("--stream-grid", default=None, help="default 5x5")
    parser.add_argument("--stream-size", default=None, help="default 480x640")
    parser.add_argument("--stream-frames", type=int, default=None,
                        help="frames landing in the stream (default 240)")
    parser.add_argument("--stream-rate", type=float, default=60.0,
                        help="frames landing per second")
    parser.add_argument("--smoke", action="store_true",
                        help=f"every case at a tiny size with the tiny test models ({SMOKE}, "
                        "sam2-tiny-test, edgetam-tiny-test, 12 stream frames): does it run?")
    parser.add_argument("--json", default=None, metavar="PATH",
                        help="write every number, the setting and the targets as JSON")
    args = parser.parse_args(argv)
    cases = [c for c in args.cases.split(",") if c and c != "none"]
    unknown = sorted(set(cases) - set(CASES))
    if unknown:
        parser.error(f"unknown cases {unknown}; choose from {', '.join(CASES)}")
    if args.smoke:
        args.quick = True
        args.model = "sam2-tiny-test" if args.model == parser.get_default("model") else \
            args.model
    preset = SMOKE if args.smoke else QUICK if args.quick else FULL
    grid = _pairs(args.grid or preset["grid"])
    size = _pairs(args.size or preset["size"])
    n = args.prompts or preset["prompts"]
    device = resolve_device(args.device)
    cuda = device.type == "cuda"
    batch = args.encode_batch or (16 if cuda else 1)
    repeats = args.repeats or (3 if cuda else 1)
    base_objects = args.baseline_objects
    if base_objects is None:
        base_objects = 1 if args.quick else 15
    base_objects = n if base_objects <= 0 else min(base_objects, n)
    began = time.perf_counter()

    lf = generate_scene(grid=grid, size=size, seed=args.seed, num_objects=max(n + 2, 4),
                        device=device)
    points = prompt_points(lf.center_labels, n, seed=args.seed)
    prompts = [Prompts(points=points[:, None, :], point_labels=np.ones((n, 1)))]
    num_views = grid[0] * grid[1]
    # batch runs: no decoder state kept with the embeddings (each view is decoded once)
    cross_view = {"auto": None, "on": True, "off": False}[args.cross_view]
    segmenter = load_segmenter(args.model, random_weights=True, device=device,
                               keep_decoder_state=False, cross_view_decode=cross_view,
                               compile_decoder=args.compile_decoder)
    segmenter.encode_batch_size = batch
    config = PipelineConfig(encode_batch_size=batch)
    ours_options = SegmentOptions(pipeline=config, run=RunOptions(method="lfsam", progress=False))
    dtype = autocast_dtype(device)
    gpu = torch.cuda.get_device_name(device) if cuda else platform.processor() or "cpu"
    print(f"bench_gpu: {args.model} (random weights) on {device} ({gpu}), "
          f"{'bf16 autocast' if dtype is not None else 'float32'}, torch {torch.__version__}, "
          f"{torch.get_num_threads()} threads; {grid[0]}x{grid[1]} views of {size[0]}x{size[1]}, "
          f"N={n} point prompts, encoder batch {batch}; views decoded together: "
          f"{segmenter.cross_view_decode}, compiled decoder: {args.compile_decoder}", flush=True)

    # Warm-up, untimed: kernels, allocator, cudnn choices; the video predictor built.
    views = lf.views.reshape(-1, *lf.views.shape[2:])
    segmenter.encode(views[: min(batch, num_views)])
    video_predictor_for(segmenter)
    if cuda:
        segment(lf, prompts, model=segmenter, disparity=lf.center_disparity,
                options=ours_options)

    disparity_s = float("nan")
    if not (args.no_estimate or args.quick):
        _, disparity_s = _timed(device, lambda: resolve_disparity("estimate", lf,
                                                                  device=str(device)))
    _reset_peak(device)
    runs = []
    for _ in range(repeats):
        result, wall = _timed(device, lambda: segment(
            lf, prompts, model=segmenter, disparity=lf.center_disparity, options=ours_options))
        runs.append((wall, result))
    wall, ours = min(runs, key=lambda item: item[0])
    peak = _peak_gib(device)
    ours_ms = 1000 * wall / (ours.num_masks * num_views)
    encoder_share = ours.timings.get("encode", float("nan")) / ours.timings["total"]

    base_ms = base_wall = base_peak = None
    if not args.no_baseline:
        sub = prompts[0].subset(slice(0, base_objects))
        _reset_peak(device)
        base_options = SegmentOptions(run=RunOptions(
            method="video-baseline", progress=False,
            baseline={"start": "center", "objects_per_pass": 15}))
        base, base_wall = _timed(device, lambda: segment(
            lf, [sub], model=segmenter, disparity=lf.center_disparity, options=base_options))
        base_peak = _peak_gib(device)
        base_ms = 1000 * base_wall / (base.num_masks * num_views)
        passes = math.ceil(n / 15)

    profile = None
    if args.profile:
        profile = profile_run(lambda: segment(lf, prompts, model=segmenter,
                                              disparity=lf.center_disparity,
                                              options=ours_options), device)
    rss_gib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20  # KiB on Linux
    rows = [
        ("LFSAM ms per mask per view", f"{ours_ms:.2f}",
         f"{wall:.3f} s / ({ours.num_masks} masks x {num_views} views); paper 15.2 on a V100"),
        ("LFSAM total seconds end to end", f"{wall:.3f}",
         f"best of {repeats}; ground-truth disparity; target < 1.5 s on an H100 at full size"),
        ("encoder share of LFSAM", f"{100 * encoder_share:.0f} %",
         f"encode stage {ours.timings.get('encode', float('nan')):.3f} s"),
        ("LFSAM stages (s)", "", ", ".join(f"{k} {v:.3f}" for k, v in ours.timings.items()
                                          if k != "total")),
        ("disparity estimate (s, not in total)",
         "skipped" if math.isnan(disparity_s) else f"{disparity_s:.3f}",
         "lfsam's estimator on this light field"),
        ("peak GPU memory, LFSAM", "n/a" if peak is None else f"{peak:.2f} GiB",
         "torch.cuda.max_memory_allocated" if cuda else "no GPU"),
    ]
    if base_ms is not None:
        rows += [
            ("video baseline ms per mask per view", f"{base_ms:.2f}",
             f"{base_wall:.3f} s / ({base.num_masks} objects x {num_views} views), one pass; "
             f"all {n} objects would take {passes} pass(es); paper 108.5"),
            ("ratio baseline / LFSAM", f"{base_ms / ours_ms:.1f}x", "paper 7.1x"),
            ("peak GPU memory, baseline", "n/a" if base_peak is None else f"{base_peak:.2f} GiB",
             f"{base.num_masks} objects tracked"),
        ]
    rows.append(("peak process RSS", f"{rss_gib:.2f} GiB", "host memory"))
    width = max(len(r[0]) for r in rows)
    vwidth = max(len(r[1]) for r in rows)
    print("\n| " + "quantity".ljust(width) + " | " + "value".ljust(vwidth) + " | how |")
    print("|" + "-" * (width + 2) + "|" + "-" * (vwidth + 2) + "|-----|")
    for name, value, how in rows:
        print(f"| {name.ljust(width)} | {value.ljust(vwidth)} | {how} |")
    numbers: dict = {"lfsam_ms": ours_ms, "total_s": wall, "encoder_share": encoder_share,
                     "stages_s": {k: round(v, 4) for k, v in ours.timings.items()
                                  if k != "total"},
                     "peak_gpu_gib": peak, "peak_rss_gib": rss_gib,
                     **({"baseline_ms": base_ms} if base_ms is not None else {}),
                     **({"profile": profile} if profile is not None else {})}
    realtime = realtime_cases(args, cases, lf, segmenter, repeats, device)
    print(f"\nbench_gpu: finished in {time.perf_counter() - began:.0f} s", flush=True)
    sys.stdout.flush()
    if args.json:
        write_json(args.json, {
            "device": str(device), "gpu": gpu, "torch": torch.__version__,
            "precision": "bf16 autocast" if dtype is not None else "float32",
            "model": args.model, "random_weights": True,
            "setting": {"grid": list(grid), "size": list(size), "prompts": n,
                        "encode_batch": batch, "repeats": repeats,
                        "cross_view_decode": segmenter.cross_view_decode,
                        "compile_decoder": args.compile_decoder},
            "paper": numbers, **realtime, "targets": TARGETS,
        })
    return {**numbers, **realtime}


def realtime_cases(args, cases: list[str], lf, segmenter, repeats: int,
                   device: torch.device) -> dict:
    """Issue 44's cases (``gpu_cases.py``), printed as a second table; their numbers."""
    from gpu_cases import click_case, stream_case

    out: dict = {}
    rows = []
    for refine in ("sparse", "all"):
        if f"click-{refine}" in cases:
            got = click_case(lf, segmenter, refine, repeats, device,
                             profile_run if args.profile and device.type == "cuda" else None)
            out[f"click_{refine}"] = got
            target = TARGETS[f"click_{refine}_s"]
            rows.append((f"one click, --refine-views {refine}", f"{got['seconds']:.3f} s",
                         f"{got['light_fields_per_second']:.1f} light fields/s; "
                         f"{got['views_encoded']} views encoded; H100 target <= {target} s"))
    smoke = args.smoke
    model = args.stream_model or ("edgetam-tiny-test" if smoke else "edgetam")
    grid = _pairs(args.stream_grid or ("3x3" if smoke else "5x5"))
    size = _pairs(args.stream_size or ("32x48" if smoke else "480x640"))
    frames = args.stream_frames or (12 if smoke else 240)
    streams = [c for c in ("stream", "stream-estimate") if c in cases]
    if streams:
        stream_model = load_segmenter(model, random_weights=True, device=device,
                                      keep_decoder_state=False)
    for case in streams:
        disparity = "estimate" if case == "stream-estimate" else "gt"
        got = stream_case(stream_model, grid, size, frames, args.stream_rate, disparity,
                          device, seed=args.seed, sources_count=3 if smoke else 10)
        got.update(model=model, grid=list(grid), size=list(size), disparity=disparity)
        out[case.replace("-", "_")] = got
        key = "stream_estimate_per_second" if disparity == "estimate" else "stream_per_second"
        p95 = got["latency_p95_s"]
        rows.append((
            f"live stream, {disparity} disparity, --latest",
            f"{got['processed_per_second']:.1f} /s",
            f"{model} {grid[0]}x{grid[1]}x{size[0]}x{size[1]}, memory, 3 objects, "
            f"--refine-views 1; {got['frames_processed']} of {frames} frames at "
            f"{args.stream_rate:g}/s processed, {got['skipped']} skipped; latency median "
            f"{got['latency_median_s']:.3f} s, p95 {p95:.3f} s, worst "
            f"{got['latency_worst_s']:.3f} s; objects {got['objects_present']}; one result "
            f"write {got['result_write_s']:.3f} s, the stream's writes (behind) median "
            f"{got['write_median_s']:.3f} s, p95 {got['write_p95_s']:.3f} s, arrival to disk "
            f"p95 {got['disk_latency_p95_s']:.3f} s; H100 target >= {TARGETS[key]}/s"
            + (f", p95 <= {TARGETS['stream_p95_latency_s']} s" if disparity == "gt" else "")))
    if rows:
        print("\n| real-time case (issue 44) | value | how |\n|---|---|---|")
        for name, value, how in rows:
            print(f"| {name} | {value} | {how} |", flush=True)
    return out


def write_json(path: str, numbers: dict) -> None:
    """Write ``numbers`` as JSON atomically (``lfsam.fileutil.atomic_output``)."""
    from lfsam.fileutil import atomic_output

    with atomic_output(path) as tmp:
        Path(tmp).write_text(json.dumps(numbers, indent=2, default=float) + "\n")
    print(f"bench_gpu: numbers written to {path}", flush=True)


if __name__ == "__main__":
    main()
