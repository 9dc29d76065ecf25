"""``lfsam synth``: write a synthetic light field with exact ground truth."""

from __future__ import annotations

import argparse
import math

from lfsam.cli.common import HelpFormatter, bounded_int, parse_pair, unit_interval
from lfsam.errors import LfsamError
from lfsam.fileutil import check_writable
from lfsam.io import WRITE_FORMATS, resolve_output, write_lightfield
from lfsam.synth import generate_scene, generate_scene_without
from lfsam.synth.rigid import LEAVING_GAP, generate_rigid_video
from lfsam.video.io.synth import generate_video, write_video_frames

__all__ = ["register", "run"]

#: Largest RGB rendering (bytes, before downsampling) that `lfsam synth` attempts.
MAX_RENDER_BYTES = 8 << 30

DESCRIPTION = r"""\
Generate a synthetic light field with exact ground truth: a textured
background plane and textured planar objects at different depths (some slanted), overlapping so
that they occlude and disocclude each other, seen by a grid of cameras. Every view gets its
exact disparity (in lfsam's convention, pixels per view step, larger = closer) and instance
labels (background = 1, objects = 2, 3, ...), each label with a category name, texture then
shape ("brick disc", "checker tile", "dots star"), the ground truth of text prompts (`lfsam
segment --text disc`). Textures come from scikit-image's sample photographs and procedural
patterns; the RGB is anti-aliased. The same seed always gives the same bytes.

The disparity range sets the baseline: with 9x9 views and --disparity-range=-2,2 the extreme
views see points up to 8 pixels away from where the center view sees them.

--hidden-objects K adds K small objects that the center view cannot see (entirely behind nearer
objects there) but that come out from behind them in the outer rows and columns, each showing
at least 100 pixels (scaled with the view size) in some corner view; their labels follow the
other objects' and are listed in the metadata (generator.hidden_labels). The rest of the scene is
the same as without them.

--frames F writes a light-field video instead: a folder of F frames (frame_0000/ ..., each a
scene folder, and lfsam_video.json). The objects move in the image plane and in depth, pass in
front of and behind each other, and the first object leaves the frame and comes back (with
F >= 5); every object keeps its label in every frame. --hard adds the hard cases of tracking
through clutter (issue 47): objects moving at 3-6 pixels per frame, depth order changing, and
(with 3 objects or more) a small object passing fully behind a near occluder for several
frames around the middle frame (F >= 10), visible longer in the outer views.

--rigid writes a light-field video of rigid textured boxes under known 3D motion instead, the
ground truth of `lfsam poses` (6D pose tracking): a metric camera (f = 400 px, baseline 1 cm,
views converged at 1 m), --objects boxes (default 3) of 10-17 cm at about 1 m in front of a
textured wall at 1.6 m, each turning 2-4 degrees about an axis of its own and moving 4-12 mm per
frame, --frames F (default 10) of --grid views (default 7x7) of --size pixels (default 240x320).
Every view is ray-cast: exact labels (wall = 1, boxes = 2, 3, ...) and disparity; every frame's
lfsam_scene.json holds the camera and each box's size and 4x4 pose (box frame to the center
camera's frame, metres) under meta.rigid.
"""

EPILOG = """\
examples:
  lfsam synth scene                                    # 9x9 views of 240x320, seed 0
  lfsam synth small.npz --grid 5x5 --size 64x96 --seed 3 --objects 4
  lfsam synth wide --disparity-range=-4,4              # note the '=' for negative numbers
  lfsam synth hidden.npz --hidden-objects 3            # 3 objects only the outer views see
  lfsam synth twin --seed 3 --without 2,4              # the same scene without objects 2 and 4
  lfsam synth glossy --specular 0.6                    # highlights that move across views
  lfsam synth glassy --glass 1 --mirror 1              # a see-through and a mirror object
  lfsam synth clip --frames 6 --grid 5x5 --size 96x128 # a light-field video of 6 frames
  lfsam synth hard --frames 12 --grid 5x5 --size 96x128 --objects 5 --hard
  lfsam synth boxes --rigid --seed 7                   # 3 boxes, 10 frames of 7x7 x 240x320
  lfsam synth small --rigid --frames 3 --grid 5x5 --size 120x160 --objects 1
  lfsam synth crossing --rigid --crossing --seed 7     # a fourth box crosses in front
  lfsam synth leaving --rigid --leaving --seed 7       # a fourth box leaves and comes back
"""


def _disparity_range(text: str) -> tuple[float, float]:
    low, high = parse_pair(text, sep=",", kind=float)
    if not (low < high and math.isfinite(low) and math.isfinite(high)):
        raise argparse.ArgumentTypeError(f"expected LO,HI with LO < HI, got {text!r}")
    return low, high


def _id_list(text: str) -> list[int]:
    try:
        ids = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        ids = []
    if not ids or min(ids) < 1:
        raise argparse.ArgumentTypeError(f"expected labels ID[,ID...] (>= 1), got {text!r}")
    return ids


def _positive_pair(text: str) -> tuple[int, int]:
    pair = parse_pair(text)
    if min(pair) < 1:
        raise argparse.ArgumentTypeError(f"expected two positive numbers AxB, got {text!r}")
    return pair


def _run_video(args: argparse.Namespace) -> int:
    """``--frames F``: a synthetic light-field video folder, written frame by frame."""
    special = args.hidden_objects or args.specular or args.glass or args.mirror
    if special or str(args.out).lower().endswith(".npz"):
        raise LfsamError(
            "--frames writes a folder of frames (give OUT without .npz) and takes none of "
            "--hidden-objects, --specular, --glass, --mirror"
        )
    check_writable(args.out, folder=True, option="OUT")
    frames = generate_video(
        grid=args.grid, size=args.size, frames=args.frames, seed=args.seed,
        num_objects=args.objects, disparity_range=args.disparity_range,
        supersample=args.supersample, hard=args.hard,
    )
    settings = {"seed": args.seed, "objects": args.objects, "frames": args.frames}
    if args.hard:
        settings["hard"] = True
    out = write_video_frames(frames, args.out, meta=settings)
    print(
        f"wrote {out}: {args.frames} frames of {args.grid[0]} x {args.grid[1]} views of "
        f"{args.size[0]} x {args.size[1]}, seed {args.seed}, {args.objects} moving objects"
    )
    return 0


def _run_rigid(args: argparse.Namespace) -> int:
    """``--rigid``: a video of rigid boxes under known 3D motion (docs/design.md section 12)."""
    if (args.hidden_objects or args.specular or args.hard or args.disparity_range is not None
            or args.glass or args.mirror or str(args.out).lower().endswith(".npz")):
        raise LfsamError(
            "--rigid writes a folder of frames (give OUT without .npz) and takes none of "
            "--hidden-objects, --specular, --hard, --glass, --mirror, --disparity-range (its "
            "camera is fixed)"
        )
    if args.objects < 1:
        raise LfsamError("--rigid needs --objects of at least 1 box")
    if args.leaving and args.frames < LEAVING_GAP + 4:
        raise LfsamError(f"--leaving needs at least {LEAVING_GAP + 4} frames (the box is out "
                         f"for {LEAVING_GAP}); got --frames {args.frames}")
    check_writable(args.out, folder=True, option="OUT")
    frames = generate_rigid_video(
        boxes=args.objects, frames=args.frames, grid=args.grid, size=args.size, seed=args.seed,
        supersample=args.supersample, crossing=args.crossing, leaving=args.leaving,
    )
    settings = {"seed": args.seed, "objects": args.objects, "frames": args.frames,
                "rigid": True, "crossing": bool(args.crossing), "leaving": bool(args.leaving)}
    out = write_video_frames(frames, args.out, meta=settings)
    print(
        f"wrote {out}: {args.frames} frames of {args.grid[0]} x {args.grid[1]} views of "
        f"{args.size[0]} x {args.size[1]}, seed {args.seed}, {args.objects} rigid boxes"
        + (" and one crossing in front of them" if args.crossing else "")
        + (" and one that leaves the view and comes back" if args.leaving else "")
        + " (poses in each frame's lfsam_scene.json, meta.rigid)"
    )
    return 0


def _defaults(args: argparse.Namespace) -> None:
    """Fill the options left unset: the issue-43 setting with --rigid, else the usual ones."""
    rigid = args.rigid
    if args.grid is None:
        args.grid = (7, 7) if rigid else (9, 9)
    if args.size is None:
        args.size = (240, 320)
    if args.objects is None:
        args.objects = 3 if rigid else 6
    if rigid and args.frames is None:
        args.frames = 10


def run(args: argparse.Namespace) -> int:
    """Generate the scene (or with ``--frames``, the video; ``--rigid``, the boxes) and write
    it."""
    _defaults(args)
    for flag, given in (("--crossing", args.crossing), ("--leaving", args.leaving)):
        if given and not args.rigid:
            raise LfsamError(f"{flag} adds a box to a --rigid video; add --rigid")
    if args.without and (args.rigid or args.frames is not None):
        raise LfsamError("--without renders one scene without objects; not with --frames, --rigid")
    if args.rigid:
        return _run_rigid(args)
    if args.disparity_range is None:
        args.disparity_range = (-2.0, 2.0)
    if args.frames is not None:
        return _run_video(args)
    if args.hard:
        raise LfsamError("--hard makes a hard light-field video: give it with --frames F")
    if args.glass + args.mirror > args.objects:
        raise LfsamError(
            f"--glass {args.glass} + --mirror {args.mirror} objects asked for but only "
            f"--objects {args.objects}; raise --objects or lower them"
        )
    npz = args.format == "npz" if args.format else str(args.out).lower().endswith(".npz")
    check_writable(args.out, folder=not npz, option="OUT")  # fail before the work, not after
    resolve_output(args.out, args.format)
    rendered = args.grid[0] * args.grid[1] * args.size[0] * args.size[1] * args.supersample**2
    if rendered * 3 > MAX_RENDER_BYTES:
        raise LfsamError(
            f"a {args.grid[0]}x{args.grid[1]} grid of {args.size[0]}x{args.size[1]} views with "
            f"supersample {args.supersample} needs more than {MAX_RENDER_BYTES >> 30} GiB; "
            "choose a smaller --grid, --size or --supersample"
        )
    settings = dict(
        grid=args.grid,
        size=args.size,
        seed=args.seed,
        num_objects=args.objects,
        disparity_range=args.disparity_range,
        supersample=args.supersample,
        hidden_objects=args.hidden_objects,
        specular=args.specular,
        glass=args.glass,
        mirror=args.mirror,
    )
    if args.without:
        lf = generate_scene_without(args.without, **settings)
    else:
        lf = generate_scene(**settings)
    out = write_lightfield(lf, args.out, format=args.format)
    hidden = f" + {args.hidden_objects} hidden" if args.hidden_objects else ""
    hidden += f", specular {args.specular:g}" if args.specular else ""
    hidden += f", {args.glass} glass" if args.glass else ""
    hidden += f", {args.mirror} mirror" if args.mirror else ""
    print(
        f"wrote {out}: {args.grid[0]}x{args.grid[1]} views of {args.size[0]}x{args.size[1]}, "
        f"seed {args.seed}, {args.objects} objects{hidden}, disparity "
        f"{lf.describe()['disparity_range'][0]:.2f}..{lf.describe()['disparity_range'][1]:.2f}"
    )
    return 0


def register(subparsers) -> None:
    """Add the ``synth`` subcommand."""
    parser = subparsers.add_parser(
        "synth",
        help="generate a synthetic light field with exact disparity and labels",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=HelpFormatter,
    )
    parser.add_argument("out", help="output: a new scene folder, or a name ending in .npz")
    parser.add_argument(
        "--grid",
        type=_positive_pair,
        default=None,
        metavar="SxT",
        help="views per column x views per row (default 9x9; 7x7 with --rigid)",
    )
    parser.add_argument(
        "--size",
        type=_positive_pair,
        default=None,
        metavar="UxV",
        help="pixel rows x columns of each view",
    )
    parser.add_argument("--seed", type=bounded_int(0), default=0, help="random seed (>= 0)")
    parser.add_argument(
        "--objects", type=bounded_int(0, 1000), default=None,
        help="objects in front of the background (default 6; boxes with --rigid, default 3)"
    )
    parser.add_argument(
        "--hidden-objects",
        type=bounded_int(0),
        default=0,
        metavar="K",
        help="small objects the center view cannot see but corner views can",
    )
    parser.add_argument(
        "--disparity-range",
        type=_disparity_range,
        default=None,
        metavar="LO,HI",
        help="disparity range in pixels per view step (default -2,2)",
    )
    parser.add_argument(
        "--specular",
        type=unit_interval,
        default=0.0,
        metavar="STRENGTH",
        help="peak brightness (0-1) of a highlight on each object that moves across views",
    )
    parser.add_argument(
        "--glass",
        type=bounded_int(0),
        default=0,
        metavar="N",
        help="make the first N objects see-through (glass: the scene behind shows, refracted)",
    )
    parser.add_argument(
        "--mirror",
        type=bounded_int(0),
        default=0,
        metavar="N",
        help="make the next N objects mirrors (a reflection moving with its own disparity)",
    )
    parser.add_argument(
        "--frames",
        type=bounded_int(1, 100000),
        default=None,
        metavar="F",
        help="write a light-field video of F frames (a folder) with moving objects "
        "(default 10 with --rigid)",
    )
    parser.add_argument(
        "--rigid",
        action="store_true",
        help="a video of rigid textured boxes under known 3D motion, every frame's 4x4 pose "
        "per box in its scene file (the ground truth of `lfsam poses`)",
    )
    parser.add_argument(
        "--crossing",
        action="store_true",
        help="with --rigid: one more box (the last label) crosses the view 35 cm nearer, "
        "turning, in front of the others, which it covers in turn (poses through occlusions)",
    )
    parser.add_argument(
        "--leaving",
        action="store_true",
        help="with --rigid: one more box (the next label) 20 cm nearer leaves the view past "
        "its left or right edge, is out of every view for 3 frames in the middle of the video "
        "and comes back, turning all the while (tracks and poses across a gap; needs 7 frames)",
    )
    parser.add_argument(
        "--hard",
        action="store_true",
        help="with --frames: the hard cases of tracking (faster objects, depth order changing, "
        "a small object passing fully behind a near one for several frames)",
    )
    parser.add_argument(
        "--supersample",
        type=bounded_int(1, 8),
        default=2,
        help="RGB samples per pixel along each axis (anti-aliasing)",
    )
    parser.add_argument(
        "--without",
        type=_id_list,
        default=None,
        metavar="ID[,ID...]",
        help="render the same scene without these objects (labels; what lies behind them, with "
        "its exact disparity and labels: the ground truth of `lfsam render --remove`)",
    )
    parser.add_argument(
        "--format",
        choices=WRITE_FORMATS,
        default=None,
        help="output format; unset: npz if OUT ends in .npz, else lfsam",
    )
    parser.set_defaults(func=run)
