"""Forward-warping the center view's disparity into another view.

Where only the center view's disparity is known (a center-only ground truth, a ``(U, V)`` file),
the disparity ``D_r`` of view ``r = (s_r, t_r)`` is obtained by *forward-warping* the center map:
center pixel ``p`` with disparity ``d`` is seen in view ``r`` at ``p - d (s_r - s_c, t_r - t_c)``
(docs/design.md section 1) and keeps its disparity there (a scene point has one disparity in every
view). Several center pixels landing on one pixel resolve by a z-buffer: the largest disparity
(the closest point) wins. Nearest-pixel splatting leaves cracks in stretched surfaces, through
which a farther surface would show: a pixel takes the nearest disparity among its 3 x 3
neighbours' that the center view *confirms* (it shows a surface of that disparity where the pixel
would be seen from the center) when that is clearly nearer than its own. Pixels still without a
value are holes: gaps of stretched surfaces, disocclusions (background the center view does not
see) and the strip entering at the frame border. Each hole takes the disparity of one of the
nearest landed pixels on either side of it along the epipolar line: a side the center view
confirms (it shows that surface where the hole would be seen from it: a stretched surface), else
the farther side, because a disocclusion shows what lies behind; at the frame border the one side
that exists.

:func:`lfsam.disparity.source.resolve_disparity` uses it for any view other than the center
(docs/design.md sections 3.2 and 8); it depends on no other part of the resolver.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from lfsam.disparity.epi import resolve_device
from lfsam.geometry import project_pixels

__all__ = ["warp_center_disparity"]

# A hole's candidate disparity is confirmed by the center view within this (pixels per view
# step): slanted surfaces change by far less across the one or two pixels a rounding moves.
_CONFIRM = 0.1


def _zbuffer(disparity: torch.Tensor, ds: float, dt: float) -> torch.Tensor:
    """Largest disparity landing on each pixel of the view at offset ``(ds, dt)``; ``-inf``
    where nothing lands (nearest-pixel forward warp)."""
    height, width = disparity.shape
    device = disparity.device
    rows = torch.arange(height, device=device, dtype=disparity.dtype)[:, None]
    cols = torch.arange(width, device=device, dtype=disparity.dtype)[None, :]
    target_u, target_v = project_pixels(rows, cols, disparity, ds, dt)
    iu = torch.round(target_u).long().reshape(-1)
    iv = torch.round(target_v).long().reshape(-1)
    inside = (iu >= 0) & (iu < height) & (iv >= 0) & (iv < width)
    zbuffer = torch.full((height * width,), -math.inf, device=device, dtype=disparity.dtype)
    zbuffer.scatter_reduce_(
        0, (iu * width + iv)[inside], disparity.reshape(-1)[inside], reduce="amax",
        include_self=True,
    )
    return zbuffer.view(height, width)


def _confirmed(
    candidate: torch.Tensor, center: torch.Tensor, ds: float, dt: float,
    rows: torch.Tensor | None = None, cols: torch.Tensor | None = None,
) -> torch.Tensor:
    """Where the center view confirms ``candidate`` (a disparity per view pixel ``q``, ``-inf``
    or ``inf`` for none): it shows a surface of that disparity (within :data:`_CONFIRM`) at
    ``q + d (ds, dt)``, where the view's pixel would be seen from the center.

    ``candidate`` is the whole view, or the values at the pixels ``(rows, cols)`` (float32)."""
    height, width = center.shape
    device = candidate.device
    if rows is None or cols is None:
        rows = torch.arange(height, device=device, dtype=torch.float32)[:, None]
        cols = torch.arange(width, device=device, dtype=torch.float32)[None, :]
    finite = torch.isfinite(candidate)
    d = torch.where(finite, candidate, torch.zeros_like(candidate))
    u = torch.round(rows + d * ds).long()
    v = torch.round(cols + d * dt).long()
    inside = (u >= 0) & (u < height) & (v >= 0) & (v < width)
    seen = center[u.clamp(0, height - 1), v.clamp(0, width - 1)]
    return finite & inside & ((seen - d).abs() <= _CONFIRM)


def _close_cracks(
    zbuffer: torch.Tensor, center: torch.Tensor, ds: float, dt: float
) -> torch.Tensor:
    """Nearest-pixel splatting leaves cracks in a stretched surface, through which a farther
    surface shows (or nothing lands). A pixel takes the nearest disparity among its 3 x 3
    neighbours' that the center view confirms (:func:`_confirmed`) when that is nearer than its
    own by more than :data:`_CONFIRM` (a crack); otherwise it keeps its own value. Only pixels
    with a neighbour that much nearer are looked at (no other can change)."""
    nearest = torch.nn.functional.max_pool2d(zbuffer[None, None], 3, stride=1, padding=1)[0, 0]
    rows, cols = torch.nonzero(nearest > zbuffer + _CONFIRM, as_tuple=True)
    if rows.numel() == 0:
        return zbuffer
    padded = torch.nn.functional.pad(zbuffer[None, None], (1, 1, 1, 1), value=-math.inf)[0, 0]
    own = zbuffer[rows, cols]
    best = torch.full_like(own, -math.inf)
    for du in range(3):
        for dv in range(3):
            candidate = padded[rows + du, cols + dv]
            ok = _confirmed(candidate, center, ds, dt, rows.float(), cols.float())
            best = torch.where(ok & (candidate > best), candidate, best)
    out = zbuffer.clone()
    out[rows, cols] = torch.where(best > own + _CONFIRM, best, own)
    return out


def _fill_holes(
    zbuffer: torch.Tensor, center: torch.Tensor, ds: float, dt: float, reach: int
) -> torch.Tensor:
    """Fill the ``-inf`` holes of ``zbuffer`` (the view at ``(ds, dt)`` from the center).

    Per hole, the nearest landed pixel on each side along the epipolar direction ``(ds, dt)`` is
    found (up to ``reach`` steps). A side's disparity ``d`` is *confirmed* when the center view
    shows that surface where the hole would be seen with ``d`` (``center`` within
    :data:`_CONFIRM` at ``q + d (ds, dt)``): the hole is then a gap of a stretched surface. Among
    confirmed sides the nearer wins (as in the z-buffer); with none confirmed (a disocclusion:
    the center sees neither surface there) the farther side wins, because a disocclusion shows
    what lies behind; one side only where the other leaves the frame. Holes that see nothing
    within ``reach`` take the smallest landed disparity. The work is done on the holes' pixels
    only."""
    height, width = zbuffer.shape
    landed = torch.isfinite(zbuffer)
    hole_rows, hole_cols = torch.nonzero(~landed, as_tuple=True)
    if hole_rows.numel() == 0:
        return zbuffer
    scale = max(abs(ds), abs(dt))
    step_u, step_v = ds / scale, dt / scale  # one pixel along the dominant axis per step
    rows, cols = hole_rows.float(), hole_cols.float()
    found = []
    for sign in (1.0, -1.0):
        value = torch.full_like(rows, math.inf)
        for k in range(1, reach + 1):
            u = torch.round(rows + sign * k * step_u).long()
            v = torch.round(cols + sign * k * step_v).long()
            inside = (u >= 0) & (u < height) & (v >= 0) & (v < width)
            sample = zbuffer[u.clamp(0, height - 1), v.clamp(0, width - 1)]
            new = inside & torch.isfinite(sample) & torch.isinf(value)
            value = torch.where(new, sample, value)
        found.append(value)
    confirmed = [_confirmed(value, center, ds, dt, rows, cols) for value in found]
    both = confirmed[0] & confirmed[1]
    farther = torch.minimum(found[0], found[1])
    filled = torch.where(
        both,
        torch.maximum(found[0], found[1]),
        torch.where(confirmed[0], found[0], torch.where(confirmed[1], found[1], farther)),
    )
    if bool(torch.isinf(filled).any()):
        filled = torch.where(torch.isinf(filled), zbuffer[landed].min(), filled)
    out = zbuffer.clone()
    out[hole_rows, hole_cols] = filled
    return out


def warp_center_disparity(
    center_disparity: np.ndarray | torch.Tensor,
    offset: tuple[float, float],
    *,
    device: str | torch.device | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Forward-warp the center view's disparity into the view at ``offset`` from the center.

    See the module docstring: nearest-pixel forward warp (docs/design.md section 1), z-buffer
    (largest disparity wins), holes filled along the epipolar line (from a side the center view
    confirms, else from the farther side).

    Parameters
    ----------
    center_disparity : (U, V) array or tensor
        Disparity of the center view (finite), package convention.
    offset : (ds, dt)
        View-row and view-column offset of the target view from the center view.
    device : str or torch.device, optional
        Where to compute; default CUDA when present, else the CPU.

    Returns
    -------
    disparity : (U, V) float32 ndarray
        The target view's disparity.
    holes : (U, V) bool ndarray
        Pixels on which no center pixel landed (their disparity was filled).
    """
    ds, dt = float(offset[0]), float(offset[1])
    disparity = torch.as_tensor(center_disparity).to(resolve_device(device)).float()
    if ds == 0 and dt == 0:
        flat = disparity.cpu().numpy()
        return flat.astype(np.float32), np.zeros(flat.shape, dtype=bool)
    zbuffer = _close_cracks(_zbuffer(disparity, ds, dt), disparity, ds, dt)
    holes = ~torch.isfinite(zbuffer)
    # the widest disocclusion: the disparity spread times the view distance, plus slack
    spread = float(disparity.max() - disparity.min())
    reach = math.ceil(spread * max(abs(ds), abs(dt))) + 2
    reach = min(reach, max(disparity.shape))
    filled = _fill_holes(zbuffer, disparity, ds, dt, reach)
    return filled.cpu().numpy().astype(np.float32), holes.cpu().numpy()
