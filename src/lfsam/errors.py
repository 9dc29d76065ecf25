"""Errors that are the user's to fix.

Every error raised for bad input (a wrong path, a wrong shape, a missing checkpoint, an offline
download) is an :class:`LfsamError` whose message is one line that names the problem and the fix.
The command-line interface prints such errors as ``lfsam: error: <message>`` without a traceback
and exits with status 2; anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

__all__ = ["LfsamError"]


class LfsamError(Exception):
    """An error caused by the user's input or environment, with a one-line actionable message."""

    def __init__(self, message: str) -> None:
        super().__init__(" ".join(str(message).split()))
