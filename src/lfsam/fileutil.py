"""Writing outputs atomically, and checking where they go.

A file (:func:`atomic_output`) or a folder (:func:`atomic_folder_output`) is written under a
temporary name in the same folder and renamed onto its final name only when complete, so a run
that fails or is interrupted leaves no partial or corrupt output behind (and a folder it
replaces stays as it was). :func:`check_output_path` and :func:`check_cache_dir` check an output
file's folder and a cache folder before any work.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

from lfsam.errors import LfsamError

__all__ = [
    "atomic_folder_output",
    "atomic_output",
    "check_cache_dir",
    "check_output_path",
    "replace_folder",
]


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


def check_cache_dir(path: str | os.PathLike) -> Path:
    """Create the cache folder ``path`` (and its parents) if it is missing, or fail in one line.

    Commands that take ``--cache`` call it before any work, so a folder that cannot be made is
    an :class:`~lfsam.errors.LfsamError` naming it, not a traceback after the light field was
    read. A folder that exists is taken as it is (a read-only cache can still be read; entries
    that cannot be written are warnings of :class:`lfsam.embeddings.EmbeddingStore`).

    Parameters
    ----------
    path : path-like
        The cache folder.

    Returns
    -------
    Path

    Raises
    ------
    LfsamError
        If ``path`` is a file, or the folder cannot be created (a parent is a file, no
        permission, a read-only or virtual file system).

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     check_cache_dir(Path(tmp) / "cache" / "sam2").is_dir()
    True
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise LfsamError(f"cache folder {str(path)!r} is a file; give a folder with --cache")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise LfsamError(
            f"cannot create the cache folder {str(path)!r} ({reason}); give a folder you can "
            "create or write to with --cache, or leave --cache out"
        ) from None
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


@contextlib.contextmanager
def atomic_folder_output(path: str | os.PathLike, mode: int | None = None) -> Iterator[Path]:
    """Yield a temporary folder next to ``path``; rename it onto ``path`` only on success.

    An existing ``path`` is moved aside and deleted only once the new folder is in place
    (:func:`replace_folder`); on any error the temporary folder is deleted and ``path`` is left
    as it was. The caller checks first that ``path`` may be replaced.

    Parameters
    ----------
    path : path-like
        The folder to create or replace.
    mode : int, optional
        Permissions of the finished folder; default those ``mkdir`` would give (``0o777`` less
        the umask).

    Examples
    --------
    >>> with atomic_folder_output("export") as tmp:  # doctest: +SKIP
    ...     (tmp / "labels.json").write_text("{}")
    """
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".part", dir=parent))
    try:
        yield tmp
        if mode is None:
            umask = os.umask(0)
            os.umask(umask)
            mode = 0o777 & ~umask
        os.chmod(tmp, mode)
        replace_folder(tmp, path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def replace_folder(new: Path, target: Path) -> None:
    """Rename the folder ``new`` onto ``target``, moving an existing ``target`` aside first (it
    is put back if the rename fails, and deleted after it succeeds)."""
    if not target.exists():
        os.replace(new, target)
        return
    old = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".old", dir=target.parent))
    os.rmdir(old)
    os.replace(target, old)
    try:
        os.replace(new, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.replace(old, target)
        raise
    shutil.rmtree(old, ignore_errors=True)
