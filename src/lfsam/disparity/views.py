"""Disparity of any view: forward-warping a center map, and a lazy per-view cache.

Prompts may be given in any view (docs/design.md section 8), and an object prompted in view
``r = (s_r, t_r)`` is propagated with the disparity ``D_r`` of that view. Where only the center
view's disparity is known (a center-only ground truth, a ``(U, V)`` file), ``D_r`` is obtained by
*forward-warping* the center map: center pixel ``p`` with disparity ``d`` is seen in view ``r`` at
``p - d (s_r - s_c, t_r - t_c)`` (docs/design.md section 1) and keeps its disparity there (a scene
point has one disparity in every view). Several center pixels landing on one pixel resolve by a
z-buffer: the largest disparity (the closest point) wins. Pixels on which nothing lands are holes:
disocclusions (background the center view does not see) and the strip entering at the frame
border. Each hole takes the disparity of the farther (smaller-disparity) of the nearest landed
pixels on either side of it along the epipolar line, because a disocclusion shows what lies
behind; at the frame border the one side that exists is used.

:class:`ViewDisparities` resolves the disparity of each view at most once, from any source
(:func:`lfsam.disparity.source.resolve_disparity`), for the interactive predictor.
"""

from __future__ import annotations

import math
import os

import numpy as np
import torch

from lfsam.disparity.epi import resolve_device, resolve_view
from lfsam.geometry import project_pixels
from lfsam.lightfield import LightField

__all__ = ["ViewDisparities", "warp_center_disparity"]


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


def _fill_from_farther_side(
    zbuffer: torch.Tensor, ds: float, dt: float, reach: int
) -> torch.Tensor:
    """Fill the ``-inf`` holes of ``zbuffer``: per hole, the nearest landed pixel on each side
    along the epipolar direction ``(ds, dt)`` is found (up to ``reach`` steps) and the smaller
    (farther) disparity of the two is taken; one side only where the other leaves the frame.
    Holes that see nothing within ``reach`` take the smallest landed disparity."""
    height, width = zbuffer.shape
    device = zbuffer.device
    landed = torch.isfinite(zbuffer)
    holes = ~landed
    if not bool(holes.any()):
        return zbuffer
    scale = max(abs(ds), abs(dt))
    step_u, step_v = ds / scale, dt / scale  # one pixel along the dominant axis per step
    rows = torch.arange(height, device=device, dtype=torch.float32)[:, None]
    cols = torch.arange(width, device=device, dtype=torch.float32)[None, :]
    found = []
    for sign in (1.0, -1.0):
        value = torch.full_like(zbuffer, math.inf)
        for k in range(1, reach + 1):
            u = torch.round(rows + sign * k * step_u).long().expand(height, width)
            v = torch.round(cols + sign * k * step_v).long().expand(height, width)
            inside = (u >= 0) & (u < height) & (v >= 0) & (v < width)
            sample = zbuffer[u.clamp(0, height - 1), v.clamp(0, width - 1)]
            new = inside & torch.isfinite(sample) & torch.isinf(value)
            value = torch.where(new, sample, value)
        found.append(value)
    filled = torch.minimum(found[0], found[1])
    if bool(torch.isinf(filled[holes]).any()):
        filled = torch.where(torch.isinf(filled), zbuffer[landed].min(), filled)
    return torch.where(holes, filled, zbuffer)


def warp_center_disparity(
    center_disparity: np.ndarray | torch.Tensor,
    offset: tuple[float, float],
    *,
    device: str | torch.device | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Forward-warp the center view's disparity into the view at ``offset`` from the center.

    See the module docstring: nearest-pixel forward warp (docs/design.md section 1), z-buffer
    (largest disparity wins), holes filled from the farther side along the epipolar line.

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
    zbuffer = _zbuffer(disparity, ds, dt)
    holes = ~torch.isfinite(zbuffer)
    # the widest disocclusion: the disparity spread times the view distance, plus slack
    spread = float(disparity.max() - disparity.min())
    reach = math.ceil(spread * max(abs(ds), abs(dt))) + 2
    reach = min(reach, max(disparity.shape))
    filled = _fill_from_farther_side(zbuffer, ds, dt, reach)
    return filled.cpu().numpy().astype(np.float32), holes.cpu().numpy()


class ViewDisparities:
    """The disparity of every view a caller asks for, resolved lazily and at most once per view.

    Parameters
    ----------
    lightfield : LightField
    spec : {"estimate", "gt"}, path to a .npy, or ndarray
        Any source :func:`lfsam.disparity.source.resolve_disparity` accepts. A file is read and
        checked once, here (so a bad file fails before any work).
    device : str, optional
        Where the estimator and the warps run.

    Examples
    --------
    >>> from lfsam.synth import generate_scene
    >>> lf = generate_scene(grid=(3, 3), size=(24, 32), num_objects=1)
    >>> views = ViewDisparities(lf, "gt")
    >>> views.get((0, 2)).shape, views.source((0, 2))
    ((24, 32), 'gt')
    """

    def __init__(
        self,
        lightfield: LightField,
        spec: str | os.PathLike | np.ndarray = "estimate",
        device: str | None = None,
    ) -> None:
        from lfsam.disparity.source import load_disparity_spec

        self.lightfield = lightfield
        self.device = device
        # a file becomes its (checked) array once; "estimate" and "gt" stay as they are
        self._spec, self._name = load_disparity_spec(spec, lightfield)
        self._cache: dict[tuple[int, int], tuple[np.ndarray, str, np.ndarray | None]] = {}

    def _resolve(self, view: tuple[int, int] | None) -> tuple[np.ndarray, str, np.ndarray | None]:
        from lfsam.disparity.source import resolve_view_disparity

        key = resolve_view(self.lightfield.grid_shape, view)
        if key not in self._cache:
            disparity, source, holes = resolve_view_disparity(
                self._spec, self.lightfield, view=key, device=self.device, name=self._name
            )
            disparity = np.array(disparity, dtype=np.float32)
            disparity.flags.writeable = False
            self._cache[key] = (disparity, source, holes)
        return self._cache[key]

    def get(self, view: tuple[int, int] | None = None) -> np.ndarray:
        """Disparity of ``view`` (default the center), ``(U, V)`` float32, read-only."""
        return self._resolve(view)[0]

    def source(self, view: tuple[int, int] | None = None) -> str:
        """Where the disparity of ``view`` came from (for result metadata)."""
        return self._resolve(view)[1]

    def holes(self, view: tuple[int, int] | None = None) -> np.ndarray | None:
        """Pixels of ``view`` whose disparity was filled after a forward warp (None if none
        was warped)."""
        return self._resolve(view)[2]

    @property
    def resolved(self) -> list[tuple[int, int]]:
        """The views resolved so far."""
        return list(self._cache)
