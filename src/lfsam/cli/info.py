"""``lfsam info``: what a light field holds and how it was read."""

from __future__ import annotations

import argparse
import json
from typing import Any

from lfsam.cli.common import HelpFormatter, add_value_range
from lfsam.cli.inputs import expect_input
from lfsam.io import FORMATS, read_lightfield
from lfsam.lightfield import LightField
from lfsam.video import is_video, read_video

__all__ = ["register", "run", "summarize"]

DESCRIPTION = """\
Show what a light field holds: the view grid and size, the center (reference) view, which ground
truth is present (disparity, labels; for every view or the center only), the disparity range,
the number of labels, the format that was detected, and how the reader oriented the data.
For a light-field video (a folder of frames, of view_SS_TT.mp4 files, or an [F, S, T, U, V, 3]
array), one line such as "6 frames of 5 x 5 views of 96 x 128" and its ground truth.

Every reader converts its data set to lfsam's one convention (a point at pixel (u, v) of view
(s, t) with disparity d is at (u - d (s' - s), v - d (t' - t)) in view (s', t'); larger = closer).
For UrbanLF and old-HCI scenes, the orientation line says what the reader flipped or negated to
get there, and the check line gives the evidence (photo-consistency residuals, occlusion order).
"""

EPILOG = """\
examples:
  lfsam info ../shared/data/hci_antinous
  lfsam info scene --json
  lfsam info views/ --format grid
"""


def summarize(lf: LightField) -> dict[str, Any]:
    """A JSON-ready description of a light field: :meth:`LightField.describe` plus the reader's
    orientation notes."""
    summary = lf.describe()
    for key in ("orientation", "orientation_check", "label_offset", "converted_from"):
        if key in lf.meta and key not in summary:
            summary[key] = lf.meta[key]
    return summary


def _plain(value: Any) -> str:
    """A value of the text summary: strings as they are, a list of strings joined by commas,
    anything else as JSON with absent entries as ``none`` (the text never says ``null``)."""
    if isinstance(value, str):
        return value
    if isinstance(value, list) and all(isinstance(v, str) for v in value):
        return ", ".join(value) if value else "none"

    def no_null(item: Any) -> Any:
        if isinstance(item, dict):
            return {k: no_null(v) for k, v in item.items()}
        if isinstance(item, list):
            return [no_null(v) for v in item]
        return "none" if item is None else item

    return json.dumps(no_null(value))


def _text(summary: dict[str, Any]) -> str:
    s_count, t_count = summary["grid"]
    rows, cols = summary["view_size"]
    lines = [
        ("source", summary.get("source", "?")),
        ("format", summary.get("format", "?")),
        (
            "grid",
            f"{s_count} x {t_count} grid, {summary.get('views_present', s_count * t_count)} of "
            f"{s_count * t_count} views present, center view {tuple(summary['center'])}",
        ),
        ("view size", f"{rows} x {cols} pixels (rows x columns)"),
    ]
    if summary["disparity"] is None:
        lines.append(("disparity", "none"))
    else:
        low, high = summary["disparity_range"]
        lines.append(
            ("disparity", f"{summary['disparity']}, {low:.3f} .. {high:.3f} px per view step")
        )
    if summary["labels"] is None:
        lines.append(("labels", "none"))
    else:
        offset = f" (file labels + {summary['label_offset']})" if "label_offset" in summary else ""
        lines.append(("labels", f"{summary['labels']}, {summary['num_labels']} labels{offset}"))
    shown = {
        "source",
        "format",
        "grid",
        "view_size",
        "center",
        "disparity",
        "disparity_range",
        "labels",
        "num_labels",
        "label_offset",
        "views_present",
    }
    for key, value in summary.items():
        if key not in shown and value is not None:  # absent: no row (JSON keeps its null)
            lines.append((key.replace("_", " "), _plain(value)))
    width = max(len(name) for name, _ in lines)
    return "\n".join(f"{name:<{width}}  {value}" for name, value in lines)


def _video_text(summary: dict[str, Any]) -> str:
    lines = [("source", summary["source"]), ("format", summary["format"]),
             ("video", summary["summary"]),
             ("center", f"view {tuple(summary['center'])} of every frame"),
             ("disparity", summary["disparity"] or "none"), ("labels", summary["labels"] or "none")]
    width = max(len(name) for name, _ in lines)
    return "\n".join(f"{name:<{width}}  {value}" for name, value in lines)


def run(args: argparse.Namespace) -> int:
    """Print the summary of ``args.path`` (a light field or a light-field video)."""
    expect_input(args.path, "info", ("lightfield", "video"),
                 hint="draw a result with `lfsam show` instead")
    if args.format is None and is_video(args.path):
        with read_video(args.path, value_range=args.value_range) as video:
            summary = video.describe()
        print(json.dumps(summary, indent=2) if args.json else _video_text(summary))
        return 0
    lf = read_lightfield(args.path, args.format, value_range=args.value_range)
    summary = summarize(lf)
    print(json.dumps(summary, indent=2) if args.json else _text(summary))
    return 0


def register(subparsers) -> None:
    """Add the ``info`` subcommand."""
    parser = subparsers.add_parser(
        "info",
        help="show what a light field holds (grid, size, ground truth, orientation)",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=HelpFormatter,
    )
    parser.add_argument("path", help="light-field (or light-field video) folder or file")
    parser.add_argument(
        "--format",
        choices=FORMATS,
        default=None,
        help="read as this format instead of detecting it from the path",
    )
    parser.add_argument("--json", action="store_true", help="print JSON instead of text")
    add_value_range(parser)
    parser.set_defaults(func=run)
