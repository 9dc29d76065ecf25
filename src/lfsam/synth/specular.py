"""Non-Lambertian surfaces for the synthetic generator: a specular highlight that moves across
views (docs/design.md section 6).

A Lambertian surface looks the same from every view, which is what every disparity estimator
assumes. A glossy one reflects a light source at a place that depends on the viewpoint: the
highlight slides over the surface as the camera moves, so a surface point changes colour from view
to view and the highlight itself has a "disparity" of its own (Tao et al., "Depth estimation and
specular removal for glossy surfaces using point and line consistency with light-field cameras",
TPAMI 2017). To measure how the disparity estimators and their confidence behave there, every
object (not the background) can carry one such highlight: a white Gaussian spot added to its
texture, centred in the object's local coordinates at a seed-drawn point that moves by
``slide * (dt, ds) / reach`` local units in the view at offset ``(ds, dt)`` (``reach``: the
largest view offset of the grid), clipped to the displayable range.
"""

from __future__ import annotations

import numpy as np
import torch

from lfsam.synth.scene import PlanarObject

__all__ = ["SLIDE", "SPOT_SIGMA", "add_highlight"]

#: How far (object-local units; the object spans [-1, 1]) the highlight moves between the
#: center view and the outermost view.
SLIDE = 0.6
#: Standard deviation of the highlight spot in local units.
SPOT_SIGMA = 0.3


def _spot_center(obj: PlanarObject) -> tuple[float, float]:
    """The highlight's local position ``(y, x)`` in the center view, drawn from the object's
    texture seed (deterministic)."""
    rng = np.random.default_rng(obj.texture_seed ^ 0x5BEC)
    y, x = rng.uniform(-0.4, 0.4, size=2)
    return float(y), float(x)


def add_highlight(
    colour: torch.Tensor,
    obj: PlanarObject,
    x: torch.Tensor,
    y: torch.Tensor,
    ds: float,
    dt: float,
    reach: float,
    strength: float,
) -> torch.Tensor:
    """``colour`` (``[3, rows, cols]``, in [0, 1]) of ``obj`` with its moving highlight added.

    Parameters
    ----------
    colour : torch.Tensor
        The object's texture sampled at the local coordinates ``x``, ``y`` (``[rows, cols]``).
    obj : PlanarObject
        The object (its texture seed places the highlight).
    ds, dt : float
        The view's offset from the center view.
    reach : float
        Largest view offset of the grid (the highlight moves by :data:`SLIDE` up to there).
    strength : float
        Peak brightness added (0 = Lambertian).

    Returns
    -------
    torch.Tensor, shape of ``colour``, clipped to [0, 1]
    """
    if strength <= 0:
        return colour
    y0, x0 = _spot_center(obj)
    scale = SLIDE / max(reach, 1.0)
    cy, cx = y0 + scale * ds, x0 + scale * dt
    spot = torch.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2.0 * SPOT_SIGMA**2))
    return (colour + strength * spot.to(colour.dtype)[None]).clamp(0.0, 1.0)
