"""``lfsam demo``: the bundled synthetic scene, segmented, scored and drawn (``make demo``)."""

from __future__ import annotations

import argparse

from lfsam.cli.common import HelpFormatter
from lfsam.cli.models import add_model_arguments, model_name_from_args
from lfsam.fileutil import check_writable

DESCRIPTION = """\
Run lfsam end to end on the bundled synthetic light field (9x9 views of 240x320 with exact
ground truth), offline.

The scene is generated, segmented automatically with the best segmenter available (SAM 2
sam2.1-hiera-small when its weights are cached or downloadable, otherwise the ground-truth
oracle; the command says which and why), with disparity estimated from the views. The paper's
metrics are printed beside the scores of the ground-truth labels themselves, and the figures and
animation are written to the output folder.
"""

EPILOG = """\
examples:
  lfsam demo                          # writes demo_output/
  lfsam demo --out /tmp/demo --model oracle
  lfsam demo --checkpoint sam2.1_hiera_small.pt
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``demo`` subcommand."""
    parser = subparsers.add_parser(
        "demo",
        help="segment, score and draw the bundled synthetic scene (offline)",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=HelpFormatter,
    )
    parser.add_argument("--out", default="demo_output", help="output folder")
    add_model_arguments(
        parser, default=None, model_help="; not given: sam2.1-hiera-small if its weights can "
        "be had, else the oracle",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``lfsam demo``."""
    check_writable(args.out, folder=True, option="--out", inside=True)  # before any work
    from lfsam.demo import run_demo

    report = run_demo(
        args.out,
        model=model_name_from_args(args),
        checkpoint=args.checkpoint,
        random_weights=args.random_weights,
        amg_options=dict(args.amg) or None,
        device=args.device,
        progress=not args.quiet,
        precision=args.precision,
    )
    print(f"Segmenter: {report.model} — {report.reason}.\n")
    print(report.table)
    print("Files:")
    for path in report.files:
        print(f"  {path}")
    print(f"\nDone in {report.seconds:.1f} s.")
    return 0
