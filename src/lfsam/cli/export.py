"""``lfsam export``: a result in the formats other tools read (docs/design.md section 8)."""

from __future__ import annotations

import argparse

from lfsam.cli.common import HelpFormatter
from lfsam.cli.inputs import expect_input, expect_partner, video_with_result
from lfsam.cli.objects import add_3d_arguments, measure_options
from lfsam.errors import LfsamError
from lfsam.export import EXPORT_FORMATS, check_export_target, export_result, export_video
from lfsam.fileutil import check_writable
from lfsam.io import read_lightfield
from lfsam.lightfield import check_result_shape
from lfsam.result import load_result
from lfsam.video.io.result import is_video_result, load_video_result

DESCRIPTION = """\
Export a segmentation result (.npz from `lfsam segment`) into a folder, for the next tool:

  png    view_SS_TT.png: one 16-bit label PNG per view (pixel value = object id, 0 = none);
         sorted file names are row-major view order (view row s, then view column t)
  masks  object_NNNN/view_SS_TT.png: one black/white PNG per object and view
  coco   annotations.json: COCO instances, one image per view (grid position in view_row,
         view_col), one RLE annotation per object and view, track_id = object id in every view
  npy    labels.npy [S, T, U, V] int32, masks.npy [K, S, T, U, V] bool, ids.npy [K], present.npy
  ply    object_NNNN.ply: one coloured point cloud per object (x y z red green blue, binary
         little-endian; metres in the center view camera's frame: x right, y down, z forward)
         and objects.json (each object's measures, as `lfsam objects --json`); needs
         --lightfield and a camera (--camera, or the light field's own); pixels whose disparity
         confidence is below --min-confidence are left out

A light-field video's result folder (from `lfsam segment VIDEO`) is exported frame by frame:
png, masks and npy into frame_FFFF/ folders (frame_0000/view_SS_TT.png ...), coco as one
annotations.json with one image per frame and view (frame_index, view_row, view_col; one COCO
video per view) and track_id = object id in every frame and view.

Every folder also holds lfsam_export.json (grid, view size, object ids, source, views present).
Views absent from a partial grid (the result's `present` flags) are never written, only flagged.
The folder is written atomically; an existing non-empty folder is replaced only with --force.
With --lightfield the result is checked against its light field (same grid and view size).
"""

EPILOG = """\
examples:
  lfsam export result.npz --to png --out labels/
  lfsam export result.npz --to coco --out coco/ --force
  lfsam export result.npz --to masks --out masks/ --lightfield scene
  lfsam export video_result/ --to coco --out coco/
  lfsam export result.npz --to ply --lightfield scene --out clouds/
  lfsam export result.npz --to ply --lightfield LF --camera camera.json --disparity gt --out clouds/
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``export`` subcommand."""
    parser = subparsers.add_parser(
        "export",
        help="write a result as label PNGs, binary masks, COCO JSON or NumPy arrays",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=HelpFormatter,
    )
    parser.add_argument("result", metavar="RESULT.npz", help="result with labels [S, T, U, V]")
    parser.add_argument("--to", required=True, choices=(*EXPORT_FORMATS, "ply"),
                        help="output format")
    parser.add_argument("--out", required=True, metavar="DIR", help="output folder")
    parser.add_argument(
        "--force", action="store_true", help="replace --out if it is a non-empty folder"
    )
    parser.add_argument(
        "--lightfield", metavar="PATH",
        help="check the result against this light field (needed for --to ply: its colours and "
        "disparity)"
    )
    add_3d_arguments(parser.add_argument_group("point clouds (--to ply)"))
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Load the result (and its light field), export it, print what was written."""
    check_writable(args.out, folder=True, option="--out")
    check_export_target(args.out, args.force)
    kind = expect_input(args.result, "export", ("result", "video-result"))
    expect_partner(args.lightfield, args.result, kind, "export", "--lightfield")
    if args.to == "ply":
        return _run_ply(args, kind)
    if is_video_result(args.result):
        return _run_video(args)
    result = load_result(args.result)
    if args.lightfield:
        lightfield = read_lightfield(args.lightfield)
        check_result_shape(result.labels.shape, lightfield, args.result)
        if result.present is None:
            result.present = lightfield.present
    out = export_result(result, args.out, args.to, force=args.force)
    s_count, t_count = result.grid_shape
    print(
        f"wrote {args.to} export of {s_count} x {t_count} views "
        f"({int(result.present_mask.sum())} present) to {out}"
    )
    return 0


def _run_video(args: argparse.Namespace) -> int:
    """Export a video result folder frame by frame."""
    video = load_video_result(args.result)
    if args.lightfield:  # checked against its video
        with video_with_result(args.result, args.lightfield):
            pass
    out = export_video(iter(video), args.out, args.to, force=args.force)
    frames, s_count, t_count = video.shape[:3]
    print(f"wrote {args.to} export of {frames} frames of {s_count} x {t_count} views to {out}")
    return 0


def _run_ply(args: argparse.Namespace, kind: str | None) -> int:
    """One PLY per object (per frame of a video) from the result, its light field and a camera."""
    from lfsam.objects3d import export_point_clouds, objects_in_3d, resolve_camera

    if not args.lightfield:
        raise LfsamError("--to ply needs --lightfield LF: the light field the result was "
                         "computed on (its colours and disparity make the points)")
    if kind == "video-result":
        with video_with_result(args.result, args.lightfield) as (video_result, frames):
            options = measure_options(args)
            found = [objects_in_3d(result, lf, **options)
                     for result, lf in zip(video_result, frames, strict=True)]
        out = export_point_clouds(found, args.out, force=args.force)
        count = sum(len(f.measures) for f in found)
        print(f"wrote {count} point clouds over {len(found)} frames to {out}")
        return 0
    lightfield = read_lightfield(args.lightfield)
    camera = resolve_camera(lightfield, args.camera)  # before the long work
    options = {**measure_options(args), "camera": camera}
    found = objects_in_3d(load_result(args.result), lightfield, **options)
    out = export_point_clouds(found, args.out, force=args.force)
    points = sum(len(c.xyz) for c in found.clouds.values())
    print(f"wrote {len(found.measures)} point clouds ({points} points; disparity "
          f"{found.disparity_source}) to {out}")
    return 0
