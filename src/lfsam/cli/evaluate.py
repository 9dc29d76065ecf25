"""``lfsam evaluate``: run a method on a whole data set and tabulate the metrics (paper Tables)."""

from __future__ import annotations

import argparse
import functools
import sys
from typing import TYPE_CHECKING

from lfsam.cli.common import (
    TRACKING_MODES,
    HelpFormatter,
    add_consensus_argument,
    add_disparity_argument,
    add_refine_views_argument,
    add_tracking_argument,
)
from lfsam.cli.inputs import expect_dataset
from lfsam.cli.models import add_model_arguments, model_name_from_args, model_options_from_args
from lfsam.cli.text import add_text_arguments, check_text_weights
from lfsam.errors import LfsamError
from lfsam.fileutil import check_writable

if TYPE_CHECKING:
    from pathlib import Path

    from lfsam.api import SegmentOptions
    from lfsam.video.evaluate import VideoTracking
    from lfsam.video.io.result import VideoResult
    from lfsam.video.io.source import LightFieldVideo

DESCRIPTION = """\
Segment every scene of a data set, score each with the paper's metrics, and tabulate them.

DATASET_DIR holds one scene per sub-folder or file (anything `lfsam info` can read), each with
ground-truth disparity and labels for every view (UrbanLF-Syn val, the paper's benchmark, or
scenes made by `lfsam synth`). Entries that are not light fields are skipped with a note. For each
scene, OUT gets <scene>.npz (the result) and <scene>.metrics.json; then metrics.csv (one row per
scene and a `mean` row) and table.md (the layout of the paper's Table 1: SIoU, LPP, AA, UE, C, T,
then object recall and SIoU over center-present masks; see `lfsam metrics --help` for their
definitions). --references corners|ring|all also generates masks in those views (`lfsam segment
--help`), to find objects the center view cannot see. --text PHRASE segments, in every scene,
the instances of each phrase instead of every object (the automatic mode).

Light-field videos (`lfsam synth clip --frames F`, any video `lfsam info` reads) may be scenes
too, with ground truth in every frame: each is tracked with --method lfsam from the objects the
automatic mode finds in frame 0 (--tracking as in `lfsam segment`) into the result folder
OUT/<scene>/, and scored frame by frame as `lfsam metrics` scores it. Its row holds the means
over the frames (vIoU: over frames and views; vIoU(min): the worst view of any frame), the frames
(F) and the identity switches (IDsw: a ground-truth object whose best-matching id changes).

Runs resume: scenes whose result and metrics are in OUT are not run again (use --force). A scene
that fails gets a row with its error; the others still run.

--ray spreads the scenes over a Ray cluster, one task per light field or video (with one GPU
each on CUDA, or --gpus-per-task); without an address it starts a local cluster on this machine.
The output folder and its files (a video's result folder included: tracked on the worker, sent
back and written here) are the same as a sequential run's (needs `pip install lfsam[ray]`; the
workers must see DATASET_DIR at the same path). See docs/performance.md.

--compare DIR1 DIR2 ... prints one table with the mean row of each earlier run and the best value
of each column in bold, like the paper's Table 1 (baseline vs ours) and Table 2 (ablations).
"""

EPILOG = """\
examples:
  lfsam evaluate UrbanLF_Syn/val --method lfsam --out runs/ours
  lfsam evaluate UrbanLF_Syn/val --method video-baseline --out runs/baseline
  lfsam evaluate UrbanLF_Syn/val --ablation none --out runs/none
  lfsam evaluate UrbanLF_Syn/val --ablation ref --out runs/ref
  lfsam evaluate --compare runs/baseline runs/ours            # paper Table 1
  lfsam evaluate --compare runs/none runs/ref runs/ours       # paper Table 2
  lfsam evaluate scenes --model oracle --disparity gt --out runs/oracle   # upper bound
  lfsam evaluate hidden_scenes --model oracle --disparity gt --references corners --out runs/c
  lfsam evaluate UrbanLF_Syn/val --out runs/ours --ray                    # local Ray cluster
  lfsam evaluate UrbanLF_Syn/val --out runs/ours --ray auto --gpus-per-task 0.5
  lfsam evaluate scenes --model oracle --disparity gt --text disc --out runs/discs
  lfsam evaluate clips --model oracle --disparity gt --out runs/clips     # light-field videos
  lfsam evaluate clips --tracking prompts --out runs/clips_prompts        # SAM 2 without memory
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``evaluate`` subcommand."""
    parser = subparsers.add_parser(
        "evaluate",
        help="run a method on every scene of a data set; paper Tables 1 and 2",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=HelpFormatter,
    )
    parser.add_argument("dataset", nargs="?", metavar="DATASET_DIR", help="folder of scenes")
    parser.add_argument("--out", metavar="DIR", help="output folder (required to evaluate)")
    parser.add_argument(
        "--method", choices=["lfsam", "video-baseline"], default="lfsam",
        help="our method or the SAM 2 video baseline",
    )
    add_model_arguments(parser)
    add_text_arguments(parser)
    add_disparity_argument(parser, files=False)
    parser.add_argument(
        "--ablation", choices=["none", "ref", "ref+occ"], default="ref+occ",
        help="row of paper Table 2: no refinement or occluding, refinement only, or both",
    )
    add_refine_views_argument(parser)
    add_consensus_argument(parser)
    add_tracking_argument(parser)
    parser.add_argument(
        "--references",
        default="center",
        metavar="MODE",
        help="views where masks are generated: center (paper), corners, ring or all",
    )
    parser.add_argument(
        "--label", metavar="TEXT", help="method name in the tables (default: built from options)"
    )
    parser.add_argument("--force", action="store_true", help="recompute finished scenes")
    parser.add_argument(
        "--ray", nargs="?", const="local", metavar="ADDRESS",
        help="run the scenes as Ray tasks: on the cluster at ADDRESS (e.g. auto, "
        "ray://head:10001), or on a local cluster when no address is given",
    )
    parser.add_argument(
        "--gpus-per-task", type=float, metavar="G",
        help="with --ray: GPUs per scene (default 1 when the cluster has GPUs, else 0)",
    )
    parser.add_argument(
        "--cpus-per-task", type=float, default=1, metavar="C", help="with --ray: CPUs per task"
    )
    parser.add_argument(
        "--compare", nargs="+", metavar="DIR",
        help="instead of evaluating: tabulate the mean rows of these earlier runs",
    )
    parser.set_defaults(func=run)


def method_label(args: argparse.Namespace) -> str:
    """The method's name in the tables, e.g. ``lfsam ref+occ (sam2.1-hiera-small)``."""
    if args.label:
        return args.label
    head = "lfsam " + args.ablation if args.method == "lfsam" else args.method
    details = [model_name_from_args(args)]
    if args.method == "lfsam" and args.disparity == "gt":
        details.append("gt disparity")
    if args.random_weights:
        details.append("random weights")
    if getattr(args, "references", "center") != "center":
        details.append(f"references {args.references}")
    if getattr(args, "refine_views", "all") != "all":
        details.append(f"refine views {args.refine_views}")
    if getattr(args, "consensus", False):
        details.append("consensus")
    if getattr(args, "text", None):
        details.append("text " + ", ".join(repr(t.phrase) for t in args.text))
    return f"{head} ({', '.join(details)})"


def run(args: argparse.Namespace) -> int:
    """Evaluate a data set, or compare earlier runs."""
    from lfsam.evaluate import compare_runs, evaluate_dataset

    if args.compare:
        if args.dataset:
            raise LfsamError("give either DATASET_DIR (to evaluate) or --compare DIR..., not both")
        print(compare_runs(args.compare), end="")
        return 0
    if not args.dataset or not args.out:
        raise LfsamError(
            "lfsam evaluate needs DATASET_DIR and --out DIR (or --compare DIR1 DIR2 ...); "
            "see `lfsam evaluate --help`"
        )
    from lfsam.pipeline.references import check_references

    check_references(args.references)
    if args.references != "center" and args.method != "lfsam":
        raise LfsamError(f"--references {args.references} needs --method lfsam")
    if args.text and args.method != "lfsam":
        raise LfsamError("text prompts need --method lfsam (the video baseline takes clicks)")
    check_writable(args.out, folder=True, option="--out", inside=True)  # before any work
    expect_dataset(args.dataset)
    check_text_weights(args)
    if args.tracking == "memory" and args.model == "oracle":
        raise LfsamError("--tracking memory needs a SAM 2 --model (the oracle has no video "
                         "memory); use --tracking prompts or auto")
    try:
        from lfsam.api import RunOptions, SegmentOptions, segment
        from lfsam.pipeline import PipelineConfig
    except ImportError as exc:
        raise LfsamError(f"segmentation is unavailable in this installation ({exc})") from exc

    if args.refine_views != "all" and args.method != "lfsam":
        raise LfsamError(f"--refine-views {args.refine_views} needs --method lfsam")
    if args.consensus and args.method != "lfsam":
        raise LfsamError("--consensus needs --method lfsam")
    options = SegmentOptions(
        pipeline=PipelineConfig.from_ablation(args.ablation, refine_views=args.refine_views,
                                              consensus=args.consensus)
        if args.method == "lfsam"
        else PipelineConfig(),
        model=model_options_from_args(args),
        run=RunOptions(method=args.method, references=args.references, progress=False),
    )
    segment_fn = functools.partial(
        segment, prompts=args.text or None, disparity=args.disparity, options=options
    )
    mapper = None
    if args.gpus_per_task is not None and not args.ray:
        raise LfsamError("--gpus-per-task applies to Ray runs only; add --ray [ADDRESS]")
    if args.ray:
        from lfsam.distributed import ray_mapper

        mapper = ray_mapper(
            None if args.ray == "local" else args.ray, device=args.device,
            num_gpus=args.gpus_per_task, num_cpus=args.cpus_per_task,
        )
    label = method_label(args)
    table = evaluate_dataset(
        args.dataset, args.out, segment_fn, method_label=label, force=args.force,
        device=args.device,
        map_scenes=mapper,
        videos=_video_tracking(args, options, label),
    )
    print(table.summary_markdown(), end="")
    ok = len(table.rows) - len(table.failed)
    print(
        f"\n{ok} scene(s) scored ({len(table.ran)} run now, {len(table.resumed)} resumed), "
        f"{len(table.failed)} failed, {len(table.skipped)} skipped; "
        f"wrote {table.out_dir / 'metrics.csv'} and {table.out_dir / 'table.md'}",
        file=sys.stderr,
    )
    return 1 if table.failed else 0


def _video_tracking(args: argparse.Namespace, options: SegmentOptions,
                    label: str) -> VideoTracking | None:
    """How the data set's light-field videos are tracked (docs/design.md section 10): from the
    automatic mode's objects of frame 0, with the run's options; None for the video baseline
    (single light fields only: videos are then skipped)."""
    if args.method != "lfsam":
        return None
    from lfsam.video.evaluate import VideoTracking
    from lfsam.video.tracking.track import track_video

    def track(video: LightFieldVideo, folder: Path) -> VideoResult:
        if args.text:
            raise LfsamError("text prompts are not tracked through light-field videos; "
                             "evaluate videos without --text")
        return track_video(video, None, folder, disparity=args.disparity, options=options,
                           memory=TRACKING_MODES[args.tracking])

    return VideoTracking(track, label, device=args.device)
