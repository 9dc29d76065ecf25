"""Where the pipeline's disparity comes from: estimated, ground truth, or a file.

Every command that consumes disparity (``lfsam segment --disparity``, ``lfsam evaluate``)
accepts the same three sources (docs/design.md section 3.2: "also accept a given disparity map").
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField

__all__ = ["resolve_disparity"]


def resolve_disparity(
    spec: str | os.PathLike,
    lightfield: LightField,
    *,
    device: str | None = None,
) -> tuple[np.ndarray, str]:
    """The center-view disparity named by ``spec``, in the package convention.

    Parameters
    ----------
    spec : {"estimate", "gt"} or path
        ``"estimate"``: the structure-tensor estimator (:func:`estimate_disparity`) on the
        views; ``"gt"``: the light field's ground-truth center disparity; otherwise a ``.npy``
        file holding a ``(U, V)`` map in the convention of :mod:`lfsam.geometry`.
    lightfield : LightField
    device : str, optional
        Where the estimator runs.

    Returns
    -------
    disparity : (U, V) float32 ndarray
    source : str
        A short description for result metadata (e.g. ``"estimate [-2.1, 1.9]"``, ``"gt"``,
        ``"file:/path/disp.npy"``).

    Raises
    ------
    LfsamError
        Ground truth absent, file missing or unreadable, or a map of the wrong shape.
    """
    size = lightfield.view_shape
    spec_text = str(spec)
    if spec_text == "estimate":
        from lfsam.disparity.structure_tensor import estimate_disparity

        estimate = estimate_disparity(lightfield, device=device)
        low, high = estimate.disparity_range
        return (
            np.asarray(estimate.disparity, dtype=np.float32),
            f"estimate [{low:.2f}, {high:.2f}]",
        )
    if spec_text == "gt":
        disparity = lightfield.center_disparity
        if disparity is None:
            raise LfsamError(
                "this light field has no ground-truth disparity; use --disparity estimate or "
                "--disparity FILE.npy"
            )
        return np.asarray(disparity, dtype=np.float32), "gt"
    path = Path(spec_text)
    if path.suffix.lower() != ".npy":
        raise LfsamError(
            f"--disparity must be 'estimate', 'gt' or a .npy file, got {spec_text!r}"
        )
    if not path.is_file():
        raise LfsamError(f"disparity file {spec_text!r} not found")
    try:
        disparity = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise LfsamError(f"cannot read disparity file {spec_text!r}: {exc}") from None
    if disparity.shape != size:
        raise LfsamError(
            f"disparity file {spec_text!r} has shape {disparity.shape}, but the center view is "
            f"{size[0]}x{size[1]}; give a (U, V) map of the center view"
        )
    if not np.issubdtype(disparity.dtype, np.number):
        raise LfsamError(f"disparity file {spec_text!r} does not hold numbers")
    return disparity.astype(np.float32), f"file:{path}"
