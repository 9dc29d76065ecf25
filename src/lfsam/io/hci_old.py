"""The old HCI light-field archive (Wanner, Meister & Goldluecke, VMV 2013).

A scene is ``lf.h5`` with the dataset ``LF`` [S, T, U, V, 3] and ``GT_DEPTH`` ([S, T, U, V] or
the center view [U, V]) plus the attributes ``dH`` (camera spacing), ``focalLength`` and
``shift``; an optional ``labels.h5`` beside it holds ``GT_LABELS``. Depth converts to disparity
in pixels per view step by the archive's formula

    disparity = dH * focalLength / depth - shift

(Wanner et al. 2013, the archive's documentation), which is larger for closer points, as the
package convention wants. Non-positive depths become NaN.

Sign and orientation: the formula fixes the disparity's sign, but not how the ``LF`` grid axes
relate to the camera motion. The reader therefore tries the 8 arrangements of the view grid by
photo-consistency with the converted disparity (:mod:`lfsam.io.orientation`) and applies the best
one; ``meta["orientation"]`` and ``meta["orientation_check"]`` report it. The labels are class
indices starting at 0 and are shifted by 1 so that 0 means "no label" (as for UrbanLF).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from lfsam.errors import LfsamError
from lfsam.io.arrays import check_view_array
from lfsam.io.decode import decoding
from lfsam.io.orientation import detect_orientation
from lfsam.lightfield import LightField

__all__ = ["depth_to_disparity", "is_hci_old", "read_hci_old"]

LABEL_OFFSET = 1


def depth_to_disparity(
    depth: np.ndarray, dh: float, focal_length: float, shift: float
) -> np.ndarray:
    """``dH * focalLength / depth - shift`` (old HCI archive); NaN where ``depth <= 0``.

    Returns
    -------
    ndarray, float32
    """
    depth = np.asarray(depth, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        disparity = np.where(depth > 0, dh * focal_length / depth - shift, np.nan)
    return disparity.astype(np.float32)


def _h5_file(path: Path) -> Path:
    return path / "lf.h5" if path.is_dir() else path


def is_hci_old(path: Path) -> bool:
    """Whether ``path`` (a folder with ``lf.h5`` or an ``.h5`` file) is an old-HCI scene."""
    import h5py

    h5 = _h5_file(path)
    if not h5.is_file():
        return False
    try:
        with h5py.File(h5, "r") as handle:
            return "LF" in handle and "GT_DEPTH" in handle
    except Exception:  # unreadable or damaged: not an old-HCI scene
        return False


def _attribute(handle, name: str, h5: Path) -> float:
    for owner in (handle, handle["LF"], handle["GT_DEPTH"]):
        if name in owner.attrs:
            return float(np.asarray(owner.attrs[name]).reshape(-1)[0])
    raise LfsamError(
        f"{h5} lacks the attribute {name!r} needed to convert GT_DEPTH to disparity; "
        "add it (old HCI files carry dH, focalLength and shift)"
    )


def read_hci_old(path: str | os.PathLike) -> LightField:
    """Read an old-HCI scene (a folder with ``lf.h5``, or the ``.h5`` file itself).

    Parameters
    ----------
    path : path-like
        Folder or ``lf.h5``; ``labels.h5`` is looked for beside it.

    Returns
    -------
    LightField
        Views, disparity from ``GT_DEPTH`` by the archive's formula, labels + 1 when present, in
        the package convention.

    Raises
    ------
    LfsamError
        If datasets or attributes are missing or shapes disagree.
    """
    import h5py

    h5 = _h5_file(Path(path))
    with decoding(h5, "HDF5"):
        handle = h5py.File(h5, "r")
    with handle, decoding(h5, "an old-HCI HDF5 file"):
        if "LF" not in handle or "GT_DEPTH" not in handle:
            raise LfsamError(f"{h5} lacks the datasets 'LF' and 'GT_DEPTH' of an old-HCI scene")
        data = np.asarray(handle["LF"])
        depth = np.asarray(handle["GT_DEPTH"])
        dh = _attribute(handle, "dH", h5)
        focal = _attribute(handle, "focalLength", h5)
        shift = _attribute(handle, "shift", h5)
    views = check_view_array(data, f"dataset 'LF' in {h5}")
    if depth.shape not in (views.shape[:4], views.shape[2:4]):
        raise LfsamError(
            f"GT_DEPTH in {h5} has shape {depth.shape}, expected {views.shape[:4]} or "
            f"{views.shape[2:4]} to match LF"
        )
    disparity = depth_to_disparity(depth, dh, focal, shift)
    labels = None
    label_file = h5.parent / "labels.h5"
    if label_file.is_file():
        with decoding(label_file, "HDF5"), h5py.File(label_file, "r") as handle:
            if "GT_LABELS" not in handle:
                raise LfsamError(f"{label_file} lacks the dataset 'GT_LABELS'")
            labels = np.asarray(handle["GT_LABELS"])
        if labels.dtype.kind not in "biuf":
            raise LfsamError(f"GT_LABELS in {label_file} are not numbers; check the file")
        labels = labels.astype(np.int64) + LABEL_OFFSET
    # The sign comes from the formula; only the grid arrangement is tested.
    finite = np.where(np.isfinite(disparity), disparity, 0.0)
    report = detect_orientation(views, finite, decide_sign=False)
    orientation = report.orientation
    meta = {
        "source": str(h5),
        "format": "hci-old",
        "depth_to_disparity": f"{dh:g} * {focal:g} / depth - {shift:g}",
        "orientation": orientation.describe(),
        "orientation_check": report.summary(),
    }
    if labels is not None:
        meta["label_offset"] = LABEL_OFFSET
        if labels.ndim == 4:
            labels = orientation.views(labels)
    return LightField(
        np.ascontiguousarray(orientation.views(views)),
        disparity=np.ascontiguousarray(orientation.disparity(disparity)),
        labels=labels,
        meta=meta,
    )
