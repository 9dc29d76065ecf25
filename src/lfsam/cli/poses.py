"""``lfsam poses``: every object's 6D pose over a light-field video (docs/design.md §12)."""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from lfsam.camera import CAMERA_EXAMPLE
from lfsam.cli.common import HelpFormatter, add_device_argument
from lfsam.cli.inputs import expect_input, expect_partner, video_with_result
from lfsam.disparity.carried import ESTIMATE_MODES
from lfsam.errors import LfsamError
from lfsam.fileutil import check_writable, write_text_atomic
from lfsam.metrics.pose import rotation_error_deg
from lfsam.objects3d import resolve_camera
from lfsam.poses import (
    POSE_VIEWS,
    ObjectPoses,
    bop_csv,
    default_pose_views,
    poses_csv,
    poses_json,
    poses_of_video,
)

__all__ = ["register", "run"]

DESCRIPTION = f"""\
Each segmented object's 6D pose, frame by frame: how it has turned and moved since its first
frame, in metres in the center view's camera frame (x right, y down, z forward), as `lfsam
objects` uses it.

Per object and frame:
  motion   the rigid 4x4 transform carrying the object's points at its first frame onto its
           points at this frame (identity at the first frame);
  pose     the object's frame in the camera (origin at the first frame's centroid, axes its
           principal axes): pose = motion . first pose;
  inliers  the share of the frame's points within 3 mm of the registered model, and rmse_m
           their RMS point-to-plane distance;
  status   tracked, uncertain (a pose given, but its fit is several times worse than the
           object's own: check it before you act on it), lost (too few points or no fit: no
           pose is given) or found again.

How: the object's points from every view that sees it (--views all, the default with --disparity gt
or a file; the light field sees around occluders), a coarse motion from SIFT matches inside its
masks in the center and corner views lifted to 3D (RANSAC + Kabsch), refined by point-to-plane ICP
of all its points onto a keyframe model of the object (no drift from chaining frame to frame). A
mask's rim is checked against the depth: pixels just behind a depth jump, and pixels within 2 pixels
of another label that are not the object's own silhouette, are left out, so a mask a pixel or two
off (as every real segmenter's is) adds no point of the wall behind the object. A single light field
(a result .npz) gives each object's pose with identity motion.

The camera is --camera CAMERA.json ({CAMERA_EXAMPLE}), else the light field's own (an HCI 4D
parameters.cfg, or an lfsam scene folder's: `lfsam synth` writes one). With --disparity
estimate (the default) the points come from the center and the four corner views (--views
corners), each estimated on its own: 5 estimates per frame, with the estimator's light
settings (--estimate light: its cost volume at one feature scale, without the structure-tensor
fusion and the surface fit that sharpen one depth map's edges; about 1.4 s a view of 7x7x240x320).
--estimate own estimates each view as `lfsam disparity` does (about 3.5 times the time; on the
rigid test scenes the largest rotation error 2.8 instead of 4.7 degrees). --views all estimates
every view (49 per frame on a 7x7 grid: about 10 times the time); --estimate carried estimates
the center view alone and carries its disparity to the other views through the light field's
geometry (one estimate per frame; less accurate: the views then repeat the center's errors).

Outputs: the table on the terminal; --json everything ({{"camera", "objects": [{{"id",
"category", "first_pose", "frames": [{{"frame", "status", "motion", "pose", "inliers",
"rmse_m", ...}}]}}]}}); --csv one row per object and frame (pose as quaternion w x y z and
translation in metres, then the motion's); --bop the BOP challenge's results CSV (scene_id,
im_id = frame, obj_id = object id, score = inliers, R, t in mm, time in s) for the BOP toolkit.
"""

EPILOG = """\
examples:
  lfsam synth boxes --rigid --seed 7          # 3 boxes under known motion, 10 frames of 7x7 views
  lfsam segment boxes --auto --model oracle --disparity gt --out boxes_result
  lfsam poses boxes_result --lightfield boxes --disparity gt --json poses.json
  lfsam poses boxes_result --lightfield boxes --csv poses.csv --bop bop.csv   # estimated depth
  lfsam poses boxes_result --lightfield boxes --estimate own        # full estimates, 3.5x time
  lfsam poses boxes_result --lightfield boxes --estimate carried    # one estimate per frame
  lfsam segment scene --auto --model oracle --disparity gt --out result.npz
  lfsam poses result.npz --lightfield scene --camera camera.json      # one light field
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``poses`` subcommand."""
    parser = subparsers.add_parser(
        "poses",
        help="each object's 6D pose (rotation and translation) over a light-field video",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=HelpFormatter,
    )
    parser.add_argument("result", metavar="RESULT",
                        help="a video's result folder (or a single result .npz)")
    parser.add_argument("--lightfield", required=True, metavar="LF",
                        help="the light-field video (or light field) the result was computed on")
    parser.add_argument(
        "--disparity", default="estimate", metavar="estimate|gt|FILE.npy",
        help="disparity: estimated (with its confidence; see --estimate), the ground truth, or "
        "a (U, V) / (S, T, U, V) .npy map used for every frame",
    )
    parser.add_argument(
        "--estimate", choices=ESTIMATE_MODES, default="light",
        help="with --disparity estimate: each used view's own estimate with the estimator's "
        "light settings (one per view and frame), each used view's own estimate as `lfsam "
        "disparity` makes it (about 3.5 times the time, more accurate), or the center view's "
        "estimate carried to the other views (one per frame, less accurate)",
    )
    parser.add_argument("--camera", metavar="CAMERA.json",
                        help=f"camera: {CAMERA_EXAMPLE} (default: the light field's own)")
    parser.add_argument("--views", choices=POSE_VIEWS, default=None,
                        help="the views whose pixels become points: every view, the center and "
                        "the four corner views, or the center view only (fastest, least "
                        "accurate) (default: corners with --disparity estimate, else all)")
    parser.add_argument("--json", metavar="OUT.json", help="write everything as JSON")
    parser.add_argument("--csv", metavar="OUT.csv",
                        help="write one row per object and frame (quaternions, metres)")
    parser.add_argument("--bop", metavar="OUT.csv", help="write the BOP challenge results CSV")
    parser.add_argument("--scene-id", type=int, default=0, metavar="N",
                        help="scene_id of the --bop rows")
    add_device_argument(parser)
    parser.set_defaults(func=run)


def _line(obj: ObjectPoses) -> str:
    tracked = [f for f in obj.frames if f.pose is not None]
    lost = sum(f.status == "lost" for f in obj.frames)
    uncertain = sum(f.status == "uncertain" for f in obj.frames)
    if not tracked:
        return f"{obj.object_id:>5} {(obj.category or '-')[:14]:<14} lost in every frame"
    last = tracked[-1]
    angle = rotation_error_deg(last.motion, np.eye(4))  # the motion's rotation angle
    shift = np.linalg.norm(last.pose[:3, 3] - obj.first_pose[:3, 3])
    inliers = np.mean([f.inliers for f in tracked])
    rmse = np.nanmean([f.rmse_m for f in tracked])
    seconds = np.mean([f.seconds for f in obj.frames])
    centre = last.pose[:3, 3]
    return (f"{obj.object_id:>5} {(obj.category or '-')[:14]:<14} frames {obj.frames[0].frame}-"
            f"{obj.frames[-1].frame} ({lost} lost, {uncertain} uncertain)  at frame "
            f"{last.frame}: turned "
            f"{angle:6.2f} deg, moved {1000 * shift:6.1f} mm, centre "
            f"[{centre[0]:.3f}, {centre[1]:.3f}, {centre[2]:.3f}] m;  inliers {inliers:.2f}, "
            f"rmse {1000 * rmse:.2f} mm, {seconds:.2f} s/frame")


def _say_estimating(args: argparse.Namespace, grid: tuple[int, int]) -> None:
    """Once the inputs are checked: an estimated disparity is most of the run's time."""
    if args.disparity != "estimate":
        return
    if args.estimate == "carried":
        print("estimating the center view's disparity in every frame, carried to the other "
              "views (--disparity gt or FILE.npy skips it)", file=sys.stderr)
        return
    count = {"all": grid[0] * grid[1], "corners": 5, "center": 1}[args.views]
    cost = [] if args.views != "all" else [f"{count / 5:.0f} times the time of --views corners"]
    if args.estimate == "own":
        cost.append("the full estimator: about 3.5 times the time of --estimate light")
    cost = f" ({'; '.join(cost)})" if cost else ""
    print(f"estimating {count} view{'' if count == 1 else 's'}' disparity in every frame"
          f"{cost}; seconds per view on a CPU (--disparity gt or FILE.npy skips it)",
          file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    """Check inputs and outputs, register every object frame by frame, print and write."""
    for option, path in (("--json", args.json), ("--csv", args.csv), ("--bop", args.bop)):
        if path:
            check_writable(path, folder=False, option=option)
    args.views = args.views or default_pose_views(args.disparity)
    kind = expect_input(args.result, "poses", ("result", "video-result"))
    expect_partner(args.lightfield, args.result, kind, "poses", "--lightfield")
    from tqdm import tqdm

    if kind == "video-result":
        with video_with_result(args.result, args.lightfield) as (video_result, video):
            camera = resolve_camera(video.frame(0), args.camera)  # before any work
            if args.disparity == "gt" and not video.has_disparity:
                raise LfsamError(f"{args.lightfield} has no ground-truth disparity; use "
                                 "--disparity estimate or FILE.npy")
            _say_estimating(args, video.frame(0).grid_shape)
            frames = tqdm(zip(video_result, video, strict=True), total=len(video),
                          desc="frames", unit="frame", file=sys.stderr)
            _, objects = poses_of_video(frames, disparity=args.disparity, camera=camera,
                                        views=args.views, estimate=args.estimate,
                                        device=args.device)
            count = len(video)
    else:
        from lfsam.io import read_lightfield
        from lfsam.lightfield import check_result_shape
        from lfsam.result import load_result

        result = load_result(args.result)
        lightfield = read_lightfield(args.lightfield)
        check_result_shape(result.labels.shape, lightfield, args.result)
        camera = resolve_camera(lightfield, args.camera)
        _say_estimating(args, lightfield.grid_shape)
        _, objects = poses_of_video([(result, lightfield)], disparity=args.disparity,
                                    camera=camera, views=args.views, estimate=args.estimate,
                                    device=args.device)
        count = 1
    print(f"{len(objects)} object{'' if len(objects) == 1 else 's'} over {count} frame"
          f"{'' if count == 1 else 's'}; disparity {args.disparity}, views {args.views}, "
          f"camera f = {camera.focal_px:.1f} px, b = {camera.baseline_m:.4g} m")
    for obj in objects:
        print(_line(obj))
    if args.json:
        document = poses_json(camera, objects, disparity=args.disparity, views=args.views,
                              estimate=args.estimate if args.disparity == "estimate" else None)
        write_text_atomic(args.json, json.dumps(document, indent=1) + "\n")
        print(f"wrote {args.json}")
    if args.csv:
        write_text_atomic(args.csv, poses_csv(objects))
        print(f"wrote {args.csv}")
    if args.bop:
        write_text_atomic(args.bop, bop_csv(objects, scene_id=args.scene_id))
        print(f"wrote {args.bop}")
    return 0
