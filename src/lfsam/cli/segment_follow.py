"""``lfsam segment FOLDER --follow``: segment a light-field camera's frames as they are written
(docs/design.md section 10, issue 35); called by :mod:`lfsam.cli.segment`."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

import numpy as np

from lfsam.cli.common import TRACKING_MODES, positive_float
from lfsam.cli.models import model_options_from_args
from lfsam.cli.prompts import objects_from_items
from lfsam.cli.text import check_text_weights, report_text
from lfsam.errors import LfsamError
from lfsam.fileutil import check_cache_dir, check_writable, write_text_atomic
from lfsam.prompts import load_prompts

__all__ = ["add_follow_arguments", "run_follow"]


def add_follow_arguments(parser: argparse.ArgumentParser) -> None:
    """``--follow``, ``--follow-timeout S``, ``--latest`` and ``--poll S``."""
    group = parser.add_argument_group(
        "live streams (a frames folder that is still growing)")
    group.add_argument(
        "--follow", action="store_true",
        help="PATH is a frames folder a camera is still writing: segment each frame as it "
        "lands (frames count once they are there, so rename complete frames in), write its "
        "result into --out at once and print its latency; ends at a file named END in PATH, "
        "after --follow-timeout, or on Ctrl-C, and --out then holds every frame done. Takes "
        "clicks and boxes, --auto or --text (found in the first frame, then tracked); a frame "
        "that cannot be read is skipped, a fault of the setup (e.g. the oracle on frames "
        "without labels) stops the stream with exit 2",
    )
    group.add_argument(
        "--follow-timeout", type=positive_float, default=None, metavar="S",
        help="with --follow: stop after S seconds without a new frame (default: wait for END "
        "or Ctrl-C)",
    )
    group.add_argument(
        "--latest", action="store_true",
        help="with --follow: never fall behind the camera: always segment the newest frame "
        "that has arrived and skip the older ones not yet started (each listed in the "
        "result's meta 'skipped' with the reason 'newer frame available'); for a control loop "
        "that needs the current scene, not the backlog",
    )
    group.add_argument(
        "--poll", type=positive_float, default=0.05, metavar="S",
        help="with --follow: seconds between looks at the folder (default 0.05)",
    )
    group.add_argument(
        "--poses", action="store_true",
        help="with --follow: register every object's 6D pose as each frame lands (as `lfsam "
        "poses`, docs/design.md section 12) and rewrite OUT/poses.json after each frame; the "
        "points come from every view with a ground-truth or file disparity, from the center "
        "view with an estimate",
    )
    group.add_argument(
        "--camera", metavar="CAMERA.json",
        help="with --poses: the camera (default: each frame's own, checked at the first)",
    )


class _LivePoses:
    """``--poses``: register each frame's objects and rewrite ``OUT/poses.json``."""

    def __init__(self, args: argparse.Namespace) -> None:
        from lfsam.poses import VideoPoses

        views = "center" if args.disparity == "estimate" else "all"
        self.session = VideoPoses(disparity=args.disparity, camera=args.camera, views=views,
                                  device=getattr(args, "device", None))
        self.out = args.out
        self.quiet = args.quiet

    def __call__(self, timing, result, lightfield) -> None:
        from pathlib import Path

        from lfsam.poses import poses_json

        entries = self.session.add(result, lightfield)
        document = poses_json(self.session.camera, self.session.objects,
                              disparity=str(self.session.disparity), views=self.session.views,
                              frames=self.session.frames)
        write_text_atomic(Path(self.out) / "poses.json", json.dumps(document, indent=1) + "\n")
        if not self.quiet:
            states = ", ".join(f"{e.status}" for e in entries)
            print(f"frame {timing.index}: poses of {len(entries)} objects ({states})",
                  file=sys.stderr, flush=True)


def _pose_session(args: argparse.Namespace) -> _LivePoses | None:
    """The ``--poses`` registration, its camera file checked before the stream starts."""
    if not args.poses:
        if args.camera:
            raise LfsamError("--camera goes with --poses (lfsam segment --follow --poses)")
        return None
    if args.camera:
        from lfsam.camera import load_camera

        args.camera = load_camera(args.camera)  # a bad file fails now, not at the first frame
    return _LivePoses(args)


def run_follow(args: argparse.Namespace, config: Any, has_prompts: bool) -> int:
    """Follow ``args.path``; exit 0 when the stream ends by END or the timeout, 130 on
    Ctrl-C (the frames done are in ``--out`` either way); a configuration fault raises
    :class:`LfsamError` at its first frame (exit 2, ``lfsam.video.stream.live``)."""
    from lfsam.api import RunOptions, SegmentOptions
    from lfsam.video.io.frames_folder import frame_entries
    from lfsam.video.io.live_result import check_live_folder
    from lfsam.video.stream.follow import FrameFollower, check_follow_folder
    from lfsam.video.stream.hidden_lines import HiddenSince, hidden_frames_text, hidden_now
    from lfsam.video.stream.live import segment_stream
    from lfsam.video.tracking.online import OnlineTracker

    if args.method != "lfsam":
        raise LfsamError("--follow tracks with --method lfsam only")
    poses = _pose_session(args)
    if args.text and (args.prompt_items or args.prompts):
        raise LfsamError("--follow takes --text or clicks and boxes, not both: the phrases' "
                         "objects are numbered as they are found in the first frame")
    check_follow_folder(args.path)
    check_writable(args.out, folder=True, option="--out", inside=True)
    check_live_folder(args.out)
    if args.cache is not None:
        check_cache_dir(args.cache)
    check_text_weights(args)  # missing SAM 3 weights: one line now, not at the first frame
    model_options = model_options_from_args(args)
    options = SegmentOptions(
        pipeline=config, model=model_options,
        run=RunOptions(method=args.method, references=args.references, cache_dir=args.cache,
                       progress=False),
    )
    objects = []
    if has_prompts and not args.text:
        objects = load_prompts(args.prompts) if args.prompts else []
        first = max((o.obj_id for o in objects), default=0) + 1
        objects += objects_from_items(args.prompt_items, first_id=first)
    # the model is loaded before the first frame is waited for (the oracle: per frame)
    model = "oracle" if model_options.name == "oracle" else model_options.build(
        keep_decoder_state=False)
    tracker = OnlineTracker(model, disparity=args.disparity, options=options,
                            memory=TRACKING_MODES[args.tracking], auto=args.auto,
                            texts=args.text or ())
    tracker.add_prompts(objects)
    follower = FrameFollower(args.path, timeout=args.follow_timeout, poll=args.poll)
    announced = [args.quiet]

    def announce() -> None:
        """The stream's first line: at once when it waits for a frame, else after the first
        frame's (a fault of the setup at the first frame is then the run's only line)."""
        if not announced[0]:
            announced[0] = True
            print(f"following {args.path} (END file, --follow-timeout or Ctrl-C ends it)",
                  file=sys.stderr, flush=True)

    if not frame_entries(follower.folder):
        announce()

    hidden = HiddenSince()  # the objects searched for, since when (issue 47)

    def show(timing, result) -> None:
        if not args.quiet and "text" in result.meta:  # what the phrases found, first frame
            report_text(result.meta["text"], model_options.text_threshold)
        if not args.quiet:
            ids = [int(i) for i in np.unique(result.labels) if i > 0]
            older = f", {timing.superseded} older skipped" if timing.superseded else ""
            searching = hidden.update(timing.index, hidden_now(result.meta.get("tracks", {})))
            print(f"frame {timing.index} ({timing.name}): {timing.latency:.2f} s from arrival "
                  f"to result ({timing.seconds:.2f} s segmenting{older}), objects {ids}"
                  f"{searching}", file=sys.stderr, flush=True)
        announce()

    def skip(line: str) -> None:
        print(line, file=sys.stderr, flush=True)
        announce()

    report = segment_stream(follower, tracker, args.out, value_range=args.value_range,
                            on_frame=show, on_skip=skip, latest=args.latest,
                            on_lightfield=None if poses is None else poses)
    summary = report.summary()
    if not args.quiet or report.ended_by == "interrupted":
        how = {"END": "END file", "timeout": "no new frame for --follow-timeout",
               "interrupted": "Ctrl-C", "stopped": "stopped"}.get(report.ended_by, "")
        where = f"{args.out} holds them" if report.frames else "nothing was written"
        print(f"stream ended ({how}) after {report.frames} frames; {where}"
              f"{hidden_frames_text(report.hidden)}", file=sys.stderr)
    if not args.quiet:
        print(json.dumps(summary), file=sys.stdout)
    return 130 if report.ended_by == "interrupted" else 0
