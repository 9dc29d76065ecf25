"""The result of a disparity estimator."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["DisparityEstimate"]


@dataclass
class DisparityEstimate:
    """Disparity of one view (the center view unless ``meta["view"]`` says otherwise), with a
    per-pixel confidence.

    Attributes
    ----------
    disparity : ndarray, shape (U, V), float32
        Disparity of the center view in pixels per view step, in the convention of
        :mod:`lfsam.geometry`: center pixel ``(u, v)`` with disparity ``d`` is seen in the view at
        offset ``(ds, dt)`` at ``(u - d ds, v - d dt)``.
    confidence : ndarray, shape (U, V), float32 in [0, 1]
        How much to trust each value: for the occlusion-aware estimator the cost-curve margin
        times the left-right consistency (:mod:`lfsam.disparity.confidence`), for the structure
        tensor its coherence; low in textureless regions and (occlusion-aware) at occlusion
        edges and on non-Lambertian surfaces (docs/design.md section 3.2).
    disparity_range : (float, float)
        The disparity range the estimator searched (given by the user or estimated from the data).
    meta : dict
        Method name, parameters and timing, JSON-ready.
    """

    disparity: np.ndarray
    confidence: np.ndarray
    disparity_range: tuple[float, float]
    meta: dict[str, Any] = field(default_factory=dict)
