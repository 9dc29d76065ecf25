"""``lfsam segment VIDEO``: track objects through a light-field video (docs/design.md
section 10); called by :mod:`lfsam.cli.segment` when its input is a video."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from lfsam.cli.common import TRACKING_MODES
from lfsam.cli.models import model_options_from_args
from lfsam.cli.prompts import objects_from_items
from lfsam.fileutil import check_cache_dir, check_writable
from lfsam.prompts import load_prompts
from lfsam.video import read_video
from lfsam.video.io.result import check_result_folder, hidden_spans

__all__ = ["run_video"]


def run_video(args: argparse.Namespace, config: Any, has_prompts: bool) -> int:
    """Track the prompted (or, with ``--auto``, frame 0's) objects; write the result folder.
    ``config`` is the command's :class:`lfsam.pipeline.PipelineConfig`, passed through."""
    from lfsam.api import RunOptions, SegmentOptions
    from lfsam.video.tracking.track import track_video

    check_writable(args.out, folder=True, option="--out")  # before the video or a model is read
    check_result_folder(args.out)
    if args.cache is not None:
        check_cache_dir(args.cache)
    options = SegmentOptions(
        pipeline=config,
        model=model_options_from_args(args),
        run=RunOptions(method=args.method, references=args.references, cache_dir=args.cache,
                       progress=not args.quiet),
    )
    with read_video(args.path, value_range=args.value_range) as video:
        objects = None
        if has_prompts:
            objects = (
                load_prompts(args.prompts, video.grid_shape, video.view_shape, len(video))
                if args.prompts else []
            )
            first = max((o.obj_id for o in objects), default=0) + 1
            objects += objects_from_items(args.prompt_items, first_id=first)
        result = track_video(video, objects, args.out, disparity=args.disparity,
                             options=options, memory=TRACKING_MODES[args.tracking])
    if not args.quiet:
        summary = {
            "out": args.out,
            "frames": len(result),
            "objects": result.object_ids,
            "views": int(result.grid_shape[0] * result.grid_shape[1]),
            "seconds": round(result.meta.get("seconds", float("nan")), 3),
            # each object's frames not found ([first, last]; kept, searched, found again)
            "hidden": hidden_spans(result.meta.get("tracks", {})),
        }
        print(json.dumps(summary), file=sys.stdout)
    return 0
