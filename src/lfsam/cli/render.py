"""``lfsam render``: refocus, see through objects and take them out (issue 66).

A thin layer over :mod:`lfsam.render` (docs/design.md section 13): it reads the light field and
the result, picks the objects' masks, resolves the disparity where one is needed, and writes
the output atomically (:mod:`lfsam.render.output`).
"""

from __future__ import annotations

import argparse

import numpy as np

from lfsam.cli.common import HelpFormatter, add_device_argument, add_disparity_argument
from lfsam.cli.render_video import run_video
from lfsam.disparity import estimate_disparity_range, resolve_disparity
from lfsam.errors import LfsamError
from lfsam.fileutil import check_writable
from lfsam.io import read_lightfield, resolve_output
from lfsam.lightfield import LightField, check_result_shape
from lfsam.render import (
    behind_focus,
    object_focus,
    objects_in_front,
    refocus,
    remove_objects,
    see_through,
)
from lfsam.render.output import write_coverage, write_image, write_removed
from lfsam.result import load_result
from lfsam.video.io.result import is_video_result

__all__ = ["register", "run"]

DESCRIPTION = """\
Render a light field around its segmented objects, with the same mask in every view:

  refocus       (--focus D or --focus-on ID; --out IMAGE.png) shift-and-add over the views at
                disparity D (pixels between neighbouring views, as `lfsam disparity`), or at an
                object's median disparity: on that plane sharp, the rest blurred as by a lens
                as wide as the aperture. Pixels near the border average the rays that land.
  see through   (--see-through ID[,ID...]; --out IMAGE.png) a synthetic-aperture image that
                leaves out every ray hitting the objects in any view (their mask there), and
                every ray hitting RESULT's other objects in front of the focus, normalised by
                the rays kept, focused on what lies behind them (the surface their rim shows)
                unless --focus is given. --coverage writes the share of views that saw each
                pixel (black: none did).
  remove        (--remove ID[,ID...]; --out LF.npz or FOLDER) the whole light field without the
                objects: each view's object pixels filled from the other views that see the
                surface behind (of the surfaces the objects' rim shows, the nearest that other
                views see there), at its disparity; what no view sees is inpainted by OpenCV
                (pip install 'lfsam[render]') and flagged in inpainted.npy, stored with it.
                lfsam's native format: `lfsam info`, `segment`, `disparity`, `view` read it.

IDs are label ids of RESULT (`lfsam segment ... --out RESULT`; with an oracle result they are
the scene's ground-truth labels). --aperture R uses the views within R view steps of the center
view (default all). A focus outside the scene's disparity range is clipped to it, with a
warning. Nothing is written when a step fails.

A light-field video's result folder (from `lfsam segment VIDEO`) renders every frame: LF is the
video and OUT a folder of frame_0000.png ... (refocus, see-through; with --coverage (any
name), coverage_0000.png ... beside them) or frame_0000/ scene folders (remove).
"""

EPILOG = """\
examples:
  lfsam synth scene --grid 9x9 --size 240x320 --seed 5
  lfsam segment scene --auto --model oracle --disparity gt --out result.npz
  lfsam render scene --focus=-1.5 --out refocused.png           # focus on a plane
  lfsam render scene --result result.npz --focus-on 3 --out object3.png
  lfsam render scene --result result.npz --see-through 3,4 --coverage cover.png --out behind.png
  lfsam render scene --result result.npz --remove 3 --out without3.npz
  lfsam render clip --result clip_result --see-through 2 --out behind_frames   # every frame
  lfsam synth truth --grid 9x9 --size 240x320 --seed 5 --without 3   # the ground truth to compare
"""


def _ids(text: str) -> list[int]:
    try:
        ids = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        ids = []
    if not ids or min(ids) < 1:
        raise argparse.ArgumentTypeError(f"expected label ids ID[,ID...] (>= 1), got {text!r}")
    return ids


def _aperture(text: str) -> float | None:
    if text == "all":
        return None
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value >= 0:
        raise argparse.ArgumentTypeError(f"expected 'all' or a radius >= 0 in views, got {text!r}")
    return value


def _masks(labels: np.ndarray, ids: list[int], where: str) -> np.ndarray:
    """The union of the objects ``ids`` in every view, or one line naming the ids there."""
    there = sorted(int(i) for i in np.unique(labels) if i > 0)
    missing = [i for i in ids if i not in there]
    if missing:
        raise LfsamError(
            f"no object {', '.join(map(str, missing))} in {where}; its ids are "
            f"{', '.join(map(str, there)) or 'none'}"
        )
    return np.isin(labels, ids)


def _disparity_range(disparity: np.ndarray) -> tuple[float, float] | None:
    finite = disparity[np.isfinite(disparity)]
    return (float(finite.min()), float(finite.max())) if finite.size else None


def _check(args: argparse.Namespace) -> str:
    """The mode, after the checks that need no input (and the output's writability)."""
    if args.see_through and args.remove:
        raise LfsamError("give one of --see-through and --remove")
    if args.focus is not None and args.focus_on is not None:
        raise LfsamError("give one of --focus and --focus-on")
    mode = "remove" if args.remove else "see-through" if args.see_through else "refocus"
    if mode == "refocus" and args.focus is None and args.focus_on is None:
        raise LfsamError("say what to render: --focus D, --focus-on ID, --see-through ID or "
                         "--remove ID")
    if mode == "remove":
        if args.focus is not None or args.focus_on is not None or args.coverage:
            raise LfsamError("--remove takes none of --focus, --focus-on, --coverage")
        resolve_output(args.out)
        check_writable(args.out, folder=not str(args.out).lower().endswith(".npz"),
                       option="--out")
    else:
        if args.coverage and mode != "see-through":
            raise LfsamError("--coverage goes with --see-through")
        check_writable(args.out, folder=False, option="--out")
        if args.coverage:
            check_writable(args.coverage, folder=False, option="--coverage")
    if (args.remove or args.see_through or args.focus_on is not None) and not args.result:
        raise LfsamError("--focus-on, --see-through and --remove need --result RESULT")
    return mode


def run(args: argparse.Namespace) -> int:
    """Render and write; every input is checked before any output is made."""
    mode = _check(args)
    if args.result and is_video_result(args.result):
        return run_video(args, mode, render_frame)
    lf = read_lightfield(args.lightfield)
    labels = None
    if args.result:
        result = load_result(args.result)
        check_result_shape(result.labels.shape, lf, args.result)
        labels = result.labels
    print(render_frame(args, mode, lf, labels, args.out, args.coverage, progress=True))
    return 0


def render_frame(args: argparse.Namespace, mode: str, lf: LightField,
                 labels: np.ndarray | None, out, coverage_out, progress: bool = False) -> str:
    """Render one light field (one frame) in ``mode`` and write it to ``out``; the summary."""
    device = None if args.device == "auto" else args.device
    disparity = None
    if mode == "refocus" and args.focus_on is None and args.disparity == "estimate":
        # Only the range is needed (to clip the focus): the coarse sweep, not a full estimate.
        scene_range = estimate_disparity_range(lf, device=args.device)
    else:
        disparity, _ = resolve_disparity(args.disparity, lf, device=args.device)
        scene_range = _disparity_range(disparity)
    center = lf.center
    if mode == "refocus":
        focus = args.focus
        if args.focus_on is not None:
            mask = _masks(labels, [args.focus_on], args.result)[center]
            focus = object_focus(mask, disparity)
        image = refocus(lf.views, focus, present=lf.present, aperture=args.aperture,
                        disparity_range=scene_range, device=device)
        write_image(out, image)
        return f"wrote {out}: refocused at disparity {_clip(focus, scene_range):.3f}"
    if mode == "see-through":
        masks = _masks(labels, args.see_through, args.result)
        focus = args.focus if args.focus is not None else behind_focus(masks, disparity)
        # The result's other objects in front of the focal plane veil what lies behind.
        front = objects_in_front(labels, args.see_through, disparity,
                                 _clip(focus, scene_range))
        image, coverage = see_through(
            lf.views, masks, focus=focus, present=lf.present, aperture=args.aperture,
            disparity_range=scene_range, occluders=front, device=device,
        )
        write_image(out, image)
        if coverage_out:
            write_coverage(coverage_out, coverage)
        seen = float((coverage > 0).mean())
        return (f"wrote {out}: seen through {args.see_through} at disparity "
                f"{_clip(focus, scene_range):.3f}; {seen:.1%} of the pixels seen by some view")
    masks = _masks(labels, args.remove, args.result)
    views, unseen = remove_objects(lf.views, masks, disparity, present=lf.present,
                                   device=device, progress=progress)
    removed = LightField(
        views, present=lf.present,
        meta={**{k: v for k, v in lf.meta.items() if k not in ("generator",)},
              "render": {"removed": args.remove, "result": str(args.result),
                         "inpainted": int(unseen.sum()), "flags": "inpainted.npy"}},
    )
    written = write_removed(removed, unseen, out)
    return (f"wrote {written}: {lf.grid_shape[0]}x{lf.grid_shape[1]} views without "
            f"{args.remove}; {int(masks.sum())} object pixels, {int(unseen.sum())} seen by no "
            "view (inpainted, flagged in inpainted.npy)")


def _clip(focus: float, scene_range: tuple[float, float] | None) -> float:
    if scene_range is None:
        return float(focus)
    return float(min(max(focus, scene_range[0]), scene_range[1]))


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``render`` subcommand."""
    parser = subparsers.add_parser(
        "render", help="refocus, see through objects, remove them", description=DESCRIPTION,
        epilog=EPILOG, formatter_class=HelpFormatter,
    )
    parser.add_argument("lightfield", metavar="LF", help="the light field (any format lfsam "
                        "reads)")
    parser.add_argument("--result", metavar="RESULT", help="its segmentation result (.npz)")
    parser.add_argument("--focus", type=float, default=None, metavar="D",
                        help="focus at disparity D (pixels per view step)")
    parser.add_argument("--focus-on", type=int, default=None, metavar="ID",
                        help="focus at object ID's median disparity")
    parser.add_argument("--see-through", type=_ids, default=None, metavar="ID[,ID...]",
                        help="see through these objects")
    parser.add_argument("--remove", type=_ids, default=None, metavar="ID[,ID...]",
                        help="write the light field without these objects")
    parser.add_argument("--aperture", type=_aperture, default=None, metavar="all|R",
                        help="views within R view steps of the center (default all)")
    parser.add_argument("--coverage", metavar="COVER.png", default=None,
                        help="with --see-through: write the share of views that saw each pixel")
    parser.add_argument("--out", required=True, metavar="OUT",
                        help="IMAGE.png (refocus, see-through) or LF.npz / FOLDER (remove)")
    add_disparity_argument(parser)
    add_device_argument(parser)
    parser.set_defaults(func=run)
