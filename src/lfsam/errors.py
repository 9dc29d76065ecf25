"""Errors that are the user's to fix, and the rule for every other exception in the package.

The rule:

- Everything a user can cause with their input or environment (a wrong path, a wrong shape, a
  missing checkpoint, an offline download, an unknown option value or device, prompts that do
  not fit, a disparity of the wrong size) raises :class:`LfsamError`, whose message is one line
  that names the problem and the fix. That holds for the Python API as much as for the CLI.
- ``ValueError`` / ``TypeError`` are raised only where the calling *code* is at fault (an
  argument no user input can produce, e.g. an axis other than -1/-2, or a drawing primitive of
  :mod:`lfsam.viz` given an image of another size than its labels, which ``lfsam show`` checks
  first). Each such place says so in the Raises section of its docstring.
- :class:`FrameError` (an :class:`LfsamError`) is one frame's fault in a stream of frames (a
  frame that cannot be read, or of another grid or view size than the first): a followed stream
  skips that frame and goes on (docs/design.md section 10). Any other :class:`LfsamError` while
  a stream is segmented is the configuration's (a model the frames cannot serve, prompts that do
  not fit): it would fail every frame, so the stream stops at the first.
- Anything else is a bug.

The command-line interface prints :class:`LfsamError` as ``lfsam: error: <message>`` without a
traceback and exits with status 2; any other exception keeps its traceback.
"""

from __future__ import annotations

__all__ = ["FrameError", "LfsamError"]


class LfsamError(Exception):
    """An error caused by the user's input or environment, with a one-line actionable message."""

    def __init__(self, message: str) -> None:
        super().__init__(" ".join(str(message).split()))


class FrameError(LfsamError):
    """One frame of a stream is at fault (unreadable, damaged, another grid or view size); the
    frames after it may be fine."""
