"""Turning any failure of a third-party decoder on a damaged file into a one-line user error.

NumPy, zipfile/zlib, h5py, SciPy and Pillow raise a wide range of exceptions on truncated or
corrupted files (``zlib.error``, ``EOFError``, ``KeyError``, ``struct.error``, ``OSError``, ...).
Only the library calls that parse a file's bytes run inside :func:`decoding`; lfsam's own checks
stay outside, so a bug in lfsam still shows its traceback.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

from lfsam.errors import LfsamError

__all__ = ["decoding"]

_MAX_DETAIL = 160


@contextlib.contextmanager
def decoding(
    path: str | os.PathLike, what: str, fix: str = "check or replace the file"
) -> Iterator[None]:
    """Run a decoder on ``path``; any exception becomes ``LfsamError("cannot read ...")``.

    Parameters
    ----------
    path : path-like
        The file being decoded (for the message).
    what : str
        What it was read as, e.g. ``".npz"`` or ``"an image"``.
    fix : str
        The advice at the end of the message.

    Raises
    ------
    LfsamError
        For any exception raised inside the block (an LfsamError passes unchanged).
    """
    try:
        yield
    except LfsamError:
        raise
    except Exception as exc:  # any decoder failure on damaged bytes
        detail = " ".join(str(exc).split())
        if len(detail) > _MAX_DETAIL:
            detail = detail[:_MAX_DETAIL] + "..."
        raise LfsamError(
            f"cannot read {str(path)!r} as {what} ({type(exc).__name__}: {detail}); {fix}"
        ) from None
