"""Writing outputs atomically, and checking where they go.

A file (:func:`atomic_output`) or a folder (:func:`atomic_folder_output`) is written under a
temporary name in the same folder and renamed onto its final name only when complete, so a run
that fails or is interrupted leaves no partial or corrupt output behind (and a folder it
replaces stays as it was). :func:`check_output_path` and :func:`check_cache_dir` check an output
file's folder and a cache folder before any work; :func:`check_writable`, which every command
calls for each of its outputs before it reads an input or loads a model, proves the output can
be written by creating and removing a file where it will be written (docs/design.md section 2,
"Outputs and inputs on the command line").
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
    "check_writable",
    "replace_folder",
    "write_text_atomic",
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


def _nearest_existing(path: Path) -> Path:
    """``path`` or its nearest ancestor that exists (``.`` for a relative path with none)."""
    for candidate in (path, *path.parents):
        try:
            if candidate.exists():
                return candidate
        except OSError:  # not searchable: the probe below names the reason
            return candidate
    return Path(".")


def check_writable(
    path: str | os.PathLike, *, folder: bool, option: str, inside: bool = False
) -> Path:
    """Check that the output ``path`` can be written, before any work, or fail in one line.

    A file is created and removed where the output will be written (docs/design.md section
    2, "Outputs and inputs on the command line"): for a file, or for a folder written next to
    its final name and renamed onto it (the atomic writes of this module), in its parent
    folder, which must exist; for a folder the command creates with its parents and writes
    into (``inside``), in the folder itself when it exists, else in its nearest existing
    ancestor. So an unwritable place (a read-only mount, another user's folder, ``/proc``)
    stops a command before it reads its input or loads a model, not after the work.

    Parameters
    ----------
    path : path-like
        The output file or folder.
    folder : bool
        Whether the output is a folder (then ``path`` must not be an existing file) or a file
        (then ``path`` must not be an existing folder).
    option : str
        How the user named the output, for the message: ``"--out"``, ``"OUT"``, ...
    inside : bool
        A folder output the command creates (parents included) and writes its files into.

    Returns
    -------
    Path

    Raises
    ------
    LfsamError
        Naming ``option``, ``path`` and the reason: a file where a folder belongs or the other
        way round, a missing parent folder, or the operating system's refusal to create a file
        there (``[Errno 13] Permission denied``, ``[Errno 30] Read-only file system``, ...).

    Examples
    --------
    >>> import tempfile
    >>> tmp = Path(tempfile.mkdtemp())
    >>> check_writable(tmp / "result.npz", folder=False, option="--out").name
    'result.npz'
    >>> _ = (tmp / "notes.txt").write_text("a file")
    >>> check_writable(tmp / "notes.txt" / "r.npz", folder=False, option="--out")
    Traceback (most recent call last):
    ...
    lfsam.errors.LfsamError: cannot write --out .../notes.txt/r.npz: ... is a file, not a folder...
    >>> shutil.rmtree(tmp)
    """
    path = Path(path)
    fix = f"choose another {option}"
    if folder and path.exists() and not path.is_dir():
        raise LfsamError(f"{option} {path} is a file, but a folder is written there; {fix}")
    if not folder and path.is_dir():
        raise LfsamError(f"{option} {path} is a folder; give a file name for {option}")
    target = path if inside else (path.parent if str(path.parent) else Path("."))
    where = _nearest_existing(target)
    if not where.is_dir():
        raise LfsamError(f"cannot write {option} {path}: {where} is a file, not a folder; {fix}")
    try:
        handle, probe = tempfile.mkstemp(prefix=".lfsam-write-check.", dir=where)
        os.close(handle)
        os.unlink(probe)
    except OSError as exc:
        reason = f"[Errno {exc.errno}] {exc.strerror}" if exc.strerror else type(exc).__name__
        raise LfsamError(
            f"cannot write {option} {path}: {reason} (creating a file in {str(where)!r}); "
            "choose a folder you can write to"
        ) from None
    if where != target and not inside:
        raise LfsamError(
            f"the folder {str(target)!r} of {option} {path} does not exist; create it "
            f"(mkdir -p {target}) or {fix}"
        )
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


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through :func:`atomic_output`: the file is complete
    or absent, never partial (docs/design.md section 8); returns the path."""
    with atomic_output(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


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
