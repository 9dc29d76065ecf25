"""The disparity estimators by name, and the one entry point that picks one.

``estimate_disparity(views, method=...)`` is what ``lfsam disparity`` and ``--disparity
estimate`` (:func:`lfsam.disparity.source.resolve_disparity`) call (docs/design.md section 3.2):

- ``"occlusion-aware"`` (default): the occlusion-aware cost volume
  (:func:`lfsam.disparity.occlusion_aware.estimate_disparity_occlusion_aware`);
- ``"structure-tensor"``: the sheared EPI structure tensor
  (:func:`lfsam.disparity.structure_tensor.estimate_disparity`), the estimator of the paper.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import torch

from lfsam.disparity.estimate import DisparityEstimate
from lfsam.disparity.occlusion_aware import estimate_disparity_occlusion_aware
from lfsam.disparity.structure_tensor import estimate_disparity as estimate_structure_tensor
from lfsam.errors import LfsamError
from lfsam.lightfield import LightField

__all__ = ["DEFAULT_METHOD", "METHODS", "estimate_disparity"]

#: Estimators by name (the values of ``lfsam disparity --method``).
METHODS: dict[str, Callable[..., DisparityEstimate]] = {
    "occlusion-aware": estimate_disparity_occlusion_aware,
    "structure-tensor": estimate_structure_tensor,
}

#: The estimator used when none is named.
DEFAULT_METHOD = "occlusion-aware"


def estimate_disparity(
    views: LightField | np.ndarray,
    disparity_range: tuple[float, float] | None = None,
    *,
    method: str = DEFAULT_METHOD,
    device: str | torch.device | None = None,
    view: tuple[int, int] | None = None,
    **options: Any,
) -> DisparityEstimate:
    """Estimate the disparity of one view with the estimator named ``method``.

    Parameters
    ----------
    views : LightField or ndarray, shape (S, T, U, V, 3), uint8
        The light field (absent views of a partial grid are skipped).
    disparity_range : (lo, hi), optional
        Disparities to search, pixels per view step (default: found from the views,
        :mod:`lfsam.disparity.range`).
    method : {"occlusion-aware", "structure-tensor"}
        Which estimator (:data:`METHODS`).
    device : str or torch.device, optional
        Where to compute; default ``auto``.
    view : (s, t), optional
        The view to estimate (0-based); default the center view.
    **options
        Keyword options of that estimator (e.g. ``edge_refinement``, ``num_hypotheses`` for the
        occlusion-aware one, ``candidate_step`` for the structure tensor).

    Returns
    -------
    DisparityEstimate
        ``disparity``, ``confidence`` in [0, 1], the range searched and ``meta`` (with
        ``meta["method"]``).

    Raises
    ------
    LfsamError
        Unknown method, or what the estimator raises (view outside the grid or absent, too few
        views, invalid range).
    """
    try:
        estimator = METHODS[method]
    except KeyError:
        raise LfsamError(
            f"unknown disparity method {method!r}; choose one of {', '.join(METHODS)}"
        ) from None
    try:
        return estimator(views, disparity_range, device=device, view=view, **options)
    except TypeError as exc:
        if "unexpected keyword argument" in str(exc):
            raise LfsamError(f"disparity method {method!r}: {exc}") from None
        raise
