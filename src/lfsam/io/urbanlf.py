"""UrbanLF (Sheng et al., IEEE TIP 2022): the paper's benchmark (paper section 4).

UrbanLF-Syn scene folders hold one image per view ``{row}_{col}.png`` (1-based, ``1_1.png`` to
``9_9.png``, 480x640 pixels) with per-view ``{row}_{col}_disparity.npy`` and
``{row}_{col}_label.npy`` (semantic classes starting at 0). UrbanLF-Real scene folders hold the
views and a center-view ``label.npy`` only.

Labels: the files' classes start at 0, so 1 is added and 0 keeps its package meaning, "no label"
(the authors add 1 too).

Orientation (docs/design.md section 2): how the files' view grid and disparity sign relate to the
package convention is not documented, and the authors' loader and metric disagree. With
ground-truth disparity the reader settles it from the data
(:func:`lfsam.io.orientation.detect_orientation`): photo-consistency picks the arrangement of the
view grid, occlusion order picks between "flip both view axes" and "negate the disparity" (which
warp identically). The result is recorded in ``meta["orientation"]`` and the evidence in
``meta["orientation_check"]``, both shown by ``lfsam info``. Without ground-truth disparity
(UrbanLF-Real) the views are kept as stored.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from lfsam.errors import LfsamError
from lfsam.io.grid_folder import assemble_grid
from lfsam.io.images import read_view_grid
from lfsam.io.orientation import detect_orientation
from lfsam.lightfield import LightField

__all__ = ["LABEL_OFFSET", "is_urbanlf", "read_urbanlf"]

#: Added to the files' class labels so that 0 means "no label".
LABEL_OFFSET = 1

_VIEW = re.compile(r"^(\d+)_(\d+)\.png$")
_GT = re.compile(r"^(\d+)_(\d+)_(disparity|label)\.npy$")


def is_urbanlf(folder: Path) -> bool:
    """Whether ``folder`` looks like an UrbanLF scene: ``R_C.png`` views plus UrbanLF labels or
    disparity files."""
    if not folder.is_dir():
        return False
    names = [p.name for p in folder.iterdir()]
    has_views = any(_VIEW.match(n) for n in names)
    has_gt = any(_GT.match(n) for n in names) or "label.npy" in names
    return has_views and has_gt


def _load(path: Path, what: str, shape: tuple[int, int]) -> np.ndarray:
    try:
        array = np.load(path, allow_pickle=False)
    except Exception as exc:  # any NumPy failure on a damaged file
        raise LfsamError(f"cannot read {what} file {path} ({exc}); check the file") from None
    array = np.squeeze(array)
    if array.shape != shape:
        raise LfsamError(
            f"{path.name} has shape {array.shape} but the views are {shape[0]}x{shape[1]}; "
            "the ground truth must match the views"
        )
    return array


def _stack_gt(
    files: dict[tuple[int, int], Path], rows, cols, what: str, shape: tuple[int, int]
) -> np.ndarray | None:
    """Per-view ground truth when every view has it, center-only when only the center has it."""
    keys = [(r, c) for r in rows for c in cols]
    if files and all(k in files for k in keys):
        return np.stack([_load(files[k], what, shape) for k in keys]).reshape(
            len(rows), len(cols), *shape
        )
    center = (rows[len(rows) // 2], cols[len(cols) // 2])
    if center in files:
        return _load(files[center], what, shape)
    return None


def read_urbanlf(folder: str | os.PathLike) -> LightField:
    """Read an UrbanLF-Syn or UrbanLF-Real scene folder.

    Parameters
    ----------
    folder : path-like
        The scene folder.

    Returns
    -------
    LightField
        Views, disparity and labels (+1) in the package convention; ``meta["orientation"]`` says
        what was flipped or negated, ``meta["orientation_check"]`` why.

    Raises
    ------
    LfsamError
        If views are missing or ground truth does not match the views.
    """
    folder = Path(folder)
    entries: dict[tuple[int, int], Path] = {}
    gt: dict[str, dict[tuple[int, int], Path]] = {"disparity": {}, "label": {}}
    for path in folder.iterdir():
        match = _VIEW.match(path.name)
        if match:
            entries[(int(match.group(1)), int(match.group(2)))] = path
        match = _GT.match(path.name)
        if match:
            gt[match.group(3)][(int(match.group(1)), int(match.group(2)))] = path
    if not entries:
        raise LfsamError(f"no ROW_COL.png views in {folder}; is this an UrbanLF scene?")
    paths, rows, cols = assemble_grid(entries, folder, lambda r, c: f"{r}_{c}.png")
    views = read_view_grid(paths)
    shape = views.shape[2:4]
    disparity = _stack_gt(gt["disparity"], rows, cols, "disparity", shape)
    labels = _stack_gt(gt["label"], rows, cols, "label", shape)
    if labels is None and (folder / "label.npy").is_file():
        labels = _load(folder / "label.npy", "label", shape)
    meta: dict = {"source": str(folder), "format": "urbanlf"}
    if labels is not None:
        if labels.size and labels.min() < 0:
            raise LfsamError(f"UrbanLF labels in {folder} are negative; check the label files")
        labels = labels.astype(np.int64) + LABEL_OFFSET
        meta["label_offset"] = LABEL_OFFSET
    if disparity is not None:
        report = detect_orientation(views, disparity.astype(np.float32))
        orientation = report.orientation
        views = orientation.views(views)
        disparity = orientation.disparity(disparity)
        if labels is not None and labels.ndim == 4:
            labels = orientation.views(labels)
        meta["orientation"] = orientation.describe()
        meta["orientation_check"] = report.summary()
    else:
        meta["orientation"] = "views as stored; not verified (no ground-truth disparity)"
    return LightField(
        np.ascontiguousarray(views),
        disparity=None if disparity is None else np.ascontiguousarray(disparity),
        labels=None if labels is None else np.ascontiguousarray(labels),
        meta=meta,
    )
