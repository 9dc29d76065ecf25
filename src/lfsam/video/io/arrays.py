"""Light-field videos stored as one array ``[F, S, T, U, V, 3]`` (docs/design.md section 10).

``.npy`` (memory-mapped), ``.npz`` (each member read frame by frame: stored members are
memory-mapped at their offset in the archive, compressed ones are decompressed as a stream up
to the frame asked for, so reading frames in order costs one pass) and ``.h5`` (an h5py
dataset, sliced per frame). Optional ``disparity`` and ``labels`` are ``[F, S, T, U, V]``.
Only the frame asked for is ever in memory.
"""

from __future__ import annotations

import os
import struct
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from lfsam.errors import LfsamError
from lfsam.io.arrays import DISPARITY_KEYS, LABEL_KEYS, VIEW_KEYS
from lfsam.lightfield import LightField

__all__ = ["ArrayFrames", "array_video_shape", "npz_shapes", "open_h5", "open_npy", "open_npz"]


class ArrayFrames:
    """Frames from ``[F, S, T, U, V, 3]`` array-likes indexable by frame (ndarray, memmap,
    h5py dataset, :class:`ZipMember`).

    Raises
    ------
    LfsamError
        If the views are not 6-D with 3 channels, or ``disparity``/``labels`` are not
        ``[F, S, T, U, V]`` of the same sizes.
    """

    def __init__(self, views: Any, disparity: Any = None, labels: Any = None,
                 where: str = "the video array", closer: Any = None) -> None:
        shape = tuple(int(x) for x in views.shape)
        if len(shape) != 6 or shape[-1] != 3:
            raise LfsamError(
                f"{where} has shape {shape}; a light-field video array is [F, S, T, U, V, 3] "
                "(frames, view rows, view columns, pixel rows, pixel columns, RGB)"
            )
        for name, array in (("disparity", disparity), ("labels", labels)):
            if array is not None and tuple(array.shape) != shape[:5]:
                raise LfsamError(
                    f"{name} in {where} has shape {tuple(array.shape)}, expected "
                    f"{shape[:5]} ([F, S, T, U, V], one per view of every frame)"
                )
        self.views, self.disparity, self.labels = views, disparity, labels
        self.num_frames = shape[0]
        self.grid_shape = shape[1:3]
        self.view_shape = shape[3:5]
        self.has_disparity = disparity is not None
        self.has_labels = labels is not None
        self.where = where
        self._closer = closer

    def read(self, index: int) -> LightField:
        """Frame ``index``: only its bytes are read."""
        disparity = None if self.disparity is None else np.asarray(self.disparity[index])
        labels = None if self.labels is None else np.asarray(self.labels[index])
        return LightField(
            np.array(self.views[index]),
            disparity=None if disparity is None else disparity.astype(np.float32),
            labels=None if labels is None else labels.astype(np.int32),
            meta={"source": self.where},
        )

    def close(self) -> None:
        """Close the file behind the arrays, if any."""
        if self._closer is not None:
            self._closer.close()
            self._closer = None


def _read_header(handle: Any) -> tuple[tuple[int, ...], bool, np.dtype]:
    """``(shape, fortran_order, dtype)`` of the ``.npy`` at ``handle``'s position."""
    version = np.lib.format.read_magic(handle)
    if version == (1, 0):
        return np.lib.format.read_array_header_1_0(handle)
    return np.lib.format.read_array_header_2_0(handle)


def npz_shapes(path: str | os.PathLike) -> dict[str, tuple[int, ...]]:
    """The shape of every array of an ``.npz``, from the members' headers (nothing loaded).

    Raises
    ------
    OSError, ValueError, EOFError, zipfile.BadZipFile
        Not a readable ``.npz`` (callers that only probe catch them).
    """
    with zipfile.ZipFile(path) as archive:
        shapes = {}
        for name in archive.namelist():
            if name.endswith(".npy"):
                with archive.open(name) as handle:
                    shapes[name[:-4]] = tuple(_read_header(handle)[0])
    return shapes


class ZipMember:
    """One ``.npy`` member of an ``.npz``, indexable by its first axis without loading it."""

    def __init__(self, archive: zipfile.ZipFile, name: str, path: Path) -> None:
        self.archive, self.name, self.path = archive, name, path
        info = archive.getinfo(name)
        with archive.open(name) as handle:
            shape, fortran, dtype = _read_header(handle)
            self.data_offset = handle.tell()
        if fortran or dtype.hasobject:
            raise LfsamError(
                f"{name} in {path} is stored in Fortran order or as objects; save it C-ordered "
                "with numpy.savez"
            )
        self.shape, self.dtype = tuple(shape), dtype
        self.ndim = len(self.shape)
        self.row_bytes = int(np.prod(self.shape[1:], dtype=np.int64)) * dtype.itemsize
        self._mmap = None
        if info.compress_type == zipfile.ZIP_STORED:
            with open(path, "rb") as raw:
                raw.seek(info.header_offset)
                header = raw.read(30)
            name_len, extra_len = struct.unpack("<HH", header[26:30])
            start = info.header_offset + 30 + name_len + extra_len + self.data_offset
            self._mmap = np.memmap(path, dtype=dtype, mode="r", offset=start, shape=self.shape)
        self._stream = None

    def __getitem__(self, index: int) -> np.ndarray:
        if self._mmap is not None:
            return self._mmap[index]
        start = self.data_offset + int(index) * self.row_bytes
        if self._stream is None or self._stream.tell() > start:
            if self._stream is not None:
                self._stream.close()
            self._stream = self.archive.open(self.name)
        self._stream.seek(start)  # forward: decompresses only what lies between
        data = self._stream.read(self.row_bytes)
        return np.frombuffer(data, dtype=self.dtype).reshape(self.shape[1:])

    def close(self) -> None:
        if self._stream is not None:
            self._stream.close()
            self._stream = None
        self._mmap = None


class _Closer:
    def __init__(self, *things: Any) -> None:
        self.things = things

    def close(self) -> None:
        for thing in self.things:
            thing.close()


def _pick_key(names: list[str], shapes: dict[str, tuple], path: Path) -> str:
    for key in VIEW_KEYS:
        if key in names:
            return key
    six = [n for n in names if len(shapes[n]) == 6 and n not in (*DISPARITY_KEYS, *LABEL_KEYS)]
    if len(six) == 1:
        return six[0]
    raise LfsamError(
        f"no light-field video array in {path} (found "
        f"{', '.join(f'{n} {shapes[n]}' for n in names) or 'nothing'}); store the views as "
        "'views' with shape [F, S, T, U, V, 3]"
    )


def _first(names: list[str], keys: tuple[str, ...]) -> str | None:
    return next((k for k in keys if k in names), None)


def _named_frames(arrays: dict[str, Any], path: Path, closer: Any) -> ArrayFrames:
    """:class:`ArrayFrames` of named arrays (``.npz`` members, HDF5 datasets): the views array
    (:func:`_pick_key`) and the optional disparity and labels."""
    names = list(arrays)
    key = _pick_key(names, {n: a.shape for n, a in arrays.items()}, path)
    disparity = _first(names, DISPARITY_KEYS)
    labels = _first(names, LABEL_KEYS)
    return ArrayFrames(
        arrays[key],
        None if disparity is None else arrays[disparity],
        None if labels is None else arrays[labels],
        where=str(path),
        closer=closer,
    )


def open_npy(path: str | os.PathLike) -> ArrayFrames:
    """A memory-mapped ``.npy`` of views ``[F, S, T, U, V, 3]``."""
    path = Path(path)
    try:
        views = np.load(path, mmap_mode="r", allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise LfsamError(f"cannot read {str(path)!r} as .npy: {exc}") from None
    return ArrayFrames(views, where=str(path))


def open_npz(path: str | os.PathLike) -> ArrayFrames:
    """An ``.npz`` with ``views`` ``[F, S, T, U, V, 3]`` and optional ``disparity``,
    ``labels`` ``[F, S, T, U, V]``, read frame by frame."""
    path = Path(path)
    try:
        archive = zipfile.ZipFile(path)
        members = {n[:-4]: ZipMember(archive, n, path) for n in archive.namelist()
                   if n.endswith(".npy")}
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise LfsamError(f"cannot read {str(path)!r} as .npz: {exc}") from None
    return _named_frames(members, path, _Closer(*members.values(), archive))


def open_h5(path: str | os.PathLike) -> ArrayFrames:
    """An HDF5 file with a 6-D views dataset (and optional ``disparity``, ``labels``), sliced
    per frame; the file stays open until :meth:`ArrayFrames.close`."""
    import h5py

    path = Path(path)
    try:
        handle = h5py.File(path, "r")
    except OSError as exc:
        raise LfsamError(f"cannot read {str(path)!r} as HDF5: {exc}") from None
    datasets = {k: v for k, v in handle.items() if isinstance(v, h5py.Dataset)}
    try:
        return _named_frames(datasets, path, handle)
    except BaseException:
        handle.close()
        raise


def array_video_shape(path: str | os.PathLike) -> tuple[int, ...] | None:
    """The shape of the views array in an ``.npy``/``.npz``/``.h5`` when it is 6-D (a video),
    else None (a single light field, or not an array file); cheap: headers only."""
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        if suffix == ".npy":
            shape = tuple(np.load(path, mmap_mode="r", allow_pickle=False).shape)
        elif suffix == ".npz":
            with zipfile.ZipFile(path) as archive:
                shapes = {n[:-4]: ZipMember(archive, n, path).shape
                          for n in archive.namelist() if n.endswith(".npy")}
            shape = shapes[_pick_key(list(shapes), shapes, path)]
        elif suffix in (".h5", ".hdf5"):
            import h5py

            with h5py.File(path, "r") as handle:
                shapes = {k: v.shape for k, v in handle.items() if isinstance(v, h5py.Dataset)}
            shape = tuple(shapes[_pick_key(list(shapes), shapes, path)])
        else:
            return None
    except (LfsamError, OSError, ValueError, KeyError, zipfile.BadZipFile):
        return None
    return shape if len(shape) == 6 else None
