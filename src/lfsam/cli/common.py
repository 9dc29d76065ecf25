"""Helpers shared by subcommands: argument types and formatter."""

from __future__ import annotations

import argparse

__all__ = ["HelpFormatter", "parse_floats", "parse_pair"]


class HelpFormatter(argparse.RawDescriptionHelpFormatter, argparse.ArgumentDefaultsHelpFormatter):
    """Keeps the description's line breaks and shows defaults."""


def parse_pair(text: str, sep: str = "x", kind: type = int) -> tuple:
    """Parse ``"9x9"`` or ``"240x320"`` (or ``"a,b"`` with ``sep=","``) into a pair."""
    parts = text.lower().split(sep)
    try:
        if len(parts) != 2:
            raise ValueError
        return kind(parts[0]), kind(parts[1])
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected two numbers as A{sep}B, got {text!r}"
        ) from None


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
