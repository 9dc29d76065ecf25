"""The result of a disparity estimator."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["DisparityEstimate"]


@dataclass
class DisparityEstimate:
    """Disparity of the center view, with a per-pixel confidence.

    Attributes
    ----------
    disparity : ndarray, shape (U, V), float32
        Disparity of the center view in pixels per view step, in the convention of
        :mod:`lfsam.geometry`: center pixel ``(u, v)`` with disparity ``d`` is seen in the view at
        offset ``(ds, dt)`` at ``(u - d ds, v - d dt)``.
    confidence : ndarray, shape (U, V), float32 in [0, 1]
        How much to trust each value (structure-tensor coherence; 0 in textureless regions).
    disparity_range : (float, float)
        The disparity range the estimator searched (given by the user or estimated from the data).
    meta : dict
        Method name, parameters and timing, JSON-ready.
    """

    disparity: np.ndarray
    confidence: np.ndarray
    disparity_range: tuple[float, float]
    meta: dict[str, Any] = field(default_factory=dict)
