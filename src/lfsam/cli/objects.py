"""``lfsam objects``: every segmented object's position and size in metres (docs/design.md §11)."""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from lfsam.camera import CAMERA_EXAMPLE
from lfsam.cli.common import HelpFormatter, add_device_argument, positive_float, unit_interval
from lfsam.cli.inputs import expect_input, expect_partner, video_with_result
from lfsam.fileutil import check_writable, write_text_atomic
from lfsam.objects3d import (
    VIEWS,
    Objects3D,
    format_table,
    objects_in_3d,
    objects_over_video,
    resolve_camera,
)
from lfsam.spatial import MIN_CONFIDENCE, trajectories_csv

DESCRIPTION = f"""\
Where each segmented object is and how big it is, in metres: for every object of a result its
pixel count, the share of them with a confident disparity, its centroid [x, y, z] (center view
camera: x right, y down, z forward), its median depth and its extent (an oriented box on the
points' principal axes, 2nd to 98th percentile). Depth is z = f b / (d + f b / z0) from lfsam's
disparity d (docs/design.md section 11).

The camera is --camera CAMERA.json ({CAMERA_EXAMPLE};
focus_distance_m may be left out for parallel views), else the light field's own: an HCI 4D
scene's parameters.cfg, or the camera of an lfsam scene folder (`lfsam synth` writes one).

When the light field has a ground-truth disparity and another disparity is used, each object's
depth error against it is reported too (median absolute error and the median depth's relative
error).

A video's result folder (from `lfsam segment VIDEO`) with its video: the table of every frame,
then each object's 3D trajectory and speed (m/s with --fps, else m per frame); --csv writes the
trajectories (one row per object and frame), --json everything.
"""

EPILOG = """\
examples:
  lfsam synth scene --grid 9x9 --size 240x320 --seed 0
  lfsam segment scene --auto --model oracle --disparity gt --out result.npz
  lfsam objects result.npz --lightfield scene                  # estimated disparity
  lfsam objects result.npz --lightfield scene --disparity gt --json objects.json
  lfsam objects result.npz --lightfield LF --camera camera.json --views all
  lfsam objects video_result/ --lightfield video/ --fps 10 --csv tracks.csv
"""


def add_3d_arguments(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """``--disparity``, ``--camera``, ``--views``, ``--min-confidence`` and ``--device``: the
    options of ``lfsam objects`` and ``lfsam export --to ply``."""
    parser.add_argument(
        "--disparity", default="estimate", metavar="estimate|gt|FILE.npy",
        help="disparity: estimated from the views (the default estimator with its "
        "structure-tensor fusion, as `lfsam disparity`; its confidence drops unsure pixels), "
        "the light field's ground truth, or a center-view (U, V) or every-view (S, T, U, V) "
        ".npy in lfsam's convention",
    )
    parser.add_argument(
        "--camera", metavar="CAMERA.json",
        help=f"camera: {CAMERA_EXAMPLE} (default: the light field's own)",
    )
    parser.add_argument(
        "--views", choices=VIEWS, default="center",
        help="the pixels that become points: the center view's, or every view's (moved to the "
        "center camera; objects hidden in the center view get points; with an estimated "
        "disparity one estimate per view, slow: the scene's disparity range is found once and "
        "each view estimated once)",
    )
    parser.add_argument(
        "--min-confidence", type=lambda text: unit_interval(text, "a confidence"),
        default=MIN_CONFIDENCE, metavar="C",
        help="leave out pixels whose disparity confidence is below C (estimates only; the "
        "default drops 18%% of HCI antinous' pixels, which hold 64%% of its gross errors)",
    )
    add_device_argument(parser)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``objects`` subcommand."""
    parser = subparsers.add_parser(
        "objects",
        help="each object's position, depth and size in metres (and trajectories in videos)",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=HelpFormatter,
    )
    parser.add_argument("result", metavar="RESULT",
                        help="a result .npz, or a video's result folder")
    parser.add_argument("--lightfield", required=True, metavar="LF",
                        help="the light field (or video) the result was computed on")
    add_3d_arguments(parser)
    parser.add_argument("--json", metavar="OUT.json", help="write every measure as JSON")
    parser.add_argument("--csv", metavar="OUT.csv",
                        help="write a CSV: one row per object (per object and frame for a video)")
    parser.add_argument("--fps", type=positive_float, metavar="F",
                        help="frames per second of a video, for speeds in m/s")
    parser.set_defaults(func=run)


def _measures_csv(found: Objects3D) -> str:
    rows = ["id,category,pixels,points,confident_share,x_m,y_m,z_m,median_depth_m,"
            "size_1_m,size_2_m,size_3_m"]
    for m in found.measures:
        size = [np.nan] * 3 if m.box is None else list(m.box.size)
        values = [m.confident_share, *m.centroid_m, m.median_depth_m, *size]
        rows.append(",".join([str(m.object_id), m.category or "", str(m.pixels), str(m.points)]
                             + ["" if not np.isfinite(v) else f"{v:.6f}" for v in values]))
    return "\n".join(rows) + "\n"


def measure_options(args: argparse.Namespace) -> dict:
    """:func:`objects_in_3d`'s options from the command line (called once per run: it says
    first what will take long)."""
    if args.disparity == "estimate":
        which = "every view's" if args.views == "all" else "the center view's"
        print(f"estimating {which} disparity (seconds to minutes per view on a CPU; "
              "--disparity gt or FILE.npy skips it)", file=sys.stderr)
    return {"disparity": args.disparity, "camera": args.camera, "views": args.views,
            "min_confidence": args.min_confidence, "device": args.device}


def _progress(total: int, what: str):
    from tqdm import tqdm

    def wrap(items):
        return tqdm(items, total=total, desc=what, unit="view", file=sys.stderr,
                    disable=total < 2)

    return wrap


def run(args: argparse.Namespace) -> int:
    """Check the outputs, load, measure, print the table, write --json / --csv."""
    for option, path in (("--json", args.json), ("--csv", args.csv)):
        if path:
            check_writable(path, folder=False, option=option)
    kind = expect_input(args.result, "objects", ("result", "video-result"))
    expect_partner(args.lightfield, args.result, kind, "objects", "--lightfield")
    if kind == "video-result":
        return _run_video(args)
    from lfsam.io import read_lightfield
    from lfsam.result import load_result

    result = load_result(args.result)
    lightfield = read_lightfield(args.lightfield)
    views = 1 if args.views == "center" else int(lightfield.present.sum())
    camera = resolve_camera(lightfield, args.camera)  # before the long work
    found = objects_in_3d(result, lightfield, progress=_progress(views, "views"),
                          **{**measure_options(args), "camera": camera})
    count = len(found.measures)
    print(f"{count} object{'' if count == 1 else 's'} of {args.result}; disparity "
          f"{found.disparity_source}, "
          f"camera f = {found.camera.focal_px:.1f} px, b = {found.camera.baseline_m:.4g} m"
          + (f", z0 = {found.camera.focus_distance_m:.4g} m"
             if found.camera.focus_distance_m else ", parallel views"))
    print(format_table(found))
    if args.json:
        write_text_atomic(args.json, json.dumps(found.to_json(), indent=1) + "\n")
        print(f"wrote {args.json}")
    if args.csv:
        write_text_atomic(args.csv, _measures_csv(found))
        print(f"wrote {args.csv}")
    return 0


def _run_video(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    with video_with_result(args.result, args.lightfield) as (video_result, video):
        frames = tqdm(zip(video_result, video, strict=True), total=len(video), desc="frames",
                      unit="frame", file=sys.stderr)
        per_frame, paths = objects_over_video(frames, fps=args.fps, **measure_options(args))
    for index, found in enumerate(per_frame):
        print(f"frame {index}:")
        print(format_table(found))
    unit = "m/s" if args.fps else "m/frame"
    print(f"trajectories ({unit}):")
    for path in paths:
        speeds = path.speeds[np.isfinite(path.speeds)]
        mean = f"{speeds.mean():.4f}" if speeds.size else "-"
        start, end = path.positions[0], path.positions[-1]
        print(f"{path.object_id:>5} {(path.category or '-')[:14]:<14} frames {len(path.frames):>3}"
              f"  from z {start[2]:.3f} to {end[2]:.3f} m  path {path.path_length_m:.3f} m  "
              f"mean speed {mean} {unit}")
    if args.json:
        write_text_atomic(args.json, json.dumps({
            "frames": [found.to_json() for found in per_frame],
            "fps": args.fps,
            "trajectories": [path.to_json() for path in paths],
        }, indent=1) + "\n")
        print(f"wrote {args.json}")
    if args.csv:
        write_text_atomic(args.csv, trajectories_csv(paths))
        print(f"wrote {args.csv}")
    return 0
