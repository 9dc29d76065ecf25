"""``lfsam convert``: any supported light field to lfsam's scene folder or ``.npz``."""

from __future__ import annotations

import argparse
from pathlib import Path

from lfsam.cli.common import HelpFormatter, add_value_range
from lfsam.cli.inputs import expect_input
from lfsam.fileutil import check_writable
from lfsam.io import FORMATS, read_lightfield, resolve_output, write_lightfield

__all__ = ["register", "run"]

DESCRIPTION = """\
Convert a light field to lfsam's own formats, with its ground truth in lfsam's convention.

The output format follows OUT's name:
  OUT.npz   one archive: views [S, T, U, V, 3] uint8, and disparity / labels [S, T, U, V]
            (or [U, V] for the center view only) when present, plus JSON meta
  OUT       a scene folder: lfsam_scene.json, view_RR_CC.png (0-based), disparity.npy,
            labels.npy; any image viewer can open the views

Readers detect the input format (lfsam info shows what they found); UrbanLF and old-HCI inputs
are re-oriented on the way (flipped view axes, negated disparity) as the reader established from
the data. Outputs are written atomically: a failed conversion leaves nothing behind.
"""

EPILOG = """\
examples:
  lfsam convert ../shared/data/hci_antinous antinous          # scene folder
  lfsam convert ../shared/data/t_rex_5x5 t_rex.npz            # one .npz archive
  lfsam convert lf.mat lf_scene --format-in mat
"""


def run(args: argparse.Namespace) -> int:
    """Read ``args.path`` and write it to ``args.out``."""
    expect_input(args.path, "convert", ("lightfield",))
    if Path(args.path).exists():  # a bad output fails before the input is read
        check_writable(args.out, folder=Path(args.out).suffix.lower() != ".npz", option="OUT")
        resolve_output(args.out)
    lf = read_lightfield(args.path, args.format_in, value_range=args.value_range)
    out = write_lightfield(lf, args.out)
    kind = ".npz archive" if out.suffix.lower() == ".npz" else "scene folder"
    s_count, t_count = lf.grid_shape
    rows, cols = lf.view_shape
    extras = [
        name
        for name, value in (("disparity", lf.disparity), ("labels", lf.labels))
        if value is not None
    ]
    print(
        f"wrote {out} ({kind}): {s_count}x{t_count} views of {rows}x{cols} from "
        f"{lf.meta.get('format', '?')}" + (f", with {' and '.join(extras)}" if extras else "")
    )
    return 0


def register(subparsers) -> None:
    """Add the ``convert`` subcommand."""
    parser = subparsers.add_parser(
        "convert",
        help="convert a light field to an lfsam scene folder or .npz",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=HelpFormatter,
    )
    parser.add_argument("path", help="input light-field folder or file")
    parser.add_argument("out", help="output: a name ending in .npz, or a new scene folder")
    parser.add_argument(
        "--format-in",
        choices=FORMATS,
        default=None,
        help="read the input as this format instead of detecting it",
    )
    add_value_range(parser)
    parser.set_defaults(func=run)
