"""``lfsam segment``: segment a light field from center-view prompts or automatically."""

from __future__ import annotations

import argparse
import json
import sys

from lfsam.cli.common import (
    HelpFormatter,
    add_value_range,
    bounded_int,
    parse_floats,
    unit_interval,
)
from lfsam.cli.models import add_model_arguments

DESCRIPTION = """\
Segment a light field consistently across all views (paper section 3).

The center view is segmented with SAM 2 from your prompts (each --point or --box is one object)
or automatically (--auto); every mask is moved into every other view with the scene's disparity,
occluded parts are removed with SAM 2's features, and SAM 2 is re-prompted in each view with a
point and a box. The result (.npz) holds the label field labels[s,t,u,v] (0 = unlabeled), the
bit-packed masks, per-view fallback flags and IoUs, stage timings and metadata; read it with
lfsam.load_result() or `lfsam show` / `lfsam metrics`.

Points are X,Y in center-view pixels (X = column, Y = row). When as many --point as --box are
given, point i and box i prompt object i together.
"""

EPILOG = """\
examples:
  lfsam segment scene --point 160,120 --point 60,40 --out result.npz
  lfsam segment scene --box 20,30,120,140 --disparity gt --out result.npz
  lfsam segment scene --auto --model oracle --disparity gt --out result.npz
  lfsam segment ../shared/data/hci_antinous --auto --model sam2.1-hiera-tiny --random-weights \\
      --out antinous.npz            # untrained weights: a speed check, not a segmentation
  lfsam segment scene --auto --no-refine --occlusion none --out ablation_none.npz
  lfsam segment scene --auto --amg points_per_side=32 --out coarser_auto.npz
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``segment`` subcommand."""
    parser = subparsers.add_parser(
        "segment",
        help="segment a light field (LFSAM or the SAM 2 video baseline)",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=HelpFormatter,
    )
    parser.add_argument("path", help="light field: a folder of views, .npz/.npy/.h5/.mat, ...")
    prompt = parser.add_argument_group("prompts (center view; one of them)")
    prompt.add_argument(
        "--point", action="append", default=[], metavar="X,Y",
        type=lambda s: parse_floats(s, 2), help="a positive point; each makes one object",
    )
    prompt.add_argument(
        "--box", action="append", default=[], metavar="X0,Y0,X1,Y1",
        type=lambda s: parse_floats(s, 4), help="a box; each makes one object",
    )
    prompt.add_argument(
        "--auto", action="store_true", help="automatic mask generation (the paper's setting)"
    )
    parser.add_argument(
        "--method", choices=["lfsam", "video-baseline"], default="lfsam",
        help="our method or SAM 2 video tracking over the views in snake order",
    )
    add_model_arguments(parser)
    method = parser.add_argument_group("method switches (paper Table 2 and beyond)")
    method.add_argument(
        "--disparity", default="estimate", metavar="estimate|gt|FILE.npy",
        help="center-view disparity: estimated (structure tensor), the scene's ground truth, "
        "or a (U, V) .npy in lfsam's convention",
    )
    method.add_argument(
        "--no-refine", action="store_true", help="skip refinement (keep the propagated masks)"
    )
    method.add_argument(
        "--occlusion", choices=["semantic", "geometric", "both", "none"], default="semantic",
        help="occluding: SAM 2 feature similarity (paper), z-buffer of the center disparity, "
        "both, or none",
    )
    method.add_argument(
        "--propagation", choices=["pixel", "mean", "median"], default="pixel",
        help="move each pixel by its disparity (paper eq. 2) or the whole mask by its "
        "mean/median disparity (authors' code)",
    )
    method.add_argument(
        "--t-sim", type=unit_interval, default=0.7, help="semantic occluding threshold, in [0, 1]"
    )
    method.add_argument(
        "--t-iou", type=unit_interval, default=0.1, help="refinement fallback threshold, in [0, 1]"
    )
    method.add_argument(
        "--objects-per-pass", type=bounded_int(1), default=15,
        help="video baseline: objects tracked per pass (the authors used 15)",
    )
    method.add_argument(
        "--baseline-start", choices=["first", "center"], default="first",
        help="video baseline: start on the first view of the snake, or on the center view "
        "and track outwards both ways",
    )
    parser.add_argument("--format", dest="input_format", help="input format (default: detect)")
    parser.add_argument("--out", required=True, metavar="RESULT.npz", help="result file")
    parser.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    add_value_range(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``lfsam segment``."""
    from lfsam.api import make_prompts, run_segmentation
    from lfsam.errors import LfsamError
    from lfsam.fileutil import check_output_path
    from lfsam.io import read_lightfield
    from lfsam.pipeline import PipelineConfig
    from lfsam.result import save_result

    has_prompts = bool(args.point or args.box)
    if has_prompts == args.auto:
        raise LfsamError(
            "give prompts (--point X,Y and/or --box X0,Y0,X1,Y1) or --auto, not both and not "
            "neither"
        )
    check_output_path(args.out)
    lightfield = read_lightfield(
        args.path, format=args.input_format, value_range=args.value_range
    )
    config = PipelineConfig(
        refine=not args.no_refine,
        occlusion=args.occlusion,
        propagation=args.propagation,
        t_sim=args.t_sim,
        t_iou=args.t_iou,
    )
    amg = dict(args.amg) or None
    result = run_segmentation(
        lightfield,
        method=args.method,
        model=args.model,
        checkpoint=args.checkpoint,
        random_weights=args.random_weights,
        disparity=args.disparity,
        config=config,
        prompts=make_prompts(args.point, args.box),
        device=None if args.device == "auto" else args.device,
        amg_options=amg,
        baseline_options={
            "objects_per_pass": args.objects_per_pass,
            "start": args.baseline_start,
        },
        progress=not args.quiet,
    )
    save_result(result, args.out)
    if not args.quiet:
        summary = {
            "out": args.out,
            "masks": result.num_masks,
            "views": int(result.labels.shape[0] * result.labels.shape[1]),
            "seconds": round(result.timings.get("total", float("nan")), 3),
            "ms_per_mask_view": None
            if result.ms_per_mask_view is None
            else round(result.ms_per_mask_view, 3),
            "fallback_views": None if result.fallback is None else int(result.fallback.sum()),
            "random_weights": result.meta.get("random_weights"),
        }
        print(json.dumps(summary), file=sys.stdout)
    return 0
