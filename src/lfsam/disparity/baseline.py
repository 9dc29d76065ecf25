"""The plain single-scale EPI structure tensor in NumPy: the comparison baseline.

A straightforward implementation of the local estimator of Wanner & Goldluecke ("Globally
consistent depth labeling of 4D light fields", CVPR 2012, section 3.1), set up like the NumPy
implementation the paper's authors called (plenpy's ``LightField.get_disparity`` with
``method="structure_tensor"``): each EPI through the center view is smoothed with a Gaussian of
inner scale 0.75, differentiated with Scharr filters, the gradient products are smoothed with a
Gaussian of outer scale 2.0 in the EPI plane, and the center line's orientation and coherence are
read off; every colour channel of both directions gives one estimate, and the estimates are
averaged with weights ``coherence^2`` (plenpy's ``fusion_method="weighted_average"``). There is no
shearing, so it only works for disparities of about +-1 to 2 pixels per view step.

All EPIs of a direction are processed at once as one ``(N, rows, cols)`` array (``scipy.ndimage``
filters with a zero sigma across pixel rows), so there is no Python loop over EPIs.
"""

from __future__ import annotations

import time

import numpy as np
from scipy import ndimage

from lfsam.disparity.epi import as_views, usable_directions
from lfsam.disparity.estimate import DisparityEstimate
from lfsam.errors import LfsamError
from lfsam.lightfield import LightField

__all__ = ["estimate_disparity_baseline"]

_SCHARR_DERIVATIVE = np.array([-1.0, 0.0, 1.0]) / 2.0
_SCHARR_SMOOTHING = np.array([3.0, 10.0, 3.0]) / 16.0


def _epi_orientation(
    epis: np.ndarray, center: int, inner_scale: float, outer_scale: float
) -> tuple[np.ndarray, np.ndarray]:
    """Disparity and coherence on the center line of a stack of EPIs ``(N, rows, cols)``.

    Axis 0 is the view, axis 2 the pixel along the same direction; axis 1 indexes the EPIs.
    """
    smooth = ndimage.gaussian_filter(epis, (inner_scale, 0, inner_scale), mode="nearest")
    g_n = ndimage.correlate1d(smooth, _SCHARR_DERIVATIVE, axis=0, mode="nearest")
    g_n = ndimage.correlate1d(g_n, _SCHARR_SMOOTHING, axis=2, mode="nearest")
    g_x = ndimage.correlate1d(smooth, _SCHARR_DERIVATIVE, axis=2, mode="nearest")
    g_x = ndimage.correlate1d(g_x, _SCHARR_SMOOTHING, axis=0, mode="nearest")
    outer = (outer_scale, 0, outer_scale)
    j_nn = ndimage.gaussian_filter(g_n * g_n, outer, mode="nearest")[center]
    j_nx = ndimage.gaussian_filter(g_n * g_x, outer, mode="nearest")[center]
    j_xx = ndimage.gaussian_filter(g_x * g_x, outer, mode="nearest")[center]
    # dominant eigenvector (d, 1): tan(2 phi) = 2 J_nx / (J_xx - J_nn), d = tan(phi)
    diff = j_xx - j_nn
    disparity = np.tan(0.5 * np.arctan2(2.0 * j_nx, diff))
    trace = j_nn + j_xx
    coherence = np.where(
        trace > np.finfo(np.float64).eps,
        np.sqrt(diff**2 + 4.0 * j_nx**2) / (trace + 1e-5),
        0.0,
    )
    return disparity, coherence


def estimate_disparity_baseline(
    views: LightField | np.ndarray,
    *,
    inner_scale: float = 0.75,
    outer_scale: float = 2.0,
    color: bool = True,
    disparity_range: tuple[float, float] | None = None,
) -> DisparityEstimate:
    """Center-view disparity with the plain single-scale EPI structure tensor (NumPy).

    Parameters
    ----------
    views : LightField or ndarray, shape (S, T, U, V, 3), uint8
        The light field; a direction needs at least three views.
    inner_scale, outer_scale : float
        Gaussian standard deviations (pixels and views) of the EPI pre-smoothing and of the
        tensor aggregation; the defaults are plenpy's.
    color : bool
        One estimate per colour channel (plenpy's behaviour) instead of one on gray levels.
    disparity_range : (lo, hi), optional
        Clip the result to this range (plenpy clips to ``vmin, vmax``); the orientation of a
        near-horizontal EPI structure otherwise gives unbounded values.

    Returns
    -------
    DisparityEstimate
        In the package convention (:mod:`lfsam.geometry`); ``disparity_range`` is the range of
        the estimate itself.

    Raises
    ------
    LfsamError
        If neither direction has three views.
    """
    start = time.perf_counter()
    array = as_views(views)
    s_count, t_count = array.shape[:2]
    directions = usable_directions((s_count, t_count))
    if not directions:
        raise LfsamError(
            f"grid {s_count}x{t_count}: need at least 3 views in a row or column to estimate "
            "disparity; give a disparity map instead (--disparity gt or a .npy file)"
        )
    s_c, t_c = s_count // 2, t_count // 2
    images = array.astype(np.float64) / 255.0
    if not color:
        images = images @ np.array([0.299, 0.587, 0.114])[:, None]
    estimates, weights = [], []
    for direction in directions:
        if direction == "horizontal":
            stack, center = images[s_c], t_c  # (T, U, V, C): EPIs (t, v) at each u
        else:
            stack, center = images[:, t_c].transpose(0, 2, 1, 3), s_c  # (S, V, U, C)
        for channel in range(stack.shape[-1]):
            disp, coh = _epi_orientation(stack[..., channel], center, inner_scale, outer_scale)
            if direction == "vertical":
                disp, coh = disp.T, coh.T
            estimates.append(disp)
            weights.append(coh**2)
    weight_sum = np.sum(weights, axis=0)
    disparity = np.sum([d * w for d, w in zip(estimates, weights, strict=True)], axis=0)
    disparity = np.where(weight_sum > 0, disparity / np.maximum(weight_sum, 1e-20), 0.0)
    if disparity_range is not None:
        disparity = np.clip(disparity, *disparity_range)
    confidence = np.sqrt(weight_sum / len(weights))
    return DisparityEstimate(
        disparity=disparity.astype(np.float32),
        confidence=np.clip(confidence, 0.0, 1.0).astype(np.float32),
        disparity_range=(float(disparity.min()), float(disparity.max())),
        meta={
            "method": "plain structure tensor (NumPy baseline)",
            "directions": directions,
            "inner_scale": inner_scale,
            "outer_scale": outer_scale,
            "color": color,
            "seconds": time.perf_counter() - start,
        },
    )
