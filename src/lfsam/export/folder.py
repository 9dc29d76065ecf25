"""Writing an export folder atomically: a temporary folder next to it, then a rename.

An export that fails or is interrupted leaves nothing behind: no partial folder and, with
``force``, the previous folder untouched (docs/design.md section 8).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

from lfsam.errors import LfsamError
from lfsam.fileutil import atomic_folder_output

__all__ = ["atomic_folder", "check_export_target"]


def check_export_target(path: str | os.PathLike, force: bool = False) -> Path:
    """Check that an export folder may be written at ``path``.

    Parameters
    ----------
    path : path-like
        The folder to create (or replace).
    force : bool
        Allow replacing a non-empty folder.

    Returns
    -------
    Path

    Raises
    ------
    LfsamError
        If the parent folder is missing, ``path`` is a file, or ``path`` is a non-empty folder
        and ``force`` is False.
    """
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise LfsamError(
            f"output folder {str(parent)!r} does not exist; create it (mkdir -p {parent}) "
            "or choose another --out"
        )
    if path.exists() and not path.is_dir():
        raise LfsamError(f"output {str(path)!r} is a file; give a folder name for --out")
    if path.is_dir() and any(path.iterdir()) and not force:
        raise LfsamError(
            f"output folder {str(path)!r} is not empty; pass --force to replace it "
            "or choose another --out"
        )
    return path


@contextlib.contextmanager
def atomic_folder(path: str | os.PathLike, force: bool = False) -> Iterator[Path]:
    """Yield a temporary folder next to ``path``; rename it onto ``path`` only on success.

    An existing ``path`` (empty, or any folder with ``force``) is moved aside and deleted only
    once the new folder is in place (:func:`lfsam.fileutil.atomic_folder_output`).

    Raises
    ------
    LfsamError
        See :func:`check_export_target`.
    """
    path = check_export_target(path, force)
    with atomic_folder_output(path) as tmp:
        yield tmp
