"""Writing output files atomically: a temporary file in the same folder, then a rename.

A run that fails or is interrupted leaves no partial or corrupt output file behind.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from lfsam.errors import LfsamError

__all__ = ["atomic_output", "check_output_path"]


def check_output_path(path: str | os.PathLike) -> Path:
    """Check that ``path`` can be written: its folder exists and it is not a folder itself.

    Raises
    ------
    LfsamError
        If the parent folder is missing or ``path`` is a directory.
    """
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise LfsamError(
            f"output folder {str(parent)!r} does not exist; create it (mkdir -p {parent}) "
            "or choose another --out"
        )
    if path.is_dir():
        raise LfsamError(f"output {str(path)!r} is a folder; give a file name")
    return path


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` only on success.

    The temporary name keeps ``path``'s suffix so writers that choose a format from it (NumPy,
    imageio, matplotlib) behave as for the final name.

    Examples
    --------
    >>> with atomic_output("result.npz") as tmp:  # doctest: +SKIP
    ...     np.savez(tmp, labels=labels)
    """
    path = check_output_path(path)
    fd, tmp_name = tempfile.mkstemp(
        prefix=f".{path.stem}.", suffix=f".part{path.suffix}", dir=path.parent or "."
    )
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        # mkstemp creates 0600; give the result the permissions a plain open() would.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise
