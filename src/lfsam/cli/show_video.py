"""``lfsam show VIDEO_RESULT``: an animation over time of one view or of the view grid
(docs/design.md section 10); called by :mod:`lfsam.cli.show` for a video result folder."""

from __future__ import annotations

import argparse
import sys
import warnings

from lfsam.errors import LfsamError
from lfsam.fileutil import check_writable
from lfsam.video import read_video
from lfsam.video.io.result import load_video_result

__all__ = ["parse_view", "run_video"]


def parse_view(text: str) -> tuple[int, int]:
    """``"S,T"`` -> ``(s, t)``."""
    try:
        s, t = (int(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a view as S,T, got {text!r}") from None
    return s, t


def run_video(args: argparse.Namespace) -> int:
    """Draw the video result ``args.input`` over its video (``--lightfield`` or the recorded
    input) as a GIF or MP4: ``--view S,T`` one view, else the grid."""
    from lfsam import viz

    if args.kind not in (None, "anim") or not str(args.out).lower().endswith(
            viz.ANIMATION_SUFFIXES):
        raise LfsamError("a light-field video's result is shown as an animation over time; "
                         "give --out ending in .gif or .mp4")
    if args.compare or args.gt_labels or args.mask_outlines:
        raise LfsamError("--compare, --gt-labels and --mask-outlines take a single light field's "
                         "result, not a video's")
    check_writable(args.out, folder=False, option="--out")  # before anything is read
    result = load_video_result(args.input)
    source = args.lightfield or result.meta.get("input")
    if source is None:
        raise LfsamError(f"{args.input} is a video result; give its video with --lightfield PATH")
    grid = result.grid_shape
    if args.view is not None and not (0 <= args.view[0] < grid[0] and 0 <= args.view[1] < grid[1]):
        raise LfsamError(f"--view {args.view[0]},{args.view[1]} is outside the "
                         f"{grid[0]} x {grid[1]} grid")
    if not 0 < args.scale <= 32 or not 0.01 <= args.fps <= 1000 or not 0 <= args.alpha <= 1:
        raise LfsamError("--scale must be in (0, 32], --fps in [0.01, 1000], --alpha in [0, 1]")
    with read_video(source) as video:
        if tuple(video.shape) != tuple(result.shape):
            raise LfsamError(f"the result's labels {result.shape} do not match the video "
                             f"{tuple(video.shape)} (F, S, T, U, V); give the video the result "
                             "was computed on")
        pairs = ((video.frame(f).views, result.labels[f]) for f in range(len(result)))
        frames = viz.time_frames(pairs, len(result), view=args.view, alpha=args.alpha,
                                 boundaries=not args.no_boundaries)
        frames = (viz.rescale(f, args.scale) for f in frames)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            path = viz.write_animation(args.out, frames, fps=args.fps,
                                       progress=False if args.quiet else None,
                                       total=len(result))
    for warning in caught:
        print(f"lfsam: note: {warning.message}", file=sys.stderr)
    if not args.quiet:
        print(path)
    return 0
