"""``lfsam metrics``: score a segmentation result against ground truth (paper section 4.1)."""

from __future__ import annotations

import argparse
import json
import math

from lfsam.cli.common import HelpFormatter, add_device_argument, bounded_int
from lfsam.cli.inputs import expect_input, expect_partner, video_with_result
from lfsam.io import read_lightfield
from lfsam.result import load_result
from lfsam.video.io.result import is_video_result

DESCRIPTION = """\
Score a segmentation result with the paper's metrics (section 4.1) and print them as JSON.

Every view's masks are projected into the center view with the ground-truth disparity of that
view (rounded to the nearest pixel; pixels landing outside the frame are dropped), then:
  siou              self IoU: per mask, the mean IoU between its projection from each other view
                    and its center-view mask; mean over masks (higher is better, <= 1). As in
                    the paper, a mask absent from the center view scores 0
  siou_center       siou over the masks present in the center view only
  lpp               labels per pixel (Khan et al. 2019): distinct labels one center pixel receives
                    from all views, averaged over labeled pixels (lower is better, >= 1)
  aa                achievable accuracy: each label mapped to the ground-truth label it overlaps
                    most; accuracy over pixels labeled in both (higher is better)
  ue                undersegmentation error (Neubert & Protzel 2012; lower is better)
  coverage          fraction of all light-field pixels that carry a label (C)
  recall            object recall: fraction of ground-truth objects (with at least --min-area
                    pixels in some view) that a label matches with IoU >= 0.5 in the view where
                    the object is largest; counts objects the center view cannot see
  view_iou          per-view IoU against the ground truth: each predicted object matched to the
                    ground-truth object it covers most in its reference view, its IoU with it
                    in every view; mean over the objects of a view, then over the views (1 is
                    exact). Unlike siou it sees masks that agree across views but are wrong
  view_iou_worst    the worst view's per-view IoU
  ms_per_mask_view  milliseconds per mask per view from the result's timings (T; null without)
  num_masks         N used for T: the stored masks, or the distinct labels of a labels-only file
Undefined values (e.g. of an empty result) are null.

RESULT is any .npz holding labels [S, T, U, V] (0 = unlabeled), e.g. from `lfsam segment`. The
ground truth must have disparity and labels for every view (UrbanLF-Syn, `lfsam synth` scenes).

A light-field video's result folder (from `lfsam segment VIDEO`) is scored against a video with
ground truth (`lfsam synth OUT --frames F`), frame by frame: {"frames": [per frame the metrics
above, "frame" and "matches" (ground-truth id -> best-matching predicted id: largest IoU over
all views of the frame)], "summary": {...}} with
  identity_switches  changes of a ground-truth object's best-matching id between consecutive
                     frames where it is visible and matched, summed over objects ("switches":
                     per object)
  mean_view_iou      mean over frames of view_iou (the mean IoU over frames and views)
  view_iou_worst     the worst view of any frame
  tracks             each ground-truth object's one track for the whole video (the predicted
                     id of the one-to-one pairing covering most pixels; "untracked": objects
                     without one) and, over the views of each frame where a tracked object
                     shows at least "min_pixels" (100 at 96x128, scaled with the view's area),
                     "lost": the share where its track's IoU is below 0.5, and "mean_iou"
and the mean over frames of every other metric.
"""

EPILOG = """\
examples:
  lfsam metrics result.npz --gt scene
  lfsam metrics result.npz --gt UrbanLF_Syn/val/Image001 --device cpu
  lfsam metrics result.npz --gt hidden.npz --min-area 50   # objects >= 50 pixels count
  lfsam metrics video_result/ --gt clip/                   # a light-field video
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``metrics`` subcommand."""
    parser = subparsers.add_parser(
        "metrics",
        help="the paper's metrics of a result against ground truth (JSON)",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=HelpFormatter,
    )
    parser.add_argument("result", metavar="RESULT.npz", help="result with labels [S, T, U, V]")
    parser.add_argument(
        "--gt", required=True, metavar="PATH",
        help="the light field with per-view ground-truth disparity and labels",
    )
    add_device_argument(parser)
    parser.add_argument(
        "--min-area",
        type=bounded_int(1),
        default=None,
        metavar="PIXELS",
        help="pixels an object must show in some view to count for recall "
        "(default: 0.1%% of a view, at least 4)",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Load the result and the ground truth, print the metrics as one JSON object."""
    from lfsam.metrics import evaluate_result  # loads on use, keeping `lfsam --help` light

    kind = expect_input(args.result, "metrics", ("result", "video-result"))
    expect_partner(args.gt, args.result, kind, "metrics", "--gt")
    if is_video_result(args.result):
        return _run_video(args)
    result = load_result(args.result)
    gt = read_lightfield(args.gt)
    metrics = evaluate_result(result, gt, device=args.device, min_area=args.min_area)
    print(json.dumps(_clean(metrics), indent=2))
    return 0


def _clean(metrics: dict) -> dict:
    """NaN as null."""
    return {
        key: value if not isinstance(value, float) or not math.isnan(value) else None
        for key, value in metrics.items()
    }


def _run_video(args: argparse.Namespace) -> int:
    """Score a video result frame by frame against a video with ground truth."""
    from lfsam.metrics.temporal import evaluate_frames

    with video_with_result(args.result, args.gt) as (result, video):
        pairs = ((result.frame(f), video.frame(f)) for f in range(len(result)))
        scores = evaluate_frames(pairs, device=args.device, min_area=args.min_area)
    scores["frames"] = [_clean(row) for row in scores["frames"]]
    scores["summary"] = _clean(scores["summary"])
    print(json.dumps(scores, indent=1))
    return 0
