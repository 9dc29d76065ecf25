"""Helpers shared by subcommands: argument types, the ``--device`` option and the formatter.

Every command that computes on a device takes ``--device`` from :func:`add_device_argument` (the
vocabulary of :mod:`lfsam.devices`); :func:`lfsam.cli.main.main` checks it before the command
runs, so a wrong or unavailable device is one line on stderr and exit status 2 before any input
is read.
"""

from __future__ import annotations

import argparse

from lfsam.devices import DEVICE_HELP

__all__ = ["HelpFormatter", "add_device_argument", "parse_floats", "parse_pair"]


class HelpFormatter(argparse.RawDescriptionHelpFormatter, argparse.ArgumentDefaultsHelpFormatter):
    """Keeps the description's line breaks and shows defaults."""


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
    """Parse ``count`` comma-separated floats, e.g. ``"10,20"`` for a point."""
    try:
        values = tuple(float(x) for x in text.split(","))
    except ValueError:
        values = ()
    if len(values) != count:
        raise argparse.ArgumentTypeError(
            f"expected {count} comma-separated numbers, got {text!r}"
        )
    return values


def add_device_argument(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """Add ``--device`` (default ``auto``): the one device option of every command.

    The value stays a string (resolved where it is used); :func:`lfsam.cli.main.main` checks it
    with :func:`lfsam.devices.resolve_device` first (one-line error for a wrong or unavailable
    device).
    """
    parser.add_argument("--device", default="auto", metavar="DEVICE", help=DEVICE_HELP)
