"""``lfsam segment``: segment a light field from prompts in any view or automatically."""

from __future__ import annotations

import argparse
import json
import sys

from lfsam.cli.common import (
    HelpFormatter,
    add_consensus_argument,
    add_disparity_argument,
    add_refine_views_argument,
    add_tracking_argument,
    add_value_range,
    bounded_int,
    unit_interval,
)
from lfsam.cli.inputs import expect_input
from lfsam.cli.models import add_model_arguments, model_options_from_args
from lfsam.cli.prompts import PROMPT_PARSERS, PromptAction, objects_from_items
from lfsam.cli.segment_follow import add_follow_arguments, run_follow
from lfsam.cli.segment_video import run_video
from lfsam.cli.text import add_text_arguments, check_text_weights, report_text
from lfsam.errors import LfsamError
from lfsam.fileutil import check_cache_dir, check_writable
from lfsam.io import read_lightfield
from lfsam.prompts import ObjectPrompts, load_prompts
from lfsam.result import save_result
from lfsam.video import is_video

DESCRIPTION = """\
Segment a light field consistently across all views (paper section 3).

Each object is segmented with SAM 2 in the view you prompted it in (the center view unless a
prompt says @S,T), or the center view is segmented automatically (--auto); every mask is moved
into every other view with that view's disparity, occluded parts are removed with SAM 2's
features, and SAM 2 is re-prompted in each view with a point and a box (plus your own clicks,
carried there by the disparity). The result (.npz) holds the label field labels[s,t,u,v]
(0 = unlabeled; an object's label is its id), the bit-packed masks, per-view fallback flags and
IoUs, stage timings and metadata; read it with lfsam.load_result() or `lfsam show`/`metrics`.

Points are X,Y in view pixels (X = column, Y = row), boxes X0,Y0,X1,Y1; add @S,T to give them in
view (S, T) (0-based view row, view column). Each --point or --box starts a new object; a --neg
(negative click) belongs to the object started last, so `--point A --neg B --point C` is two
objects with the negative click on the first. --prompts FILE.json gives objects with any number
of points and a box each (format: README, "Prompt files"). The prompts are saved in the result,
so it can be reopened and edited (lfsam view --result). --cache DIR keeps the image encoder's
output on disk: a second run on the same views encodes nothing (the result's views_encoded).

--refine-views sparse encodes and refines about one view in six (13 of 9x9, spread over the
grid) instead of every view, several times faster; every other view takes the refined masks of
the views nearest to it, moved by disparity (docs/design.md section 3.7). --refine-views N picks
N views. The result records which views were refined (meta refined_views; lfsam show marks them).

A light-field video (a folder of frames, of view_SS_TT.mp4 files, or an [F, S, T, U, V, 3]
array) is tracked: tag prompts with a frame as X,Y#F or X,Y@S,T#F (default frame 0; an object
starts at its first frame, a --neg at frame F corrects F onwards), --auto finds the objects of
frame 0, and --out names a folder that receives one result per frame.

--references (with --auto) sets where masks are generated: center (the paper's setting), or also
the corner views (corners), the outer ring's corners and edge midpoints (ring), or every view
(all), there only where no mask lands yet, to find objects the center view cannot see (an object
found from two of them is kept once).

--text PHRASE finds every instance of a concept with SAM 3's detector in the reference view
(PHRASE@S,T: in view S,T; with --references, also in those views where nothing found so far
lands) and segments each as an object whose category is the phrase, kept in the result and in
`lfsam export --to coco`. Repeat it for several phrases; it mixes with clicks and boxes. SAM 3's
weights (facebook/sam3) are gated: request access on the model page and `hf auth login`, or pass
a local copy with --text-checkpoint DIR. With --model oracle the phrases are answered from the
scene's ground-truth categories (`lfsam synth` names each object by texture and shape, e.g.
"brick disc"). A phrase that finds nothing is reported on stderr; the run still succeeds.
"""

EPILOG = """\
examples:
  lfsam segment scene --point 160,120 --point 60,40 --out result.npz
  lfsam segment scene --point 160,120 --neg 180,120 --point 60,40@0,8 --out result.npz
  lfsam segment scene --prompts objects.json --cache ~/.cache/lfsam --out result.npz
  lfsam segment scene --point 150,90 --model oracle --oracle-merge 1 --disparity gt --out m.npz
  lfsam segment scene --box 20,30,120,140 --disparity gt --out result.npz
  lfsam segment scene --auto --model oracle --disparity gt --out result.npz
  lfsam segment ../shared/data/hci_antinous --auto --model sam2.1-hiera-tiny --random-weights \\
      --out antinous.npz            # untrained weights: a speed check, not a segmentation
  lfsam segment scene --auto --no-refine --occlusion none --out ablation_none.npz
  lfsam segment scene --auto --amg points_per_side=32 --out coarser_auto.npz
  lfsam segment hidden.npz --auto --references corners --out all_objects.npz
  lfsam segment scene --auto --refine-views sparse --out fast.npz   # 13 of 9x9 views encoded
  lfsam segment scene --point 160,120 --model edgetam --out edge.npz  # on-device SAM 2, 4x faster
  lfsam segment scene --point 160,120 --model edgetam --precision bfloat16 --out edge.npz
  lfsam segment scene --point 160,120 --checkpoint ~/models/my-sam2-hf --out mine.npz  # HF folder
  lfsam segment scene --text disc --model oracle --disparity gt --out discs.npz
  lfsam segment scene --text "red cup" --text plate@0,0 --point 60,40 --out mixed.npz
  lfsam segment scene --text cup --text-checkpoint ~/models/sam3 --out cups.npz
  lfsam segment clip --point 30,20 --point 50,40#3 --model oracle --disparity gt --out tracked
  lfsam segment clip --point 30,20 --tracking prompts --out tracked   # SAM 2 without its memory
  lfsam segment frames/ --follow --point 30,20 --model edgetam --refine-views 1 --out live
                                  # a camera's growing frames folder; ends at frames/END
  lfsam segment frames/ --follow --latest --point 30,20 --model edgetam --refine-views 1 --out live
                                  # never fall behind: the newest frame, older ones skipped
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
    prompt = parser.add_argument_group("prompts (any view; prompts or --auto)")
    for flag, kind, metavar, text in (
        ("--point", "point", "X,Y[@S,T]", "a positive click; starts a new object"),
        ("--neg", "neg", "X,Y[@S,T]", "a negative click of the object started last"),
        ("--box", "box", "X0,Y0,X1,Y1[@S,T]", "a box; starts a new object"),
    ):
        prompt.add_argument(
            flag, action=PromptAction, dest="prompt_items", default=[], metavar=metavar,
            type=PROMPT_PARSERS[kind], help=text,
        )
    prompt.add_argument(
        "--prompts", metavar="FILE.json", help="objects from a prompt file (README: Prompt files)"
    )
    prompt.add_argument(
        "--auto", action="store_true", help="automatic mask generation (the paper's setting)"
    )
    prompt.add_argument(
        "--references",
        default="center",
        metavar="MODE",
        help="with --auto or --text: center (paper), corners, ring or all: views where masks "
        "are generated or phrases looked for",
    )
    parser.add_argument(
        "--method", choices=["lfsam", "video-baseline"], default="lfsam",
        help="our method or SAM 2 video tracking over the views in snake order",
    )
    add_model_arguments(parser)
    add_text_arguments(parser)
    method = parser.add_argument_group("method switches (paper Table 2 and beyond)")
    add_disparity_argument(method)
    method.add_argument(
        "--no-refine", action="store_true", help="skip refinement (keep the propagated masks)"
    )
    add_refine_views_argument(method)
    add_consensus_argument(method)
    method.add_argument(
        "--no-surface-depth", action="store_true",
        help="with --disparity estimate, carry a glass or mirror object's mask by what its "
        "inside shows instead of by its silhouette's depth (docs/design.md section 3.2)",
    )
    add_tracking_argument(method)
    add_follow_arguments(parser)
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
    parser.add_argument(
        "--cache", metavar="DIR",
        help="on-disk cache of view embeddings (keyed by view content and model); created if "
        "missing",
    )
    parser.add_argument("--format", dest="input_format", help="input format (default: detect)")
    parser.add_argument("--out", required=True, metavar="RESULT.npz", help="result file")
    parser.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    add_value_range(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``lfsam segment``."""
    # the method's modules load on use, keeping `lfsam --help` light
    from lfsam.api import RunOptions, SegmentOptions, segment
    from lfsam.pipeline import PipelineConfig
    from lfsam.pipeline.references import check_references

    check_references(args.references)
    has_prompts = bool(args.prompt_items or args.prompts or args.text)
    if has_prompts == args.auto:
        raise LfsamError(
            "give prompts (--point X,Y, --box X0,Y0,X1,Y1, --text PHRASE or --prompts "
            "FILE.json) or --auto, not both and not neither"
        )
    config = PipelineConfig(
        refine=not args.no_refine,
        occlusion=args.occlusion,
        propagation=args.propagation,
        t_sim=args.t_sim,
        t_iou=args.t_iou,
        refine_views=args.refine_views,
        consensus=args.consensus,
        surface_depth=not args.no_surface_depth,
    )
    if args.follow:  # issue 35: a frames folder still being written
        return run_follow(args, config, has_prompts)
    if args.follow_timeout is not None:
        raise LfsamError("--follow-timeout goes with --follow")
    if args.latest:
        raise LfsamError("--latest goes with --follow (a frames folder still being written)")
    if args.poses or args.camera:
        raise LfsamError("--poses and --camera go with --follow; for a video's result use "
                         "lfsam poses RESULT --lightfield VIDEO")
    expect_input(args.path, "segment", ("lightfield", "video"))
    if args.input_format is None and is_video(args.path):  # issue 25: track through frames
        return run_video(args, config, has_prompts)
    if args.tracking != "auto":
        raise LfsamError(f"--tracking {args.tracking} applies to light-field videos; "
                         f"{args.path} is a single light field")
    check_writable(args.out, folder=False, option="--out")  # before any reading or model
    if args.cache is not None:
        check_cache_dir(args.cache)
    check_text_weights(args)  # missing SAM 3 weights: one line now, not after the reading
    lightfield = read_lightfield(
        args.path, format=args.input_format, value_range=args.value_range
    )
    objects = None
    if has_prompts:
        objects = (
            load_prompts(args.prompts, lightfield.grid_shape, lightfield.view_shape)
            if args.prompts
            else []
        )
        first = max((o.obj_id for o in objects if isinstance(o, ObjectPrompts)), default=0) + 1
        objects += objects_from_items(args.prompt_items, first_id=first)
        objects += args.text
    options = SegmentOptions(
        pipeline=config,
        model=model_options_from_args(args),
        run=RunOptions(
            method=args.method,
            references=args.references,
            cache_dir=args.cache,
            progress=not args.quiet,
            baseline={
                "objects_per_pass": args.objects_per_pass,
                "start": args.baseline_start,
            },
        ),
    )
    result = segment(lightfield, objects, disparity=args.disparity, options=options)
    save_result(result, args.out)
    if not args.quiet:
        summary = {
            "out": args.out,
            "masks": result.num_masks,
            "views": int(result.labels.shape[0] * result.labels.shape[1]),
            "views_encoded": result.meta.get("views_encoded"),
            "seconds": round(result.timings.get("total", float("nan")), 3),
            "ms_per_mask_view": None
            if result.ms_per_mask_view is None
            else round(result.ms_per_mask_view, 3),
            "fallback_views": None if result.fallback is None else int(result.fallback.sum()),
            "random_weights": result.meta.get("random_weights"),
        }
        if "text" in result.meta:
            summary["text"] = result.meta["text"]
            report_text(result.meta["text"], result.meta.get("text_threshold"))
        print(json.dumps(summary), file=sys.stdout)
    return 0
