"""``lfsam render`` over a light-field video's result: every frame (issue 66).

The video and its result folder are opened together and checked to match
(:func:`lfsam.cli.inputs.video_with_result`); each frame is rendered as a single light field
and written into one output folder, atomically as a whole
(:func:`lfsam.fileutil.atomic_folder_output`):
``frame_0000.png`` ... for refocus and see-through (with ``--coverage``, ``coverage_0000.png``
... beside them), ``frame_0000/`` scene folders for removal.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

from tqdm import tqdm

from lfsam.cli.inputs import video_with_result
from lfsam.errors import LfsamError
from lfsam.fileutil import atomic_folder_output, check_writable

__all__ = ["run_video"]


def run_video(args: argparse.Namespace, mode: str, render_frame: Callable[..., str]) -> int:
    """Render every frame of a video result into the folder ``args.out``."""
    if str(args.out).lower().endswith((".png", ".npz", ".jpg")):
        raise LfsamError("a video result renders every frame: give --out a folder (no suffix)")
    check_writable(args.out, folder=True, option="--out")
    with video_with_result(args.result, args.lightfield) as (result, video), \
            atomic_folder_output(args.out) as tmp:
        for index in tqdm(range(len(video)), desc="rendering frames", unit="frame",
                          disable=None, leave=False):
            name = f"frame_{index:04d}"
            out = tmp / (name if mode == "remove" else f"{name}.png")
            cover = tmp / f"coverage_{index:04d}.png" if args.coverage else None
            render_frame(args, mode, video.frame(index), result.frame(index).labels, out, cover)
    print(f"wrote {args.out}: {len(video)} frames rendered ({mode})")
    return 0
