"""Light-field video (issue 25; docs/design.md section 10): the cost of tracking.

Parts, each printing its table:

* ``speed`` — a synthetic 9x9 video (``--size``, ``--frames``), ground-truth disparity, for each
  model (``--models``: the oracle tracks with constrained prompts, a SAM 2 model with random
  weights with SAM 2's video memory) and each ``--refine-views`` setting: milliseconds per
  frame of tracking (``track_video`` from one click per object on frame 0, result written to
  disk) against segmenting each frame on its own (``lfsam.segment`` from one ground-truth click
  per object visible in that frame's center view; labels kept in memory only). Target (issue
  25): tracking costs at most 10% more than independent frames.
* ``memory`` — peak resident memory (``ru_maxrss``) of a fresh process tracking a 5x5 video of
  F frames with ``--memory-model`` (default the tiny SAM 2: its video memory), for each F in
  ``--memory-frames`` (target: flat in F; issue 35: 10 to 100 frames).
* ``stream`` (issue 35) — a live stream: a writer thread lands the frames of a synthetic 5x5
  video of ``--stream-size`` (default 240x320, 3 objects, ``--stream-frames`` 30) into a
  followed folder at ``--rate`` frames per second (written under a hidden name, renamed in)
  while :func:`lfsam.video.stream.live.segment_stream` segments each as it lands, for each of
  ``--stream-runs`` (``MODEL:TRACKING``: the video memory or constrained prompts) with random
  weights, ``--refine-views 1``, ground-truth disparity, the 3 objects clicked in frame 0.
  Random weights score every object absent after frame 0; with the memory, as in the tests,
  the object-score bias is raised so the objects stay present and are segmented in every
  frame, as trained weights would. Printed per model: one encoder pass (median of 5, seconds), the
  mean seconds per frame spent reading and segmenting it, the sustained rate that allows
  (1 / mean), the per-frame cost in encoder passes, the latency from arrival to result
  (median and worst), the range of objects present in the center view per frame, and the
  result files' writing behind the tracker (issue 44: median per frame, arrival to disk p95).
  Targets: EdgeTAM at least 1 frame per second; Hiera-T at most 1.3
  encoder passes per frame.
* ``latest`` (issue 44) — a camera twice as fast as the tracker: the tracker's frame time is
  measured first (``--latest-model`` on ``--latest-grid`` views of ``--latest-size``, 3 objects
  clicked in frame 0, ground-truth disparity, ``--refine-views 1``; the median of 5 frames), then
  a writer process lands ``--latest-frames`` frames (a 10-frame synthetic clip in turn) at twice
  that rate while :func:`lfsam.video.stream.live.segment_stream` follows, once with ``latest=True``
  (``--latest``) and once without. Printed for each: frames processed per second, latency from
  arrival to result (median, 95th percentile, worst) in seconds and in frame times,
  frames skipped, the process's resident memory after the first 10 % of the frames and at
  the end, and the result files' writing (median per frame, arrival to disk p95).
  Target: 95th percentile under two frame times with ``--latest``, memory flat.
* ``write`` (issue 44) — writing one frame's result: the oracle tracker's result on a synthetic
  5x5 frame of ``--write-size`` (default 480x640, 3 objects), written ``--write-repeats`` times
  (median and best, milliseconds; file size) as result format 1 did (int32 labels,
  ``numpy.savez_compressed``) and as format 2 does at zlib levels 6, 1 (a video's frames) and 0;
  the object ids of its labels by ``numpy.unique`` and by ``label_ids``; and a live writer's
  cost to the tracking thread per frame (the hand-over) against its writer thread's. Then
  ``--write-frames`` such frames (their views as an uncompressed ``.npz``, hard-linked in) at
  ``--write-rate`` per second (default 60 at 30/s) followed with ``latest=True`` by a tracker
  that returns that result at once, the results written as format 1 on the tracking thread
  (before issue 44), as format 2 level 1 on it, and behind it: frames processed per second,
  latency, write time, arrival to disk. Target: a 30-per-second stream not bounded by
  writing (33 ms per frame).

Usage::

    python benchmarks/bench_video.py [--parts speed,memory,stream] [--size 96x128]
        [--grid 9x9] [--frames 6] [--models oracle,sam2-tiny-test] [--settings all,sparse]
        [--memory-frames 3,6,12] [--stream-runs edgetam:memory,...] [--rate 1]
        [--latest-model oracle] [--latest-frames 100] [--latest-size 96x128]
        [--write-size 480x640] [--write-repeats 7] [--write-frames 60] [--write-rate 30]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

import torch

from lfsam.api import RunOptions, SegmentOptions, segment
from lfsam.pipeline import PipelineConfig
from lfsam.prompts import ObjectPrompts, PointPrompt
from lfsam.segmenters import load_segmenter
from lfsam.video import read_video
from lfsam.video.io.synth import generate_video, write_video_frames
from lfsam.video.stream import live
from lfsam.video.stream.follow import FrameFollower
from lfsam.video.stream.live import segment_stream
from lfsam.video.tracking.online import OnlineTracker
from lfsam.video.tracking.track import track_video


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


def keep_objects_present(tracker) -> None:
    """Raise the memory's object-score bias by 50 (random weights score objects absent)."""
    memory = tracker._memory
    model = getattr(memory, "predictor", None) or memory.model
    decoder = getattr(model, "sam_mask_decoder", None) or model.mask_decoder
    head = decoder.pred_obj_score_head
    last = head.layers[-1] if hasattr(head, "layers") else head
    with torch.no_grad():
        last.bias += 50.0


def land_frames(sources: list[Path], folder: Path, rate: float) -> None:
    """Land ``sources`` in ``folder`` at ``rate`` frames per second, then END."""
    start = time.monotonic()
    for index, source in enumerate(sources):
        time.sleep(max(0.0, start + index / rate - time.monotonic()))
        hidden = folder / f".{source.name}.part"
        shutil.copytree(source, hidden)
        hidden.rename(folder / source.name)
    (folder / "END").write_bytes(b"")


def stream_part(args: argparse.Namespace, work: Path) -> None:
    size = parse_size(args.stream_size)
    source = work / "stream_clip"
    write_video_frames(generate_video(grid=(5, 5), size=size, frames=args.stream_frames,
                                      seed=0, num_objects=3), source)
    frames = sorted(p for p in source.iterdir() if p.name.startswith("frame_"))
    first = read_video(source).frame(0)
    print(f"\n## stream: 5x5 views of {size[0]}x{size[1]}, {len(frames)} frames landing at "
          f"{args.rate:g}/s, 3 objects, --refine-views 1, video memory, ground-truth "
          "disparity, CPU, random weights\n")
    print("| model | tracking | encoder pass (s) | s/frame (mean) | sustained frames/s | "
          "encoder passes per frame | latency median (s) | latency worst (s) | objects | "
          "write median (ms) | arrival to disk p95 (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    objects = [obj for obj in clicks(first) if obj.obj_id != 1]  # label 1: the backdrop
    for run in args.stream_runs:
        name, tracking = run.split(":")
        segmenter = load_segmenter(name, random_weights=True, device="cpu",
                                   keep_decoder_state=False)
        view = first.views[first.center][None]
        segmenter.encode(view)  # warm-up
        passes = []
        for _ in range(5):
            start = time.perf_counter()
            segmenter.encode(view)
            passes.append(time.perf_counter() - start)
        encoder = statistics.median(passes)
        options = SegmentOptions(pipeline=PipelineConfig(refine_views=1),
                                 run=RunOptions(progress=False))
        memory = tracking == "memory"
        if memory:
            warm = OnlineTracker(segmenter, disparity="gt", options=options, memory=True)
            warm.add_prompts(objects)
            warm.track(first)  # builds the memory's model (not counted)
            keep_objects_present(warm)
        tracker = OnlineTracker(segmenter, disparity="gt", options=options, memory=memory)
        tracker.add_prompts(objects)
        folder = work / f"in_{name}_{tracking}"
        folder.mkdir()
        seconds: list[float] = []
        present: list[int] = []

        def record(timing, result, seconds=seconds, present=present) -> None:
            seconds.append(timing.seconds)
            center = result.labels[tuple(s // 2 for s in result.labels.shape[:2])]
            present.append(int((np.unique(center) > 0).sum()))

        writer = threading.Thread(target=land_frames, args=(frames, folder, args.rate))
        writer.start()
        report = segment_stream(FrameFollower(folder, poll=0.01), tracker,
                                work / f"out_{name}_{tracking}", on_frame=record)
        writer.join()
        mean = statistics.fmean(seconds)
        lat = report.summary()
        print(f"| {name} | {tracking} | {encoder:.3f} | {mean:.3f} | {1 / mean:.2f} | "
              f"{mean / encoder:.2f} | {lat['latency_median_s']:.3f} | "
              f"{lat['latency_worst_s']:.3f} | {min(present)}-{max(present)} | "
              f"{lat['write_median_s'] * 1000:.1f} | {lat['disk_latency_p95_s']:.3f} |",
              flush=True)
    print("\ntargets: edgetam >= 1 frame/s sustained; sam2.1-hiera-tiny <= 1.3 encoder passes "
          "per frame")


def rss_mib() -> float:
    """The process's resident memory now (MiB; Linux ``/proc/self/statm``)."""
    import os

    pages = int(Path("/proc/self/statm").read_text().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def land_cycle(sources: list[Path], folder: Path, count: int, rate: float) -> None:
    """Land ``count`` frames ``frame_NNNN`` (``sources`` in turn) at ``rate`` per second, each
    written under a hidden name and renamed in, then END."""
    start = time.monotonic()
    for index in range(count):
        time.sleep(max(0.0, start + index / rate - time.monotonic()))
        hidden = folder / f".frame_{index:04d}.part"
        shutil.copytree(sources[index % len(sources)], hidden)
        hidden.rename(folder / f"frame_{index:04d}")
    (folder / "END").write_bytes(b"")


def latest_part(args: argparse.Namespace, work: Path) -> None:
    from lfsam.video.stream.live import percentile

    size, grid = parse_size(args.latest_size), parse_size(args.latest_grid)
    source = work / "latest_clip"
    write_video_frames(generate_video(grid=grid, size=size, frames=10, seed=0, num_objects=3),
                       source)
    sources = sorted(p for p in source.iterdir() if p.name.startswith("frame_"))
    video = read_video(source)
    objects = clicks(video.frame(0))
    options = SegmentOptions(pipeline=PipelineConfig(refine_views=1),
                             run=RunOptions(progress=False))
    model = model_for(args.latest_model, video.frame(0))

    def tracker() -> OnlineTracker:
        made = OnlineTracker(model, disparity="gt", options=options)
        made.add_prompts(objects)
        return made

    probe = tracker()
    times = []
    for index in range(6):
        lf = video.frame(index)
        start = time.perf_counter()
        probe.track(lf)
        times.append(time.perf_counter() - start)
    frame_time = statistics.median(times[1:])
    rate = 2 / frame_time
    print(f"\n## latest: a camera twice as fast as the tracker: {args.latest_model}, "
          f"{grid[0]}x{grid[1]} views of {size[0]}x{size[1]}, 3 objects, --refine-views 1, "
          f"ground-truth disparity, CPU; tracker {frame_time:.3f} s per frame (median of 5), "
          f"{args.latest_frames} frames landing at {rate:.1f}/s\n")
    print("| --latest | frames processed | processed per s | s per frame | latency median (s) | "
          "latency p95 (s) | p95 in frame times | latency worst (s) | skipped | "
          "reads per frame | RSS after 10 % (MiB) | RSS at end (MiB) | write median (ms) | "
          "arrival to disk p95 (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    reads = [0]
    read_lightfield = live.read_lightfield

    def counted(*a, **k):  # frames read (decoded) by the prefetch thread
        reads[0] += 1
        return read_lightfield(*a, **k)

    live.read_lightfield = counted
    for latest in (True, False):
        folder = work / f"latest_in_{latest}"
        folder.mkdir()
        rss: list[float] = []
        done: list[float] = []

        def record(timing, result, rss=rss, done=done) -> None:
            rss.append(rss_mib())
            done.append(time.perf_counter())

        # the camera is a process of its own (as a real one is), so the tracker's Python
        # threads do not share their interpreter lock with it
        writer = multiprocessing.get_context("fork").Process(
            target=land_cycle, args=(sources, folder, args.latest_frames, rate))
        began = time.perf_counter()
        writer.start()
        reads[0] = 0
        report = segment_stream(FrameFollower(folder, poll=0.01), tracker(),
                                work / f"latest_out_{latest}", on_frame=record, latest=latest)
        writer.join()
        lat = report.latencies
        p95 = percentile(lat, 95)
        early = rss[max(0, len(rss) // 10 - 1)]
        period = statistics.median(np.diff(done))  # the tracker's frame time in this stream
        print(f"| {'yes' if latest else 'no'} | {report.frames} | "
              f"{report.frames / (done[-1] - began):.2f} | {period:.3f} | "
              f"{statistics.median(lat):.3f} | {p95:.3f} | {p95 / period:.2f} | "
              f"{max(lat):.3f} | {len(report.skipped)} | {reads[0] / report.frames:.2f} | "
              f"{early:.0f} | {rss[-1]:.0f} | {statistics.median(report.write_seconds) * 1000:.1f}"
              f" | {percentile(report.disk_latencies, 95):.3f} |", flush=True)
    live.read_lightfield = read_lightfield
    print("\ntarget: with --latest the 95th-percentile latency under 2 frame times; memory flat")


def format1_save(result, path: Path) -> None:
    """A result file as ``save_result`` wrote it before format 2 (issue 44): int32 labels,
    ``numpy.savez_compressed`` (zlib level 6), atomically; the baseline of the write part."""
    from lfsam.fileutil import atomic_output

    arrays = {"format_version": np.array(1), "labels": np.asarray(result.labels, np.int32),
              "timings": np.array(json.dumps(result.timings)),
              "meta": np.array(json.dumps(result.meta, default=str)),
              "masks_packed": result.masks.data,
              "masks_shape": np.array(result.masks.shape, dtype=np.int64)}
    for name in ("scores", "fallback", "refine_iou", "present"):
        if getattr(result, name) is not None:
            arrays[name] = np.asarray(getattr(result, name))
    with atomic_output(path) as tmp, open(tmp, "wb") as handle:
        np.savez_compressed(handle, **arrays)


class _Replay:
    """A tracker that returns one precomputed result at once: a stream bounded only by reading
    frames and writing results (the ``write`` part's stream)."""

    name, auto, texts, disparity, tracking = "replay", False, (), "gt", "replay"

    def __init__(self, result) -> None:
        self.result, self.prompts, self.text_finds = result, [], {}

    def track(self, lf):
        from lfsam.result import SegmentationResult

        return SegmentationResult(labels=self.result.labels, masks=self.result.masks,
                                  scores=self.result.scores, meta={})


def write_stream(result, lf, work: Path, frames: int, rate: float, mode: str) -> dict:
    """``frames`` light fields landing at ``rate`` per second, followed with ``latest=True`` by
    :class:`_Replay`; ``mode``: ``before`` (format 1 written on the tracking thread, as before
    issue 44), ``inline`` (format 2, level 1, on the tracking thread) or ``behind`` (format 2,
    level 1, the writer thread)."""
    import os

    import lfsam.video.io.live_result as live_result
    import lfsam.video.io.result as video_result
    from lfsam.io.arrays import write_npz
    from lfsam.lightfield import LightField
    from lfsam.video.stream.live import percentile

    source = work / "source.npz"
    if not source.exists():  # the views only, as a camera writes them
        write_npz(LightField(views=lf.views), source, compress=False)
    folder, out = work / f"in_{mode}", work / f"out_{mode}"
    folder.mkdir()

    def land() -> None:
        start = time.monotonic()
        for index in range(frames):
            time.sleep(max(0.0, start + index / rate - time.monotonic()))
            hidden = folder / f".frame_{index:04d}.npz"
            os.link(source, hidden)
            hidden.rename(folder / f"frame_{index:04d}.npz")
        (folder / "END").write_bytes(b"")

    save, write = video_result.save_result, live_result._LiveWriter.write
    if mode == "before":
        video_result.save_result = lambda r, path, **k: format1_save(r, path)
    if mode != "behind":
        def inline(self, r, arrived=None):  # the write waited for, as before issue 44
            write(self, r, arrived)
            self.flush()
        live_result._LiveWriter.write = inline
    done: list[float] = []
    try:
        camera = threading.Thread(target=land)
        began = time.time()
        camera.start()
        report = segment_stream(FrameFollower(folder, poll=0.005), _Replay(result), out,
                                on_frame=lambda timing, r: done.append(time.time()),
                                latest=True)
        camera.join()
    finally:
        video_result.save_result, live_result._LiveWriter.write = save, write
    return {"processed": report.frames, "per_s": report.frames / (done[-1] - began),
            "p50": statistics.median(report.latencies),
            "p95": percentile(report.latencies, 95),
            "write": statistics.median(report.write_seconds),
            "disk95": percentile(report.disk_latencies, 95)}


def write_part(args: argparse.Namespace, work: Path) -> None:
    from lfsam.result import FAST_LEVEL, label_ids, save_result
    from lfsam.video.io.live_result import live_video_result_writer

    size, repeats = parse_size(args.write_size), args.write_repeats
    lf = next(iter(generate_video(grid=(5, 5), size=size, frames=1, seed=0, num_objects=3)))
    tracker = OnlineTracker("oracle", disparity="gt", options=SegmentOptions(
        pipeline=PipelineConfig(refine_views=1), run=RunOptions(progress=False)))
    tracker.add_prompts([obj for obj in clicks(lf) if obj.obj_id != 1])
    result = tracker.track(lf)
    ids = [int(i) for i in np.unique(result.labels) if i > 0]
    print(f"\n## write: one frame's result, 5x5 views of {size[0]}x{size[1]}, objects {ids} "
          f"(the oracle tracker on a synthetic frame; {result.masks.num_masks} packed masks), "
          f"median of {repeats}, CPU\n")
    print("| writer | ms per frame (median) | best | file (KiB) |")
    print("|---|---|---|---|")

    def timed(call) -> tuple[float, float]:
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            call()
            times.append(time.perf_counter() - start)
        return statistics.median(times) * 1000, min(times) * 1000

    path = work / "one.npz"
    writers = [("format 1: int32, numpy.savez_compressed (before)",
                lambda: format1_save(result, path)),
               ("format 2, level 6 (save_result's default)", lambda: save_result(result, path)),
               (f"format 2, level {FAST_LEVEL} (a video's frames)",
                lambda: save_result(result, path, level=FAST_LEVEL)),
               ("format 2, level 0 (stored)", lambda: save_result(result, path, level=0))]
    for name, call in writers:
        median, best = timed(call)
        print(f"| {name} | {median:.1f} | {best:.1f} | {path.stat().st_size / 1024:.0f} |")
    for name, call in (("object ids: numpy.unique (before)", lambda: np.unique(result.labels)),
                       ("object ids: label_ids (run ends)", lambda: label_ids(result.labels))):
        median, best = timed(call)
        print(f"| {name} | {median:.1f} | {best:.1f} | |")
    handed: list[float] = []
    with live_video_result_writer(work / "live") as writer:
        for _ in range(repeats):
            start = time.perf_counter()
            writer.write(result)
            handed.append(time.perf_counter() - start)
            time.sleep(0.1)  # a tracker's frame: the writer thread catches up meanwhile
    behind = statistics.median(writer.write_seconds) * 1000
    print(f"| the tracking thread's cost per frame, live writer (hand-over) | "
          f"{statistics.median(handed) * 1000:.2f} | {min(handed) * 1000:.2f} | |")
    print(f"| the live writer's thread per frame (file, ids; behind the tracking) | "
          f"{behind:.1f} | {min(writer.write_seconds) * 1000:.1f} | |")
    print(f"\n{args.write_frames} such frames landing at {args.write_rate:g}/s, followed with "
          "--latest by a tracker that returns this result at once (so only reading frames and "
          "writing results bound it):\n")
    print("| results written | frames processed | processed per s | latency median (ms) | "
          "latency p95 (ms) | write median (ms) | arrival to disk p95 (ms) |")
    print("|---|---|---|---|---|---|---|")
    for mode, name in (("before", "format 1, on the tracking thread (before)"),
                       ("inline", f"format 2 level {FAST_LEVEL}, on the tracking thread"),
                       ("behind", f"format 2 level {FAST_LEVEL}, behind (writer thread)")):
        got = write_stream(result, lf, work, args.write_frames, args.write_rate, mode)
        print(f"| {name} | {got['processed']} of {args.write_frames} | {got['per_s']:.1f} | "
              f"{got['p50'] * 1000:.0f} | {got['p95'] * 1000:.0f} | {got['write'] * 1000:.1f} | "
              f"{got['disk95'] * 1000:.0f} |", flush=True)
    print("\ntarget (issue 44): a 30-per-second stream not bounded by writing its results "
          "(33 ms per frame)")


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
    parser.add_argument("--stream-runs",
                        default="edgetam:memory,sam2.1-hiera-tiny:memory,"
                                "sam2.1-hiera-tiny:prompts",
                        help="MODEL:TRACKING pairs (tracking: memory or prompts)")
    parser.add_argument("--stream-size", default="240x320")
    parser.add_argument("--stream-frames", type=int, default=30)
    parser.add_argument("--rate", type=float, default=1.0, help="frames landing per second")
    parser.add_argument("--latest-model", default="oracle")
    parser.add_argument("--latest-frames", type=int, default=100)
    parser.add_argument("--latest-size", default="96x128")
    parser.add_argument("--latest-grid", default="5x5")
    parser.add_argument("--write-size", default="480x640")
    parser.add_argument("--write-repeats", type=int, default=7)
    parser.add_argument("--write-frames", type=int, default=60)
    parser.add_argument("--write-rate", type=float, default=30.0)
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
        if "stream" in parts:
            args.stream_runs = args.stream_runs.split(",")
            stream_part(args, work)
        if "latest" in parts:
            latest_part(args, work)
        if "write" in parts:
            write_part(args, work)


if __name__ == "__main__":
    main()
