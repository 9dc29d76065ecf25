"""Light fields stored as arrays: ``.npz``, ``.npy``, HDF5 (``.h5``) and MATLAB (``.mat``).

The views must be one 5-D array ``[S, T, U, V, 3]`` (view row, view column, pixel row, pixel
column, RGB), uint8, or float in [0, 1] or [0, 255] (the rule: :func:`lfsam.lightfield.float_scale`;
``value_range`` says which). Files with several arrays are searched by the usual key names
(``views``, ``LF``, ``lf``, ``lightfield``, ``data``, ...), otherwise by the only 5-D array they
hold. ``.npz`` files may also hold ``disparity`` and ``labels`` ([S, T, U, V] or center
[U, V]), a JSON ``categories`` string (label id -> name, docs/design.md section 9) and a JSON
``meta`` string: that is the package's exchange format, written by
:func:`write_npz`, and its disparity is in the package convention.

MATLAB v7.3 files are HDF5; MATLAB stores arrays column-major, so their axes are reversed on
reading (an ``LF`` of MATLAB size [S, T, U, V, 3] reads as [S, T, U, V, 3]). MATLAB light fields
of the Light Field Toolbox carry a 4th weight channel, which is dropped.
"""

from __future__ import annotations

import json
import os
import zipfile
from pathlib import Path

import numpy as np

from lfsam.errors import LfsamError
from lfsam.fileutil import atomic_output
from lfsam.io.decode import decoding
from lfsam.io.native import json_safe
from lfsam.lightfield import LightField, categories_from_json, categories_to_json

__all__ = ["read_h5", "read_mat", "read_npy", "read_npz", "write_npz"]

#: Key names searched for the views, in order of preference.
VIEW_KEYS = ("views", "LF", "lf", "lightfield", "light_field", "LightField", "data", "images")
DISPARITY_KEYS = ("disparity", "disp", "DISPARITY")
LABEL_KEYS = ("labels", "label", "LABELS")

_SHAPE_HELP = (
    "a light field needs shape [S, T, U, V, 3] (view row, view column, pixel row, pixel column, "
    "RGB)"
)


def check_view_array(array: np.ndarray, where: str, allow_weight_channel: bool = False):
    """Check a views array and return it, with a clear message for the usual mistakes.

    Raises
    ------
    LfsamError
        For anything other than ``[S, T, U, V, 3]`` (or ``[S, T, U, V, 4]`` when allowed).
    """
    shape = tuple(array.shape)
    if array.ndim == 5 and shape[-1] == 3:
        return array
    if array.ndim == 5 and shape[-1] == 4 and allow_weight_channel:
        return array[..., :3]
    hint = ""
    if array.ndim == 4:
        hint = (
            "; a 4-D array is a single-channel light field or a stack of views: add the RGB axis "
            "(np.repeat(a[..., None], 3, -1)) or reshape the stack to [S, T, U, V, 3]"
        )
    elif array.ndim == 3:
        hint = "; a 3-D array is one image, not a light field"
    elif array.ndim == 5 and shape[2] in (3, 4):
        hint = "; it looks channels-first: move the channel axis last (np.moveaxis(a, 2, -1))"
    elif array.ndim == 5:
        hint = f"; its last axis has {shape[-1]} channels, expected 3 (RGB)"
    raise LfsamError(f"{where} has shape {shape}, but {_SHAPE_HELP}{hint}")


def _pick(keys: list[str], arrays: dict, preferred: tuple[str, ...], where: Path) -> str:
    for key in preferred:
        if key in arrays:
            return key
    five = [k for k in keys if getattr(arrays[k], "ndim", 0) == 5]
    if len(five) == 1:
        return five[0]
    if not five:
        shapes = ", ".join(f"{k} {tuple(arrays[k].shape)}" for k in keys[:6]) or "nothing"
        raise LfsamError(
            f"no light-field array in {where} (found {shapes}); store the views as 'views' "
            f"with shape [S, T, U, V, 3]"
        )
    raise LfsamError(
        f"{where} holds several 5-D arrays ({', '.join(five)}); name the views 'views'"
    )


def _optional(arrays: dict, keys: tuple[str, ...]) -> np.ndarray | None:
    for key in keys:
        if key in arrays:
            return np.asarray(arrays[key])
    return None


def read_npz(path: str | os.PathLike, value_range: int | None = None) -> LightField:
    """Read an ``.npz`` light field (``views`` plus optional ``disparity``, ``labels``, ``meta``).

    Raises
    ------
    LfsamError
        If the file is unreadable or holds no ``[S, T, U, V, 3]`` array.
    """
    path = Path(path)
    arrays: dict[str, np.ndarray] = {}
    with decoding(path, ".npz"), np.load(path, allow_pickle=False) as archive:
        if not hasattr(archive, "files"):
            raise LfsamError(f"{path} is a single .npy array, not an .npz archive; rename it")
        for key in archive.files:
            try:
                arrays[key] = archive[key]
            except ValueError as exc:  # a pickled object array: never unpickled, skipped
                if "allow_pickle" not in str(exc):
                    raise
                continue
    keys = [
        k for k in arrays
        if k not in ("meta", "present", "categories", *DISPARITY_KEYS, *LABEL_KEYS)
    ]
    key = _pick(keys, arrays, VIEW_KEYS, path)
    views = check_view_array(arrays[key], f"array {key!r} in {path}")
    meta: dict = {}
    if "meta" in arrays:
        try:
            meta = json.loads(str(arrays["meta"]))
        except ValueError:
            meta = {}
        meta = meta if isinstance(meta, dict) else {}
    old_source, old_format = meta.pop("source", None), meta.pop("format", None)
    if old_source is not None or old_format is not None:
        meta["converted_from"] = f"{old_format or '?'}: {old_source or '?'}"
    meta.update(source=str(path), format="npz")
    labels = _optional(arrays, LABEL_KEYS)
    categories = None
    if "categories" in arrays and labels is not None:
        try:
            categories = json.loads(str(arrays["categories"]))
        except ValueError:
            raise LfsamError(
                f"{path}: 'categories' is not a JSON object mapping label ids to names; "
                "rewrite it as e.g. json.dumps({\"2\": \"disc\"})"
            ) from None
        categories = categories_from_json(categories, f"{path}: categories")
    return LightField(
        views,
        disparity=_optional(arrays, DISPARITY_KEYS),
        labels=labels,
        meta=meta,
        present=arrays.get("present"),
        value_range=value_range,
        categories=categories,
    )


def read_npy(path: str | os.PathLike, value_range: int | None = None) -> LightField:
    """Read a single ``.npy`` array ``[S, T, U, V, 3]``.

    Raises
    ------
    LfsamError
        If the file is unreadable or has the wrong shape.
    """
    path = Path(path)
    with decoding(path, ".npy"):
        array = np.load(path, mmap_mode="r", allow_pickle=False)
    if not isinstance(array, np.ndarray):
        raise LfsamError(f"{path} is not a single .npy array; give an [S, T, U, V, 3] .npy")
    views = check_view_array(array, str(path))
    with decoding(path, ".npy"):
        views = np.array(views)
    return LightField(
        views, meta={"source": str(path), "format": "npy"}, value_range=value_range
    )


def _h5_arrays(group) -> dict[str, object]:
    """All datasets of an HDF5 file by name (full path and leaf name)."""
    import h5py

    found: dict[str, object] = {}

    def visit(name: str, obj) -> None:
        if isinstance(obj, h5py.Dataset):
            found.setdefault(name, obj)
            found.setdefault(name.rsplit("/", 1)[-1], obj)

    group.visititems(visit)
    return found


class _Reversed:
    """A lazy view of an HDF5 dataset with its axes reversed (MATLAB column-major order)."""

    def __init__(self, dataset) -> None:
        self.dataset = dataset
        self.ndim = dataset.ndim
        self.shape = tuple(reversed(dataset.shape))

    def __array__(self, dtype=None, copy=None):
        array = np.asarray(self.dataset[()]).transpose()
        return array if dtype is None else array.astype(dtype)


def _read_hdf5(path: Path, fmt: str, matlab: bool, value_range: int | None = None) -> LightField:
    import h5py

    with decoding(path, "HDF5"):
        handle = h5py.File(path, "r")
    with handle:
        with decoding(path, "HDF5"):
            datasets = _h5_arrays(handle)
        arrays = {k: (_Reversed(v) if matlab else v) for k, v in datasets.items()}
        keys = [k for k in arrays if k not in (*DISPARITY_KEYS, *LABEL_KEYS)]
        key = _pick(keys, arrays, VIEW_KEYS, path)
        with decoding(path, "HDF5"):
            data = np.asarray(arrays[key])
            disparity = _optional(arrays, DISPARITY_KEYS)
            labels = _optional(arrays, LABEL_KEYS)
        views = check_view_array(data, f"dataset {key!r} in {path}", allow_weight_channel=matlab)
    meta = {"source": str(path), "format": fmt, "dataset": key}
    if matlab:
        meta["layout"] = "MATLAB v7.3 (HDF5), axes reversed from column-major storage"
    return LightField(
        views, disparity=disparity, labels=labels, meta=meta, value_range=value_range
    )


def read_h5(path: str | os.PathLike, value_range: int | None = None) -> LightField:
    """Read a 5-D ``[S, T, U, V, 3]`` dataset from an HDF5 file (key ``LF``, ``views``, ...).

    Raises
    ------
    LfsamError
        If the file is unreadable or holds no suitable dataset.
    """
    return _read_hdf5(Path(path), "h5", matlab=False, value_range=value_range)


def read_mat(path: str | os.PathLike, value_range: int | None = None) -> LightField:
    """Read a MATLAB ``.mat`` light field (v5 with SciPy, v7.3 with h5py).

    Raises
    ------
    LfsamError
        If the file is unreadable or holds no suitable array.
    """
    import scipy.io

    path = Path(path)
    with decoding(path, "a MATLAB file"):
        try:
            contents = scipy.io.loadmat(path)
        except NotImplementedError:  # MATLAB v7.3 is HDF5
            contents = None
    if contents is None:
        return _read_hdf5(path, "mat", matlab=True, value_range=value_range)
    arrays = {
        k: v for k, v in contents.items() if not k.startswith("__") and isinstance(v, np.ndarray)
    }
    keys = [k for k in arrays if k not in (*DISPARITY_KEYS, *LABEL_KEYS)]
    key = _pick(keys, arrays, VIEW_KEYS, path)
    views = check_view_array(arrays[key], f"variable {key!r} in {path}", allow_weight_channel=True)
    return LightField(
        views,
        disparity=_optional(arrays, DISPARITY_KEYS),
        labels=_optional(arrays, LABEL_KEYS),
        meta={"source": str(path), "format": "mat", "variable": key},
        value_range=value_range,
    )


def write_npz(lf: LightField, path: str | os.PathLike, compress: bool = True) -> Path:
    """Write ``views`` [S, T, U, V, 3] uint8, ``disparity``, ``labels`` and ``meta`` to ``.npz``.

    The archive is written atomically and byte-for-byte reproducibly (fixed member timestamps),
    so equal light fields give identical files. :func:`numpy.load` reads it.

    Parameters
    ----------
    lf : LightField
        Ground truth must already be in the package convention.
    path : path-like
        Output file; should end in ``.npz``.
    compress : bool
        Deflate the members (level 1: fast, typically half the size).

    Returns
    -------
    Path
    """
    arrays = {"views": lf.views}
    if lf.disparity is not None:
        arrays["disparity"] = lf.disparity.astype(np.float32)
    if lf.labels is not None:
        arrays["labels"] = lf.labels.astype(np.int32)
    if lf.categories is not None:
        arrays["categories"] = np.array(json.dumps(categories_to_json(lf.categories)))
    if not lf.is_complete:
        arrays["present"] = lf.present
    arrays["meta"] = np.array(json.dumps(json_safe(lf.meta), sort_keys=True))
    method = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    with (
        atomic_output(path) as tmp,
        zipfile.ZipFile(tmp, "w", compression=method, compresslevel=1 if compress else None) as zf,
    ):
        for name, array in arrays.items():
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = method
            info.external_attr = 0o644 << 16
            with zf.open(info, "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.asarray(array), allow_pickle=False)
    return Path(path)
