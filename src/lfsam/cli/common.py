"""Helpers shared by subcommands: argument types, the ``--device`` option and the formatter.

Every command that computes on a device takes ``--device`` from :func:`add_device_argument` (the
vocabulary of :mod:`lfsam.devices`); :func:`lfsam.cli.main.main` checks it before the command
runs, so a wrong or unavailable device is one line on stderr and exit status 2 before any input
is read.
"""

from __future__ import annotations

import argparse
import math

from lfsam.devices import DEVICE_HELP

__all__ = [
    "TRACKING_MODES",
    "HelpFormatter",
    "add_device_argument",
    "add_refine_views_argument",
    "add_tracking_argument",
    "add_value_range",
    "bounded_int",
    "parse_floats",
    "parse_pair",
    "probability",
    "refine_views",
    "unit_interval",
]


class HelpFormatter(argparse.RawDescriptionHelpFormatter, argparse.ArgumentDefaultsHelpFormatter):
    """Keeps the description's line breaks and shows defaults (not a bare "None": an option
    without a default says in its help what happens when it is left out)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.default is None:
            return action.help
        return super()._get_help_string(action)


def parse_pair(text: str, sep: str = "x", kind: type = int) -> tuple:
    """Parse ``"9x9"`` or ``"240x320"`` (or ``"a,b"`` with ``sep=","``) into a pair."""
    parts = text.lower().split(sep)
    try:
        pair = tuple(kind(part) for part in parts)
    except ValueError:
        pair = ()
    if len(pair) != 2:
        raise argparse.ArgumentTypeError(f"expected two numbers as A{sep}B, got {text!r}")
    return pair


def parse_floats(text: str, count: int) -> tuple[float, ...]:
    """Parse ``count`` comma-separated finite floats, e.g. ``"10,20"`` for a point."""
    try:
        values = tuple(float(x) for x in text.split(","))
    except ValueError:
        values = ()
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(
            f"expected {count} comma-separated numbers, got {text!r}"
        )
    return values


def unit_interval(text: str, what: str = "a number") -> float:
    """Parse a number in [0, 1] (a threshold such as ``--t-sim``); ``what`` names it in the
    error ("expected a number in [0, 1], got '2'")."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0.0 <= value <= 1.0:  # also rejects NaN
        raise argparse.ArgumentTypeError(f"expected {what} in [0, 1], got {text!r}")
    return value


def positive_float(text: str) -> float:
    """Parse a finite number > 0 (seconds such as ``--follow-timeout``)."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}")
    return value


def probability(text: str) -> float:
    """Parse a probability, a number in [0, 1] (``--oracle-merge``)."""
    return unit_interval(text, "a probability")


def add_value_range(parser: argparse.ArgumentParser) -> None:
    """Add ``--value-range 1|255``: how floating-point views are scaled (LightField docstring)."""
    parser.add_argument(
        "--value-range",
        type=int,
        choices=(1, 255),
        default=None,
        help="floating-point views are [0, 1] (1) or [0, 255] (255); default: [0, 1] when the "
        "99.9th percentile of the values is <= 2",
    )


def bounded_int(low: int, high: int | None = None):
    """An argparse type: an integer in ``[low, high]`` (no upper bound when ``high`` is None)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < low or (high is not None and value > high):
            bounds = f"in [{low}, {high}]" if high is not None else f">= {low}"
            raise argparse.ArgumentTypeError(f"expected an integer {bounds}, got {text!r}")
        return value

    parse.__name__ = "integer"
    return parse


def add_disparity_argument(
    parser: argparse.ArgumentParser | argparse._ArgumentGroup, *, files: bool = True
) -> None:
    """Add ``--disparity`` (default ``estimate``): where each reference view's disparity comes
    from, the one disparity option of ``segment``, ``view`` and ``evaluate``.

    The value goes unchanged to :func:`lfsam.disparity.resolve_disparity` (through
    :class:`lfsam.disparity.views.ViewDisparities`), which checks it. ``files=False`` (a data
    set of many light fields) allows only ``estimate`` and ``gt``.
    """
    if files:
        parser.add_argument(
            "--disparity", default="estimate", metavar="estimate|gt|FILE.npy",
            help="disparity: estimated from the views (occlusion-aware cost volume, as "
            "`lfsam disparity`), the scene's ground "
            "truth, or a center-view (U, V) or every-view (S, T, U, V) .npy in lfsam's "
            "convention; the disparity of a view other than the center is derived from it",
        )
    else:
        parser.add_argument(
            "--disparity", choices=["estimate", "gt"], default="estimate",
            help="disparity: estimated from each light field's views, or its ground truth",
        )


def add_device_argument(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """Add ``--device`` (default ``auto``): the one device option of every command.

    The value stays a string (resolved where it is used); :func:`lfsam.cli.main.main` checks it
    with :func:`lfsam.devices.resolve_device` first (one-line error for a wrong or unavailable
    device).
    """
    parser.add_argument("--device", default="auto", metavar="DEVICE", help=DEVICE_HELP)


def refine_views(text: str) -> str | int:
    """Parse ``--refine-views``: ``all``, ``sparse`` or a number of views N >= 1."""
    from lfsam.errors import LfsamError
    from lfsam.pipeline.sparse import check_refine_views

    try:
        return check_refine_views(text)
    except LfsamError:
        raise argparse.ArgumentTypeError(
            f"expected all, sparse or a number of views N >= 1, got {text!r}"
        ) from None


def add_refine_views_argument(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """``--refine-views all|sparse|N`` (docs/design.md section 3.7)."""
    parser.add_argument(
        "--refine-views", type=refine_views, default="all", metavar="all|sparse|N",
        help="views encoded and refined with SAM 2: all (the paper), sparse (about one in six: "
        "13 of 9x9, 9 of 5x5, spread over the grid; about 5x faster) or N views; the other "
        "views take the masks of the refined views nearest to them, moved by disparity",
    )


def add_consensus_argument(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """``--consensus`` (docs/design.md section 3.9): the multi-view vote after refinement."""
    parser.add_argument(
        "--consensus", action="store_true",
        help="multi-view consensus: after refinement, each view's mask of each object is voted "
        "with the refined masks of the nearest views, carried by disparity (a segmenter's "
        "error in one view is outvoted; result meta consensus_replaced counts the masks it "
        "replaced); about 2x the work of a sparse fill. Recommended for videos tracked "
        "with a segmenter whose answers are not exact (fewer objects lost; docs/design.md "
        "3.9)",
    )


#: ``--tracking`` values and the ``memory`` argument of
#: :func:`lfsam.video.tracking.track.track_video`.
TRACKING_MODES = {"auto": None, "memory": True, "prompts": False}


def add_tracking_argument(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """``--tracking auto|memory|prompts`` for light-field videos (docs/design.md section 10)."""
    parser.add_argument(
        "--tracking", choices=list(TRACKING_MODES), default="auto",
        help="light-field videos: how each object's reference mask moves to the next frame: "
        "memory (SAM 2's video memory over the center views), prompts (constrained prompts "
        "carried from the previous frame; any model) or auto (memory for SAM 2, prompts for "
        "the others)",
    )
