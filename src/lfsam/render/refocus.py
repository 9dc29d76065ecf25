"""Refocusing: shift-and-add over the synthetic aperture at one disparity (docs/design.md 13).

Ng (2005), "Fourier slice photography" / Ng et al. (2005), "Light field photography with a
hand-held plenoptic camera": every view is shifted so that the plane of disparity ``focus``
lines up with the center view and the views are averaged; what lies on that plane is sharp,
the rest is blurred as by a lens as wide as the aperture. Sub-pixel shifts are Lanczos-3 by
default (bilinear blurs a sharp texture by each view's own sub-pixel phase), and each pixel is
normalised by the rays that landed in it (:mod:`lfsam.render.shift`).
"""

from __future__ import annotations

import numpy as np
import torch

from lfsam.devices import resolve_device
from lfsam.errors import LfsamError
from lfsam.render.shift import shift_and_add
from lfsam.render.views import clip_focus, select_views, views_tensor

__all__ = ["object_focus", "refocus"]


def refocus(
    views: np.ndarray,
    focus: float,
    *,
    present: np.ndarray | None = None,
    aperture: float | None = None,
    disparity_range: tuple[float, float] | None = None,
    device: str | torch.device | None = None,
    kernel: str = "lanczos3",
) -> np.ndarray:
    """The light field refocused at disparity ``focus``.

    Parameters
    ----------
    views : (S, T, U, V, 3) uint8 array
    focus : float
        Disparity of the focal plane, pixels between neighbouring views (the convention of
        ``lfsam disparity``, docs/design.md section 1).
    present : (S, T) bool array, optional
        Views that exist; absent ones are skipped.
    aperture : float, optional
        Radius of the synthetic aperture in view steps; None = every view.
    disparity_range : (lo, hi), optional
        The scene's range; a focus outside it is clipped to it, with a warning.
    device : str or torch.device, optional
        Where to compute (default CPU).
    kernel : {"lanczos3", "linear"}
        Sub-pixel interpolation (:func:`lfsam.render.shift.shift_and_add`). Lanczos-3 keeps a
        sharp texture on the focal plane sharp (bilinear sampling blurs each view by its own
        sub-pixel phase: a checkerboard object of ``lfsam synth`` refocused at its own plane
        is 32 dB from the center view with bilinear sampling, 35 dB with Lanczos-3).

    Returns
    -------
    (U, V, 3) float32 array in [0, 255]
        Each pixel the mean of the rays that landed in it (0 where none did).

    Examples
    --------
    >>> import numpy as np
    >>> lf = np.full((3, 3, 4, 5, 3), 7, dtype=np.uint8)
    >>> round(float(refocus(lf, 0.6).max()), 3)
    7.0
    """
    views = np.asarray(views)
    if views.ndim != 5 or views.shape[-1] != 3:
        raise LfsamError(f"views must be (S, T, U, V, 3), got shape {views.shape}")
    focus = clip_focus(focus, disparity_range)
    device = resolve_device("cpu" if device is None else device)
    chosen, offsets = select_views(views.shape[:2], present, aperture)
    images = views_tensor(views, chosen, device)
    total, weight = shift_and_add(images, offsets, focus, kernel=kernel)
    image = total / weight.clamp_min(1e-6)
    image = torch.where(weight > 1e-6, image, torch.zeros_like(image))
    return image.permute(1, 2, 0).clamp(0, 255).cpu().numpy().astype(np.float32)


def object_focus(mask: np.ndarray, disparity: np.ndarray) -> float:
    """The median disparity of an object in the center view (``--focus-on``).

    Parameters
    ----------
    mask : (U, V) bool array
        The object in the center view.
    disparity : (U, V) float array
        The center view's disparity.

    Raises
    ------
    LfsamError
        If the object is not seen in the center view or has no finite disparity there.
    """
    values = np.asarray(disparity)[np.asarray(mask, dtype=bool)]
    values = values[np.isfinite(values)]
    if values.size == 0:
        raise LfsamError("the object is not seen in the center view; give --focus instead")
    return float(np.median(values))
