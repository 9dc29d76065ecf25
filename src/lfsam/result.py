"""Segmentation results: N light-field masks, their label field, flags, timings and metadata.

A result holds N masks over all views, ``M[n, s, t, u, v]``, bit-packed (never dense for large N:
200 masks x 81 views x 480 x 640 is 5 GB as bool, 0.6 GB packed), and the derived label field
``labels[s, t, u, v]`` (int32, 0 = unlabeled, mask ``n`` has label ``n + 1``). It is saved as one
``.npz`` written atomically, with a JSON ``meta`` (docs/design.md section 1), and read back by
:func:`load_result`. Format version 2 (issue 44) stores the labels in the smallest unsigned
dtype that holds their largest id (:func:`label_storage_dtype`) at a chosen zlib level
(:data:`FAST_LEVEL` for the frames of a live stream); they are read back as int32, and files
of version 1 (int32 labels) load as before.
"""

from __future__ import annotations

import json
import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from lfsam.errors import LfsamError
from lfsam.fileutil import atomic_output

__all__ = [
    "PackedMasks",
    "SegmentationResult",
    "check_present",
    "label_ids",
    "label_storage_dtype",
    "load_result",
    "pack_masks",
    "save_result",
    "write_npz",
]

FORMAT_VERSION = 2
#: zlib level of :func:`save_result` by default (zlib's and ``numpy.savez_compressed``'s own).
DEFAULT_LEVEL = 6
#: zlib level for the frames of a stream (issue 44): about a fifth of the time of level 6 on a
#: frame's labels, for files about a fifth larger (docs/performance.md, "Issue 44").
FAST_LEVEL = 1


def label_storage_dtype(labels: np.ndarray) -> np.dtype:
    """The dtype a result file stores ``labels`` in (format version 2): uint8 for ids up to
    255, uint16 up to 65535, else int32 (docs/design.md section 1). Labels are ids >= 0; a
    negative value (not a valid label) keeps int32, so that the loader names it.

    Examples
    --------
    >>> [str(label_storage_dtype(np.array([0, x]))) for x in (3, 255, 256, 65536)]
    ['uint8', 'uint8', 'uint16', 'int32']
    """
    labels = np.asarray(labels)
    if labels.size == 0:
        return np.dtype(np.uint8)
    low, high = int(labels.min()), int(labels.max())
    if low < 0:
        return np.dtype(np.int32)
    for dtype in (np.uint8, np.uint16):
        if high <= np.iinfo(dtype).max:
            return np.dtype(dtype)
    return np.dtype(np.int32)


def pack_masks(masks: Any) -> np.ndarray:
    """Bit-pack ``(N, ...)`` boolean masks row by row, exactly as ``numpy.packbits(axis=1)`` of
    the flattened masks (big-endian bits); torch tensors are packed on their own device, so
    only an eighth of the bytes leaves a GPU.

    Examples
    --------
    >>> pack_masks(np.array([[1, 0, 0, 0, 0, 0, 0, 1, 1]], dtype=bool)).tolist()
    [[129, 128]]
    """
    import torch

    if not isinstance(masks, torch.Tensor):
        flat = np.asarray(masks, dtype=bool).reshape(len(masks), -1)
        return np.packbits(flat, axis=1)
    flat = masks.reshape(masks.shape[0], -1).to(torch.uint8)
    pad = (-flat.shape[1]) % 8
    if pad:
        flat = torch.nn.functional.pad(flat, (0, pad))
    weights = torch.tensor([128, 64, 32, 16, 8, 4, 2, 1], dtype=torch.uint8, device=flat.device)
    packed = (flat.view(flat.shape[0], -1, 8) * weights).sum(-1, dtype=torch.uint8)
    return packed.cpu().numpy()


class PackedMasks:
    """N boolean masks over an ``S x T`` grid of ``U x V`` views, one bit per pixel.

    Parameters
    ----------
    shape : (N, S, T, U, V)
        Logical shape.
    data : (N, S, T, ceil(U * V / 8)) uint8 ndarray, optional
        Packed bits (``numpy.packbits`` of each flattened view mask); zeros if omitted.
    """

    def __init__(self, shape: tuple[int, int, int, int, int], data: np.ndarray | None = None):
        self.shape = tuple(int(x) for x in shape)
        n, s, t, u, v = self.shape
        nbytes = (u * v + 7) // 8
        if data is None:
            data = np.zeros((n, s, t, nbytes), dtype=np.uint8)
        if data.shape != (n, s, t, nbytes) or data.dtype != np.uint8:
            raise LfsamError(
                f"packed masks have shape {data.shape} {data.dtype}, "
                f"expected {(n, s, t, nbytes)} uint8 for masks of shape {self.shape}"
            )
        self.data = data

    @property
    def num_masks(self) -> int:
        """N."""
        return self.shape[0]

    def set_view(self, s: int, t: int, masks: np.ndarray) -> None:
        """Store the N masks of view ``(s, t)``, given as ``(N, U, V)`` bool."""
        n, _, _, u, v = self.shape
        masks = np.asarray(masks, dtype=bool).reshape(n, u * v)
        self.data[:, s, t] = np.packbits(masks, axis=1)

    def view(self, s: int, t: int) -> np.ndarray:
        """The N masks of view ``(s, t)``, ``(N, U, V)`` bool."""
        n, _, _, u, v = self.shape
        bits = np.unpackbits(self.data[:, s, t], axis=1, count=u * v)
        return bits.reshape(n, u, v).astype(bool)

    def mask(self, index: int) -> np.ndarray:
        """Mask ``index`` over all views, ``(S, T, U, V)`` bool."""
        _, s, t, u, v = self.shape
        bits = np.unpackbits(self.data[index], axis=-1, count=u * v)
        return bits.reshape(s, t, u, v).astype(bool)

    def areas(self) -> np.ndarray:
        """Pixel count of every mask in every view, ``(N, S, T)`` int64."""
        table = np.unpackbits(np.arange(256, dtype=np.uint8)[:, None], axis=1).sum(1)
        return table[self.data].sum(axis=-1, dtype=np.int64)


@dataclass
class SegmentationResult:
    """Light-field masks and everything needed to trust and reuse them.

    Parameters
    ----------
    labels : (S, T, U, V) int32 ndarray
        Label field, 0 = unlabeled, mask ``n`` is label ``n + 1`` (larger masks written first,
        smaller on top; docs/design.md section 3.6).
    masks : PackedMasks or None
        The N masks before label fusion (overlaps kept).
    scores : (N,) float32 ndarray
        Score of each source mask in the prompted view (SAM 2's predicted IoU, or 1.0).
    fallback : (N, S, T) bool ndarray
        True where a view kept the coarse mask because refinement failed (paper section 3.4).
    refine_iou : (N, S, T) float32 ndarray
        IoU of the chosen refined mask with the coarse mask (NaN where not refined).
    timings : dict of str to float
        Seconds per stage (e.g. ``encode``, ``propagate``, ``occlude``, ``refine``) and ``total``.
    meta : dict
        JSON-serialisable: method, model, random-weights flag, thresholds, disparity source,
        input path, package version.
    present : (S, T) bool ndarray, optional
        Which views of the light field exist (partial grids, docs/design.md section 8); absent
        views hold all-zero labels. None (older files) means every view is present.
    """

    labels: np.ndarray
    masks: PackedMasks | None = None
    scores: np.ndarray | None = None
    fallback: np.ndarray | None = None
    refine_iou: np.ndarray | None = None
    timings: dict[str, float] = field(default_factory=dict)
    meta: dict[str, Any] = field(default_factory=dict)
    present: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.present is not None:
            self.present = check_present(self.present, np.shape(self.labels)[:2], "result")

    @property
    def present_mask(self) -> np.ndarray:
        """``present`` as an (S, T) bool array (all True when the result has none)."""
        if self.present is None:
            return np.ones(self.grid_shape, dtype=bool)
        return self.present

    @property
    def num_masks(self) -> int:
        """N, the number of masks (the largest label when masks are not stored)."""
        if self.masks is not None:
            return self.masks.num_masks
        return int(self.labels.max()) if self.labels.size else 0

    @property
    def grid_shape(self) -> tuple[int, int]:
        """``(S, T)``."""
        return self.labels.shape[0], self.labels.shape[1]

    @property
    def ms_per_mask_view(self) -> float | None:
        """Paper metric T: total wall-clock milliseconds / (N x S x T); None without timings."""
        total = self.timings.get("total")
        n = self.num_masks
        if total is None or n == 0:
            return None
        s, t = self.grid_shape
        return 1000.0 * total / (n * s * t)


def label_ids(labels: np.ndarray) -> np.ndarray:
    """The distinct values of ``labels``, sorted: ``numpy.unique`` of the values that end a run
    of equal values in C order (about 4 ms on a ``[5, 5, 480, 640]`` label field of a few
    objects, against about 100 ms for ``numpy.unique`` of every pixel; no faster on noise).

    Examples
    --------
    >>> label_ids(np.array([[0, 0, 3], [3, 70000, 0]])).tolist()
    [0, 3, 70000]
    """
    flat = np.ravel(labels)
    if flat.size == 0:
        return np.unique(flat)
    ends = flat[:-1][flat[1:] != flat[:-1]]
    return np.unique(np.append(ends, flat[-1]))


def save_result(result: SegmentationResult, path: str | os.PathLike,
                level: int = DEFAULT_LEVEL) -> Path:
    """Write ``result`` to ``path`` (``.npz``, compressed) atomically.

    The file is an ordinary ``.npz`` (``numpy.load`` reads it); the labels are stored in
    :func:`label_storage_dtype` (format version 2, docs/design.md section 1).

    Parameters
    ----------
    result : SegmentationResult
    path : path-like
        The ``.npz`` to write; it appears only when complete.
    level : int
        zlib level of every array, 0 (stored) to 9; :data:`FAST_LEVEL` for a stream's frames.

    Returns
    -------
    path : Path
        The written file.

    Examples
    --------
    See :func:`load_result`, which reads it back.
    """
    labels = np.asarray(result.labels)
    if labels.dtype.kind not in "iu":
        labels = labels.astype(np.int32)
    arrays: dict[str, np.ndarray] = {
        "format_version": np.array(FORMAT_VERSION),
        "labels": labels.astype(label_storage_dtype(labels), copy=False),
        "timings": np.array(json.dumps(result.timings)),
        "meta": np.array(json.dumps(result.meta, default=_json_default)),
    }
    if result.masks is not None:
        arrays["masks_packed"] = result.masks.data
        arrays["masks_shape"] = np.array(result.masks.shape, dtype=np.int64)
    for name in ("scores", "fallback", "refine_iou", "present"):
        value = getattr(result, name)
        if value is not None:
            arrays[name] = np.asarray(value)
    with atomic_output(path) as tmp:
        write_npz(tmp, arrays, level)
    return Path(path)


def write_npz(path: str | os.PathLike, arrays: dict[str, np.ndarray], level: int) -> None:
    """Write ``arrays`` as an ``.npz`` (as ``numpy.savez_compressed`` does) at zlib ``level``
    (0: stored, no compression)."""
    compression = zipfile.ZIP_DEFLATED if level > 0 else zipfile.ZIP_STORED
    with zipfile.ZipFile(path, "w", compression, compresslevel=level if level > 0 else None,
                         allowZip64=True) as archive:
        for name, value in arrays.items():
            with archive.open(f"{name}.npy", "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.asanyarray(value), allow_pickle=False)


def load_result(path: str | os.PathLike) -> SegmentationResult:
    """Read a result written by :func:`save_result`, or any ``.npz`` with a ``labels`` array.

    Raises
    ------
    LfsamError
        If the file is missing, unreadable or has no ``labels`` of shape ``(S, T, U, V)``.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> result = SegmentationResult(
    ...     labels=np.ones((1, 2, 3, 4), dtype=np.int32), meta={"method": "example"}
    ... )
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = save_result(result, os.path.join(folder, "result.npz"))
    ...     loaded = load_result(path)
    >>> loaded.labels.shape, loaded.num_masks, loaded.meta["method"]
    ((1, 2, 3, 4), 1, 'example')
    """
    path = Path(path)
    if not path.is_file():
        raise LfsamError(f"result file {str(path)!r} not found; give the .npz written by --out")
    try:
        with np.load(path, allow_pickle=False) as npz:
            contents = {key: npz[key] for key in npz.files}
    except Exception as exc:  # zipfile/zlib/NumPy errors on damaged files vary
        detail = " ".join(str(exc).split())[:160]
        raise LfsamError(
            f"cannot read {str(path)!r} as a result .npz ({type(exc).__name__}: {detail}); "
            "give the .npz written by `lfsam segment --out`"
        ) from None
    if "labels" not in contents:
        raise LfsamError(
            f"{str(path)!r} holds no 'labels' array (keys: {sorted(contents)}); "
            "a result needs labels of shape (S, T, U, V)"
        )
    labels = contents["labels"]
    if labels.ndim != 4:
        raise LfsamError(f"'labels' in {str(path)!r} has shape {labels.shape}, need (S, T, U, V)")
    if not np.issubdtype(labels.dtype, np.integer) or (
        labels.size and (labels.min() < 0 or labels.max() > np.iinfo(np.int32).max)
    ):
        raise LfsamError(
            f"'labels' in {str(path)!r} must be integers >= 0 (0 = unlabeled), got "
            f"{labels.dtype}; re-create the result"
        )
    masks = None
    if "masks_packed" in contents and "masks_shape" in contents:
        try:
            shape = tuple(int(x) for x in np.asarray(contents["masks_shape"]).ravel())
        except (TypeError, ValueError):
            shape = ()
        if len(shape) != 5 or min(shape) < 0:
            raise LfsamError(
                f"'masks_shape' in {str(path)!r} is not 5 sizes (N, S, T, U, V); "
                "re-create the result"
            )
        if shape[1:] != labels.shape:
            raise LfsamError(
                f"masks in {str(path)!r} have shape {shape[1:]} per mask but the labels "
                f"{labels.shape}; re-create the result"
            )
        masks = PackedMasks(shape, contents["masks_packed"])
    try:
        timings = json.loads(str(contents["timings"])) if "timings" in contents else {}
        meta = json.loads(str(contents["meta"])) if "meta" in contents else {}
    except ValueError:
        raise LfsamError(
            f"'timings' or 'meta' in {str(path)!r} is not JSON; re-create the result"
        ) from None
    present = contents.get("present")
    if present is not None:
        present = check_present(present, labels.shape[:2], repr(str(path)))
    return SegmentationResult(
        labels=labels.astype(np.int32),
        masks=masks,
        scores=contents.get("scores"),
        fallback=contents.get("fallback"),
        refine_iou=contents.get("refine_iou"),
        timings=timings if isinstance(timings, dict) else {},
        meta=meta if isinstance(meta, dict) else {},
        present=present,
    )


def check_present(present: Any, grid_shape: tuple[int, ...], where: str) -> np.ndarray:
    """Check a ``present`` mask: (S, T), boolean (or 0/1); return it as bool.

    Raises
    ------
    LfsamError
        If it has another shape or values other than 0 and 1.
    """
    present = np.asarray(present)
    if present.shape != tuple(grid_shape):
        raise LfsamError(
            f"'present' of {where} has shape {present.shape}, but the grid is "
            f"{tuple(grid_shape)}; it must be one flag per view"
        )
    if present.dtype != bool and not (
        np.issubdtype(present.dtype, np.number) and np.isin(present, (0, 1)).all()
    ):
        raise LfsamError(f"'present' of {where} must hold booleans (True = view exists)")
    return present.astype(bool)


def _json_default(value: Any) -> Any:
    """``json.dump``'s ``default`` hook for metadata: NumPy scalars and arrays, tuples, paths.

    Raises
    ------
    TypeError
        For any other type, as ``json`` requires of the hook (metadata is built by lfsam itself,
        so this is a fault of the calling code).
    """
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (np.ndarray, tuple)):
        return np.asarray(value).tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")
