"""``lfsam show``: figures and animations of a segmentation result or of a light field."""

from __future__ import annotations

import argparse
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lfsam.cli.common import HelpFormatter
from lfsam.cli.inputs import expect_input, expect_partner
from lfsam.cli.show_video import parse_view, run_video
from lfsam.errors import LfsamError
from lfsam.fileutil import check_writable
from lfsam.io import read_lightfield
from lfsam.result import load_result

KINDS = ("grid", "epi", "anim", "all")

DESCRIPTION = """\
Draw a segmentation result over its light field, or draw a light field by itself.

Every label id has one colour in every view and figure (and in both panels of a comparison), so
a view-consistent segmentation keeps each object's colour from view to view. Kinds of output:

  grid   the views with labels overlaid and region edges drawn: all views in their grid
         arrangement (--views all), the four corners and the center (--views corners) or
         top-left, center, bottom-right as in the paper's Figure 2 (--views diagonal); views
         a sparse run refined (--refine-views) are framed in amber and captioned "(s, t) *"
  epi    the center view with its horizontal epipolar-plane image (pixel row --row of every
         view of the center view row) below and its vertical EPI (pixel column --col of every
         view of the center view column) to the right, each view repeated --upsample times.
         A scene point traces a straight line whose slope is its disparity; a consistent
         segmentation colours each line in one colour (paper section 4.3)
  anim   an animated GIF (or MP4 with imageio-ffmpeg installed) running through the views in
         snake order, with a map of the view grid showing the current view
  all    all of the above: --out is then a folder (existing, or ending in /) receiving
         grid.png, epi.png and anim.gif, or a prefix P giving P_grid.png, P_epi.png, P_anim.gif

Without --kind the kind follows --out: .gif/.mp4 -> anim, an image suffix -> grid, none -> all.
INPUT is a result (.npz from `lfsam segment`; give its light field with --lightfield unless the
result records where it came from) or a light field (then --gt-labels overlays its ground truth).
--compare puts a second result (or the light field's ground truth: --compare gt) beside the
first in every figure.

A light-field video's result folder (from `lfsam segment VIDEO`) is drawn as an animation over
time (--out .gif or .mp4): one frame per video frame, the whole view grid, or one view with
--view S,T, a time bar below.
"""

EPILOG = """\
examples:
  lfsam show result.npz --lightfield scene --out grid.png --views corners
  lfsam show result.npz --lightfield scene --out epi.png --kind epi --row 120 --upsample 6
  lfsam show result.npz --lightfield scene --out views.gif
  lfsam show ours.npz --lightfield scene --compare baseline.npz --match-colors --out figs/
  lfsam show ours.npz --lightfield scene --compare gt --kind epi --out ours_vs_gt.png
  lfsam show ../shared/data/hci_antinous --out antinous --scale 0.5    # the light field alone
  lfsam show scene --gt-labels --out scene_gt.mp4                      # its ground truth
  lfsam show video_result/ --out tracks.gif --view 2,2                 # a video, one view
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``show`` subcommand."""
    parser = subparsers.add_parser(
        "show",
        help="figures (view grid, EPIs) and animations of a result or a light field",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=HelpFormatter,
    )
    parser.add_argument("input", metavar="INPUT", help="result .npz, or a light field")
    parser.add_argument(
        "--lightfield", metavar="PATH", help="the light field the result was computed on"
    )
    parser.add_argument(
        "--format", dest="input_format", help="light-field format; detected when omitted"
    )
    parser.add_argument(
        "--out",
        required=True,
        metavar="FILE",
        help="output file (.png/.jpg/... for grid and epi, .gif/.mp4 for anim), or a folder or "
        "prefix for --kind all",
    )
    parser.add_argument(
        "--kind", choices=KINDS, help="what to draw; follows the suffix of --out when omitted"
    )
    what = parser.add_argument_group("what to draw")
    what.add_argument(
        "--views",
        choices=["all", "corners", "diagonal"],
        default="all",
        help="views in the grid figure",
    )
    what.add_argument(
        "--view", type=parse_view, metavar="S,T",
        help="a light-field video's result: animate this view only (default the whole grid)",
    )
    what.add_argument(
        "--row", type=int, help="pixel row of the horizontal EPI; the middle row when omitted"
    )
    what.add_argument(
        "--col", type=int, help="pixel column of the vertical EPI; the middle one when omitted"
    )
    what.add_argument(
        "--upsample", type=int, default=8, metavar="K", help="EPI: repeat each view K times"
    )
    what.add_argument(
        "--compare",
        metavar="OTHER.npz|gt",
        help="a second result (or 'gt', the light field's ground-truth labels) to show beside "
        "the first",
    )
    what.add_argument(
        "--match-colors",
        action="store_true",
        help="with --compare: renumber the second labels to the first's best-overlapping ids, "
        "so the same object gets the same colour",
    )
    what.add_argument(
        "--names", metavar="A,B", help="panel titles with --compare; from the files when omitted"
    )
    what.add_argument(
        "--gt-labels",
        action="store_true",
        help="INPUT is a light field: overlay its ground-truth labels",
    )
    look = parser.add_argument_group("appearance")
    look.add_argument("--alpha", type=float, default=0.5, help="opacity of the label colours")
    look.add_argument("--no-boundaries", action="store_true", help="do not draw region edges")
    look.add_argument(
        "--mask-outlines",
        action="store_true",
        help="outline every stored mask (overlaps visible) instead of the label regions",
    )
    look.add_argument("--no-captions", action="store_true", help="no (s, t) above each view")
    look.add_argument(
        "--scale", type=float, default=1.0, help="resize every figure and frame by this factor"
    )
    look.add_argument("--fps", type=float, default=8.0, help="animation frames per second")
    look.add_argument(
        "--anim-format",
        choices=["gif", "mp4"],
        default="gif",
        help="animation file type for --kind all",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bars or summary")
    parser.set_defaults(func=run)


@dataclass
class _Scene:
    """What to draw: views, up to two label fields, their names and the stored masks."""

    views: np.ndarray
    labels: np.ndarray | None
    name: str
    other: np.ndarray | None = None
    other_name: str | None = None
    masks: object | None = None
    lightfield: object | None = None
    refined: np.ndarray | None = None


def _is_result_file(path: Path) -> bool:
    """An .npz holding ``labels`` but no ``views`` is a result, not a light field."""
    if path.suffix.lower() != ".npz" or not path.is_file():
        return False
    try:
        with np.load(path, allow_pickle=False) as npz:
            keys = set(npz.files)
    except Exception:  # not a readable npz: let the light-field reader report it
        return False
    return "labels" in keys and "views" not in keys


def _recorded_source(meta: dict) -> str | None:
    for key in ("source", "input", "lightfield", "path"):
        value = meta.get(key)
        if isinstance(value, str) and Path(value).exists():
            return value
    return None


def _full_labels(lightfield) -> np.ndarray:
    """Ground-truth labels for every view; center-only labels leave the other views unlabeled."""
    if lightfield.labels is None:
        raise LfsamError(
            "the light field has no ground-truth labels; drop --gt-labels / --compare gt"
        )
    if lightfield.labels.ndim == 4:
        return lightfield.labels
    full = np.zeros(lightfield.views.shape[:4], dtype=np.int32)
    full[lightfield.center] = lightfield.labels
    return full


def _result_name(result, path: Path) -> str:
    method = result.meta.get("method")
    return f"{method} ({path.name})" if method else path.name


def _load_scene(args: argparse.Namespace) -> _Scene:
    source = Path(args.input)
    if args.lightfield is not None or _is_result_file(source):
        result = load_result(source)
        lf_path = args.lightfield or _recorded_source(result.meta)
        if lf_path is None:
            raise LfsamError(
                f"{source} is a segmentation result; give the light field it was computed on "
                "with --lightfield PATH"
            )
        if args.gt_labels:
            raise LfsamError(
                "--gt-labels is for showing a light field; to put a result beside the ground "
                "truth use --compare gt"
            )
        lightfield = read_lightfield(lf_path, format=args.input_format)
        if result.labels.shape != lightfield.views.shape[:4]:
            raise LfsamError(
                f"the result's labels {tuple(result.labels.shape)} do not match the light field's "
                f"views {tuple(lightfield.views.shape[:4])} (S, T, U, V); give the light field "
                "the result was computed on"
            )
        scene = _Scene(lightfield.views, result.labels, _result_name(result, source))
        scene.masks, scene.lightfield = result.masks, lightfield
        refined = result.meta.get("refined_views")
        if refined is not None and np.shape(refined) == lightfield.views.shape[:2]:
            refined = np.asarray(refined, dtype=bool)
            present = np.asarray(lightfield.present, dtype=bool)
            if not refined[present].all():  # a sparse run (docs/design.md section 3.7)
                scene.refined = refined
    else:
        lightfield = read_lightfield(source, format=args.input_format)
        labels = _full_labels(lightfield) if args.gt_labels else None
        name = "ground truth" if args.gt_labels else "views"
        scene = _Scene(lightfield.views, labels, name, lightfield=lightfield)
    if args.compare:
        if args.compare.lower() == "gt":
            scene.other, scene.other_name = _full_labels(scene.lightfield), "ground truth"
        else:
            other_path = Path(args.compare)
            other = load_result(other_path)
            if other.labels.shape != scene.views.shape[:4]:
                raise LfsamError(
                    f"the compared result's labels {tuple(other.labels.shape)} do not match the "
                    f"light field's views {tuple(scene.views.shape[:4])}; compare results of the "
                    "same light field"
                )
            scene.other, scene.other_name = other.labels, _result_name(other, other_path)
        if scene.labels is None:
            scene.labels = np.zeros(scene.views.shape[:4], dtype=np.int32)
    return scene


def _check_options(args: argparse.Namespace, scene: _Scene) -> None:
    u_count, v_count = scene.views.shape[2:4]
    if args.row is not None and not 0 <= args.row < u_count:
        raise LfsamError(f"--row {args.row} is outside the views (0..{u_count - 1})")
    if args.col is not None and not 0 <= args.col < v_count:
        raise LfsamError(f"--col {args.col} is outside the views (0..{v_count - 1})")
    if not 1 <= args.upsample <= 64:
        raise LfsamError(f"--upsample must be in 1..64, got {args.upsample}")
    if not 0.0 <= args.alpha <= 1.0:
        raise LfsamError(f"--alpha must lie in [0, 1], got {args.alpha}")
    if not 0 < args.scale <= 32:  # NaN fails too
        raise LfsamError(f"--scale must be > 0 and <= 32, got {args.scale}")
    if not 0.01 <= args.fps <= 1000:  # a GIF frame lasts at most 655 s
        raise LfsamError(f"--fps must lie in [0.01, 1000], got {args.fps}")
    if args.mask_outlines and (scene.masks is None or scene.other is not None):
        raise LfsamError("--mask-outlines needs a result that stores its masks, and no --compare")
    if args.match_colors and scene.other is None:
        raise LfsamError("--match-colors needs --compare")


def _outputs(args: argparse.Namespace) -> tuple[list[tuple[str, Path]], Path | None]:
    """(kind, path) of every file to write, checked before any drawing, and a folder to create."""
    from lfsam.viz import ANIMATION_SUFFIXES, IMAGE_SUFFIXES  # loads on use (--help stays light)

    out = Path(args.out)
    suffix = out.suffix.lower()
    kind = args.kind
    if kind is None:
        if suffix in ANIMATION_SUFFIXES:
            kind = "anim"
        elif suffix in IMAGE_SUFFIXES:
            kind = "grid"
        else:
            kind = "all"
    new_folder = None
    if kind == "all":
        anim_name = f"anim.{args.anim_format}"
        if out.is_dir() or str(args.out).endswith(("/", "\\")):
            if not out.is_dir():
                new_folder = out  # its parent must exist (checked below); made after checks
            paths = [
                ("grid", out / "grid.png"),
                ("epi", out / "epi.png"),
                ("anim", out / anim_name),
            ]
        else:
            prefix = out.with_suffix("") if suffix in IMAGE_SUFFIXES + ANIMATION_SUFFIXES else out
            paths = [
                ("grid", prefix.with_name(f"{prefix.name}_grid.png")),
                ("epi", prefix.with_name(f"{prefix.name}_epi.png")),
                ("anim", prefix.with_name(f"{prefix.name}_{anim_name}")),
            ]
    else:
        wanted = ANIMATION_SUFFIXES if kind == "anim" else IMAGE_SUFFIXES
        if suffix not in wanted:
            raise LfsamError(
                f"--kind {kind} writes {'/'.join(wanted)} files, but --out is {str(out)!r}; "
                "change the suffix of --out"
            )
        paths = [(kind, out)]
    # before anything is read (docs/design.md section 2): the new folder, or every file
    for target in [new_folder] if new_folder is not None else [path for _, path in paths]:
        check_writable(target, folder=target is new_folder, option="--out")
    return paths, new_folder


def run(args: argparse.Namespace) -> int:
    """Run ``lfsam show``."""
    from lfsam import viz
    from lfsam.video.io.result import is_video_result

    kind = expect_input(args.input, "show", ("result", "video-result", "lightfield"),
                        hint=f"segment it first (lfsam segment {args.input} --auto --out "
                        "RESULT_FOLDER) and show the result folder")
    if kind == "lightfield" and args.lightfield is not None:
        raise LfsamError(f"{args.input} is a light field; --lightfield goes with a result "
                         "(lfsam show RESULT.npz --lightfield PATH)")
    expect_partner(args.lightfield, args.input, kind, "show", "--lightfield")
    if args.compare is not None and args.compare.lower() != "gt":
        expect_input(args.compare, "show", ("result",), option="--compare")
    if is_video_result(args.input):
        return run_video(args)
    if args.view is not None:
        raise LfsamError("--view is for a light-field video's result")
    outputs, new_folder = _outputs(args)
    scene = _load_scene(args)
    _check_options(args, scene)
    progress = False if args.quiet else None
    other = scene.other
    if other is not None and args.match_colors:
        other = viz.match_labels(scene.labels, other)
    names = [scene.name, scene.other_name or ""]
    if args.names:
        names = [n.strip() for n in args.names.split(",")]
        if len(names) != 2:
            raise LfsamError(f"--names takes two titles as A,B, got {args.names!r}")
    masks = scene.masks if args.mask_outlines else None
    overlay = {"alpha": args.alpha, "boundaries": not args.no_boundaries}
    grid_opts = {"which": args.views, "captions": not args.no_captions, "progress": progress}
    epi_opts = {"row": args.row, "col": args.col, "upsample": args.upsample}

    if new_folder is not None:
        new_folder.mkdir(exist_ok=True)
    written = []
    for kind, path in outputs:
        if kind == "grid":
            if other is None:
                image = viz.view_grid(
                    scene.views, scene.labels, masks=masks, marked=scene.refined, **grid_opts,
                    **overlay,
                )
            else:
                image = viz.compare_grid(
                    scene.views, scene.labels, other, names=names, **grid_opts, **overlay
                )
            written.append(viz.save_image(path, viz.rescale(image, args.scale)))
        elif kind == "epi":
            if other is None:
                image = viz.epi_figure(scene.views, scene.labels, **epi_opts, **overlay)
            else:
                image = viz.compare_epi(
                    scene.views, scene.labels, other, names=names, **epi_opts, **overlay
                )
            written.append(viz.save_image(path, viz.rescale(image, args.scale)))
        else:
            if other is None:
                frames = viz.animation_frames(scene.views, scene.labels, masks=masks, **overlay)
            else:
                frames = viz.compare_frames(
                    scene.views, scene.labels, other, names=names, **overlay
                )
            frames = (viz.rescale(f, args.scale) for f in frames)
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                written.append(
                    viz.write_animation(
                        path,
                        frames,
                        fps=args.fps,
                        progress=progress,
                        total=scene.views.shape[0] * scene.views.shape[1],
                    )
                )
            for warning in caught:
                print(f"lfsam: note: {warning.message}", file=sys.stderr)
    if not args.quiet:
        for path in written:
            print(path)
    return 0
