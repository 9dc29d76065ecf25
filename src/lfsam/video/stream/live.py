"""Segmenting a live light-field stream: frames segmented as a camera writes them
(docs/design.md section 10, issue 35; ``lfsam segment FOLDER --follow``, the viewer's Follow).

:func:`segment_stream` joins the three parts: :class:`lfsam.video.stream.follow.FrameFollower`
yields each frame as it lands, :class:`lfsam.video.tracking.online.OnlineTracker` segments it at
once (ids and video memory kept), and :func:`lfsam.video.io.live_result.live_video_result_writer`
writes its result into the result folder in a writer thread while the next frame is segmented (issue
44: each file atomic; the folder reads as a valid result of the frames on disk at any moment, and
every frame handed over is written before :func:`segment_stream` returns, also on an error or
Ctrl-C).

A frame at fault (:class:`lfsam.errors.FrameError`: one that cannot be read — damaged,
half-written by a writer that does not rename — is read once more after :data:`RETRY_SECONDS`
first; one of another grid or view size) is skipped: one line through ``on_skip``, listed in
the result's ``meta["skipped"]``; the stream goes on and nothing already written changes. Any
other :class:`~lfsam.errors.LfsamError` while a frame is segmented is the configuration's (the
oracle on frames without ground-truth labels, ``--disparity gt`` without ground truth, prompts
outside the views): every frame would fail the same way, so the stream stops at the first, the
result folder valid with the frames done (``meta["ended_by"] = "error"``, ``meta["error"]``),
and one line is raised (issue 46). Frame indices (of the result and of prompts' ``#F``) count
the frames segmented. Ctrl-C (``KeyboardInterrupt``) drops the frame in progress and ends the
stream like ``END``: ``ended_by`` says ``"interrupted"``.
"""

from __future__ import annotations

import os
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from lfsam.errors import FrameError, LfsamError
from lfsam.io import read_lightfield
from lfsam.lightfield import LightField
from lfsam.result import SegmentationResult
from lfsam.version import __version__
from lfsam.video.io.live_result import live_video_result_writer
from lfsam.video.io.result import hidden_spans, record_states
from lfsam.video.stream.feed import NEWER_FRAME, FrameFeed
from lfsam.video.stream.follow import ArrivedFrame, FrameFollower
from lfsam.video.tracking.online import OnlineTracker

__all__ = ["RETRY_SECONDS", "FrameTiming", "StreamReport", "segment_stream"]

#: Seconds before a frame that could not be read is read once more.
RETRY_SECONDS = 0.5


@dataclass(frozen=True)
class FrameTiming:
    """When one frame of a stream was done.

    Attributes
    ----------
    index : int
        The frame's index in the result.
    name : str
        Its entry's name in the followed folder.
    latency : float
        Seconds from its arrival to its result (handed to ``on_frame``; the writer thread puts
        its file on disk after, ``StreamReport.disk_latencies``).
    seconds : float
        Seconds spent segmenting it (it was read ahead while the frame before was segmented).
    superseded : int
        Frames left out for it (``latest``: they arrived before it and were not segmented).
    """

    index: int
    name: str
    latency: float
    seconds: float
    superseded: int = 0


@dataclass
class StreamReport:
    """How a followed stream went."""

    out: Path
    frames: int = 0
    ended_by: str | None = None
    skipped: list[dict[str, str]] = field(default_factory=list)
    latencies: list[float] = field(default_factory=list)
    object_ids: list[int] = field(default_factory=list)
    #: Each object's runs of hidden frames (:func:`lfsam.video.io.result.hidden_spans`).
    hidden: dict[str, list[list[int]]] = field(default_factory=dict)
    #: Seconds each frame's file took to write (in the writer thread), in order.
    write_seconds: list[float] = field(default_factory=list)
    #: Seconds from each frame's arrival to its file on disk.
    disk_latencies: list[float] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        """Frames, skipped frames (of them ``superseded``: left out for a newer frame), how it
        ended, the objects and their runs of hidden frames (``hidden``, as
        :func:`lfsam.video.io.result.hidden_spans`), latency median, 95th percentile and worst,
        and the result files' writing (:meth:`write_summary`), in seconds."""
        lat = self.latencies
        return {
            "out": str(self.out), "frames": self.frames, "skipped": len(self.skipped),
            "superseded": sum(s.get("reason") == NEWER_FRAME for s in self.skipped),
            "ended_by": self.ended_by, "objects": self.object_ids, "hidden": self.hidden,
            "latency_median_s": round(statistics.median(lat), 3) if lat else None,
            "latency_p95_s": round(percentile(lat, 95), 3) if lat else None,
            "latency_worst_s": round(max(lat), 3) if lat else None,
            **self.write_summary(),
        }

    def write_summary(self) -> dict[str, float | None]:
        """Per-frame write time (median, 95th percentile) and arrival to file on disk (95th
        percentile), seconds (``meta["write"]`` of the result)."""
        def p(values: list[float], q: float) -> float | None:
            return round(percentile(values, q), 4) if values else None

        return {"write_median_s": p(self.write_seconds, 50),
                "write_p95_s": p(self.write_seconds, 95),
                "disk_latency_p95_s": p(self.disk_latencies, 95)}


def percentile(values: list[float], q: float) -> float:
    """The ``q``-th percentile of ``values`` (linear interpolation, as ``numpy.percentile``)."""
    ordered = sorted(values)
    at = (len(ordered) - 1) * q / 100
    low = int(at)
    high = min(low + 1, len(ordered) - 1)
    return ordered[low] + (ordered[high] - ordered[low]) * (at - low)


def _read_frame(arrived: ArrivedFrame, value_range: int | None) -> LightField:
    """The frame's light field, read once more after :data:`RETRY_SECONDS` if it fails.

    Raises
    ------
    FrameError
        It cannot be read the second time either.
    """
    try:
        return read_lightfield(arrived.path, value_range=value_range)
    except (LfsamError, OSError, ValueError):
        time.sleep(RETRY_SECONDS)
    try:
        return read_lightfield(arrived.path, value_range=value_range)
    except (LfsamError, OSError, ValueError) as exc:
        raise FrameError(str(exc) if isinstance(exc, LfsamError) else
                         f"cannot read it ({exc})") from exc


def segment_stream(
    follower: FrameFollower,
    tracker: OnlineTracker,
    out: str | os.PathLike,
    *,
    value_range: int | None = None,
    on_frame: Callable[[FrameTiming, SegmentationResult], None] | None = None,
    on_skip: Callable[[str], None] | None = None,
    latest: bool = False,
    on_lightfield: Callable[[FrameTiming, SegmentationResult, LightField], None] | None = None,
) -> StreamReport:
    """Segment every frame ``follower`` yields, writing each result into ``out`` at once.

    Parameters
    ----------
    follower : FrameFollower
        The followed frames folder (it decides when the stream ends).
    tracker : OnlineTracker
        Holds the model, options, prompts and memory (prompts may be added between frames,
        e.g. from ``on_frame``).
    out : path-like
        The live result folder (:func:`lfsam.video.io.live_result.check_live_folder`: new or empty).
    value_range : int, optional
        Passed to :func:`lfsam.io.read_lightfield` for each frame.
    on_frame : callable, optional
        ``on_frame(timing, result)`` after each frame is segmented, in this thread; its file
        follows from the writer thread (the folder lists it once written).
    on_skip : callable, optional
        ``on_skip(message)`` with one line for each frame skipped as unreadable or refused
        (not for frames superseded with ``latest``: each frame's timing counts those).
    latest : bool
        Never fall behind (``--latest``): always segment the newest frame that has arrived;
        the frames that arrived before it and were not started are left out, each listed in
        ``meta["skipped"]`` with the reason ``"newer frame available"``
        (:class:`lfsam.video.stream.feed.FrameFeed`). Either way the next frame is read in a
        prefetch thread while the current one is segmented.
    on_lightfield : callable, optional
        ``on_lightfield(timing, result, lightfield)`` after ``on_frame``, with the frame's light
        field (``lfsam segment --follow --poses`` registers its objects there).

    Returns
    -------
    StreamReport
        ``ended_by`` is ``"END"``, ``"timeout"``, ``"stopped"`` or ``"interrupted"``.

    Raises
    ------
    LfsamError
        The first configuration fault (see the module docstring): one line naming the frame
        and how many frames were done, raised after they are published. Any other exception
        (a bug, a full disk) propagates after the frames done so far are published.
    """
    report = StreamReport(Path(out))
    meta: dict[str, Any] = {
        "method": "lfsam-video", "input": str(follower.folder), "model": tracker.name,
        "prompt_mode": "auto" if tracker.auto else "text" if tracker.texts else "prompts",
        "package_version": __version__,
        "disparity": tracker.disparity, "follow": True, "latest": bool(latest),
        "skipped": report.skipped, "ended_by": None, "tracks": {},
    }
    superseded: list[str] = []

    def supersede(arrived: ArrivedFrame) -> None:  # in the feed's thread
        with writer.lock:
            report.skipped.append({"name": arrived.path.name, "reason": NEWER_FRAME})
        superseded.append(arrived.path.name)

    feed = FrameFeed(follower, lambda arrived: _read_frame(arrived, value_range),
                     latest=latest, on_superseded=supersede)
    with live_video_result_writer(out, meta=meta, objects=lambda: tracker.prompts) as writer:
        current = None
        try:
            for item in feed:
                arrived, lf = item.arrived, None
                start, current = time.perf_counter(), arrived.path.name
                try:
                    lf = item.lightfield()
                    result = tracker.track(lf)
                except FrameError as exc:
                    line = f"frame {arrived.path.name} skipped: {exc}"
                    with writer.lock:
                        report.skipped.append({
                            "name": arrived.path.name, "error": str(exc),
                            "reason": "unreadable" if lf is None else "refused"})
                    if on_skip is not None:
                        on_skip(line)
                    continue
                result.meta["frame_source"] = arrived.path.name
                result.meta["arrival_index"] = arrived.index
                with writer.lock:  # the writer thread builds manifests from meta
                    meta["tracking"] = tracker.tracking
                    if tracker.texts:  # what the phrases found in the first frame
                        meta["text"] = tracker.text_finds
                    record_states(meta["tracks"], result.meta.get("tracks", {}),
                                  writer.accepted)
                writer.write(result, arrived=arrived.arrived)
                timing = FrameTiming(writer.accepted - 1, arrived.path.name,
                                     time.time() - arrived.arrived,
                                     time.perf_counter() - start, len(superseded))
                superseded.clear()
                report.latencies.append(timing.latency)
                report.frames = writer.accepted
                if on_frame is not None:
                    on_frame(timing, result)
                if on_lightfield is not None:
                    on_lightfield(timing, result, lf)
            report.ended_by = follower.ended_by
        except KeyboardInterrupt:
            report.ended_by = "interrupted"
        except LfsamError as exc:  # not the frame's: every frame would fail so
            feed.close()
            with writer.lock:
                report.ended_by = meta["ended_by"] = "error"
                meta["error"] = str(exc)
            done = (f"the {writer.accepted} frame(s) done are in {out}" if writer.accepted
                    else "nothing was written")
            where = f"at {current}; " if current else ""
            raise LfsamError(f"{exc} ({where}the stream stopped: {done})") from exc
        feed.close()
        writer.flush()  # every frame on disk: its objects, its write time
        report.write_seconds, report.disk_latencies = writer.write_seconds, writer.disk_latencies
        meta["ended_by"] = report.ended_by
        meta["latency"] = {k: v for k, v in report.summary().items() if k.startswith("latency")}
        meta["write"] = report.write_summary()
        report.object_ids = sorted(writer.object_ids)
        report.hidden = hidden_spans(meta["tracks"])
    return report
