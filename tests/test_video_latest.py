"""Live streams that never fall behind (issue 44, docs/design.md section 10): ``--latest``
segments the newest frame that has arrived and lists every frame it leaves out, a prefetch
thread reads the next frame while the current one is segmented, latency stays bounded when the
camera is faster than the tracker, and the frames held in memory stay few."""

from __future__ import annotations

import shutil
import statistics
import threading
import time
import weakref
from pathlib import Path

import numpy as np
import pytest

import lfsam
import lfsam.video.stream.live as live
from lfsam.api import RunOptions, SegmentOptions
from lfsam.cli.main import main
from lfsam.prompts import ObjectPrompts, PointPrompt
from lfsam.video import read_video
from lfsam.video.io.synth import generate_video, write_video_frames
from lfsam.video.stream.feed import NEWER_FRAME, FrameFeed
from lfsam.video.stream.follow import FrameFollower
from lfsam.video.stream.live import percentile, segment_stream
from lfsam.video.tracking.online import OnlineTracker

QUIET = SegmentOptions(run=RunOptions(progress=False))
OBJECT = 3  # the ground-truth label clicked (label 1 is the backdrop)


@pytest.fixture(scope="module")
def clip(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("latest") / "clip"
    write_video_frames(generate_video(grid=(3, 3), size=(48, 64), frames=4, seed=0,
                                      num_objects=3), folder)
    return folder


def _click(lf) -> PointPrompt:
    from scipy import ndimage

    depth = ndimage.distance_transform_edt(lf.labels[lf.center] == OBJECT)
    row, col = np.unravel_index(int(np.argmax(depth)), depth.shape)
    return PointPrompt(float(col), float(row))


def _land(sources: list[Path], folder: Path, count: int, interval: float) -> None:
    """Land ``count`` frames (the sources in turn, named frame_0000...) every ``interval`` s,
    each written under a hidden name and renamed in, then END."""
    start = time.monotonic()
    for index in range(count):
        time.sleep(max(0.0, start + index * interval - time.monotonic()))
        hidden = folder / f".frame_{index:04d}.part"
        shutil.copytree(sources[index % len(sources)], hidden)
        hidden.rename(folder / f"frame_{index:04d}")
    (folder / "END").write_bytes(b"")


def _stream(clip: Path, tmp_path: Path, name: str, latest: bool, period: float, count: int,
            monkeypatch):
    """A producer landing ``count`` frames at twice the tracker's rate (the tracker padded to
    ``period`` s per frame) while ``segment_stream`` follows; returns the report, the frames'
    timings and the most light fields alive at once (read but not yet freed)."""
    folder = tmp_path / f"in_{name}"
    folder.mkdir()
    sources = sorted(clip.glob("frame_*"))
    tracker = OnlineTracker("oracle", disparity="gt", options=QUIET)
    tracker.add_prompts([ObjectPrompts(1, (_click(read_video(clip).frame(0)),))])
    real = tracker.track

    def padded(lf):
        start = time.perf_counter()
        result = real(lf)
        time.sleep(max(0.0, period - (time.perf_counter() - start)))
        return result

    tracker.track = padded
    alive: list[weakref.ref] = []
    most = [0]
    reader = live.read_lightfield

    def counted(*args, **kwargs):
        lf = reader(*args, **kwargs)
        alive.append(weakref.ref(lf))
        return lf

    monkeypatch.setattr(live, "read_lightfield", counted)
    timings = []

    def on_frame(timing, result) -> None:
        timings.append((timing, time.monotonic()))
        most[0] = max(most[0], sum(ref() is not None for ref in alive))

    writer = threading.Thread(target=_land, args=(sources, folder, count, period / 2))
    writer.start()
    report = segment_stream(FrameFollower(folder, poll=0.01), tracker, tmp_path / f"out_{name}",
                            on_frame=on_frame, latest=latest)
    writer.join()
    return report, timings, most[0]


def test_latest_keeps_latency_bounded_where_the_backlog_grows(clip, tmp_path, monkeypatch):
    period, count = 0.2, 40
    fast, timings, held = _stream(clip, tmp_path, "latest", True, period, count, monkeypatch)
    # the frame time: the tracker's own period between results, measured in this run
    done = [t for _, t in timings]
    frame_time = statistics.median(np.diff(done))
    assert frame_time >= period
    p95 = percentile(fast.latencies, 95)
    assert p95 < 2 * frame_time, (p95, frame_time)
    assert fast.frames < count  # frames were left out ...
    result = lfsam.load_result(tmp_path / "out_latest")
    sources = [result.frame(f).meta["frame_source"] for f in range(len(result))]
    skipped = [s["name"] for s in result.meta["skipped"]]
    # ... every one of them named, with its reason, and none segmented twice or lost
    assert sorted(sources + skipped) == [f"frame_{i:04d}" for i in range(count)]
    assert all(s["reason"] == NEWER_FRAME for s in result.meta["skipped"])
    assert sources[-1] == f"frame_{count - 1:04d}"  # the stream ends on the newest frame
    assert fast.summary()["superseded"] == count - fast.frames
    assert sum(t.superseded for t, _ in timings) == count - fast.frames
    arrivals = [result.frame(f).meta["arrival_index"] for f in range(len(result))]
    indices = [result.frame(f).meta["frame"] for f in range(len(result))]
    assert arrivals == sorted(arrivals) and indices == list(range(len(result)))
    assert result.meta["latest"] is True and held <= 3  # segmented + read ahead + being read
    assert (result.labels[0] == 1).any()  # the clicked object is segmented
    # every frame's file was written behind the tracker and timed (issue 44)
    assert len(fast.write_seconds) == len(fast.disk_latencies) == fast.frames
    assert result.meta["write"] == fast.write_summary() and fast.write_summary()["write_p95_s"]

    count = 12
    slow, _, held = _stream(clip, tmp_path, "backlog", False, period, count, monkeypatch)
    assert slow.frames == count and not slow.skipped
    # without --latest the camera's backlog queues: the latency grows frame after frame
    first, last = statistics.fmean(slow.latencies[:4]), statistics.fmean(slow.latencies[-4:])
    assert last > first + 0.25 * count * period, (first, last)
    assert percentile(slow.latencies, 95) > 2 * frame_time
    assert held <= 3  # the backlog is a list of names; one frame read ahead


def test_feed_takes_the_newest_frame_and_reports_unreadable_ones(tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    for index in range(5):
        (folder / f"f_{index}.npz").write_bytes(b"")
    (folder / "END").write_bytes(b"")

    def slow_read(arrived):
        time.sleep(0.1)  # every entry is queued before the first read ends
        if arrived.path.name == "f_4.npz":
            raise ValueError("damaged")
        return arrived.path.name

    superseded = []
    feed = FrameFeed(FrameFollower(folder, poll=0.01), slow_read, latest=True,
                     on_superseded=lambda a: superseded.append(a.path.name))
    items = list(feed)
    names = [item.arrived.path.name for item in items]
    # the newest frame is read next; the first one read may go to the idle consumer first
    assert names in (["f_4.npz"], ["f_0.npz", "f_4.npz"])
    with pytest.raises(ValueError, match="damaged"):
        items[-1].lightfield()  # unreadable: handed over as such, not superseded
    assert sorted(superseded + names) == [f"f_{i}.npz" for i in range(5)]
    assert superseded[-1] == "f_3.npz" and "f_4.npz" not in superseded
    in_order = FrameFeed(FrameFollower(folder, poll=0.01), slow_read)
    assert [item.arrived.path.name for item in in_order] == [f"f_{i}.npz" for i in range(5)]
    assert in_order.peak_held <= 2


def test_the_timeout_waits_while_a_frame_is_segmented(clip, tmp_path):
    """--follow-timeout counts the time without a new frame while nothing is being done."""
    folder = tmp_path / "in"
    folder.mkdir()
    sources = sorted(clip.glob("frame_*"))
    shutil.copytree(sources[0], folder / sources[0].name)
    tracker = OnlineTracker("oracle", disparity="gt", options=QUIET)
    tracker.add_prompts([ObjectPrompts(1, (_click(read_video(clip).frame(0)),))])
    real = tracker.track

    def slow(lf):
        if tracker.frames_done == 0:  # a frame arrives during a segmentation longer than S
            time.sleep(0.8)
            shutil.copytree(sources[1], folder / ".part")
            (folder / ".part").rename(folder / sources[1].name)
        return real(lf)

    tracker.track = slow
    report = segment_stream(FrameFollower(folder, timeout=0.4, poll=0.01), tracker,
                            tmp_path / "out")
    assert report.frames == 2 and report.ended_by == "timeout"


def test_cli_latest_with_a_backlog_segments_the_newest_frame(clip, tmp_path, capsys):
    folder, out = tmp_path / "in", tmp_path / "out"
    folder.mkdir()
    frames = sorted(clip.glob("frame_*"))
    for source in frames:
        shutil.copytree(source, folder / source.name)
    (folder / "END").write_bytes(b"")
    click = _click(read_video(clip).frame(0))
    code = main(["segment", str(folder), "--follow", "--latest", "--point",
                 f"{click.x:g},{click.y:g}", "--model", "oracle", "--disparity", "gt",
                 "--out", str(out), "--poll", "0.02"])
    assert code == 0
    result = lfsam.load_result(out)
    names = [f.name for f in frames]
    done = [result.frame(f).meta["frame_source"] for f in range(len(result))]
    assert done[-1] == names[-1] and len(done) < len(names)
    assert sorted(done + [s["name"] for s in result.meta["skipped"]]) == names
    err = capsys.readouterr().err
    assert "older skipped" in err
    assert main(["segment", str(folder), "--latest", "--auto", "--out",
                 str(tmp_path / "x")]) == 2
    assert "--latest goes with --follow" in capsys.readouterr().err
