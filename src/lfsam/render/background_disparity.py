"""The disparity of what lies behind objects (docs/design.md section 13).

Never the object's own disparity: behind an object, the surface its rim shows continues. In the
center view, the disparity estimated from the views is kept wherever the objects are not (their
masks grown by a few pixels, where estimates bleed across the edge) and filled inside from
around: a plane fitted robustly to the rim behind the object, plus OpenCV's inpainting of what
departs from it (:mod:`lfsam.render.inpaint`): a plane behind the object is filled exactly.
Any other view gets the center's disparity forward-warped into it (its own rim, even where
nearer objects hide the background from the center view), filled in its own object pixels
the same way.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import torch
import torch.nn.functional as F
from scipy.ndimage import distance_transform_edt
from tqdm import tqdm

from lfsam.devices import resolve_device, view_workers
from lfsam.disparity import warp_center_disparity
from lfsam.render.inpaint import inpaint

__all__ = ["background_center", "dilate", "rim_disparity", "rim_surfaces", "view_backgrounds"]

#: Pixels by which the object masks grow before their disparity is replaced.
GAP = 2
#: Disparity above the object's (95th percentile) that marks a nearer surface, pixels.
NEARER = 0.1
#: Width of the ring around an object from which the surface behind it is fitted, pixels.
RING = 6
#: Most surfaces (planes) the rim behind an object is split into.
SURFACES = 3
#: Fewest rim pixels of a further surface, as a share of the rim behind the object.
SURFACE_SHARE = 0.1
#: Largest departure of a rim pixel from its surface's plane, pixels per view step.
ON_PLANE = 0.1
#: Bin width of the rim's disparity histogram whose mode seeds each surface, and the reach
#: around it of the pixels the surface's plane is first fitted to (pixels per view step).
SEED_BIN = 0.1
SEED_REACH = 0.3
#: Distance from its rim within which a surface may continue behind the object, pixels.
REACH = 12


def dilate(masks: torch.Tensor, radius: int) -> torch.Tensor:
    """Bool masks ``(..., U, V)`` grown by ``radius`` pixels (a square neighbourhood: a
    maximum along the rows, then along the columns)."""
    if radius <= 0:
        return masks.bool()
    shape = masks.shape
    flat = masks.reshape(-1, 1, *shape[-2:]).float()
    size = 2 * radius + 1
    grown = F.max_pool2d(flat, (1, size), stride=1, padding=(0, radius))
    grown = F.max_pool2d(grown, (size, 1), stride=1, padding=(radius, 0))
    return grown.reshape(shape) > 0.5


def rim_disparity(mask: np.ndarray, disparity: np.ndarray, width: int = 3) -> float | None:
    """The disparity of the surface an object's rim shows (median of a ring around it).

    Ring pixels nearer than the object (larger disparity than its median) are left out: they
    are in front of it, not behind. None for an empty mask or ring.
    """
    mask_t = torch.from_numpy(np.asarray(mask, dtype=bool))
    if not mask_t.any():
        return None
    ring = dilate(mask_t, GAP + width) & ~dilate(mask_t, GAP)
    disparity = np.asarray(disparity, dtype=np.float32)
    values = disparity[ring.numpy()]
    inside = disparity[np.asarray(mask, dtype=bool)]
    inside = inside[np.isfinite(inside)]
    values = values[np.isfinite(values)]
    if inside.size:
        behind = values[values < np.median(inside)]
        values = behind if behind.size else values
    return float(np.median(values)) if values.size else None


def background_center(disparity: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The center view's disparity with the objects of ``mask`` taken out (filled from around).

    Parameters
    ----------
    disparity : (U, V) float array
        The center view's disparity (estimated from the views, or ground truth).
    mask : (U, V) bool array
        The objects in the center view.

    Returns
    -------
    (U, V) float32 array
    """
    disparity = np.asarray(disparity, dtype=np.float32)
    mask = np.asarray(mask, dtype=bool)
    hole_t = dilate(torch.from_numpy(mask), GAP)
    hole = hole_t.numpy() | ~np.isfinite(disparity)
    if not hole.any():
        return disparity.copy()
    plane = _rim_plane(disparity, mask, hole)
    # What lies in front of the object around it (nearer objects) is not what lies behind it:
    # left out of the fill as well.
    inside = disparity[mask & np.isfinite(disparity)]
    unknown = hole.copy()
    if inside.size:
        near = dilate(torch.from_numpy(hole), RING).numpy() & (disparity >= np.median(inside))
        unknown |= near
    residual = np.where(unknown, 0.0, disparity - plane).astype(np.float32)
    filled = plane + inpaint(residual, unknown)
    if inside.size:  # the grown mask's pixels of nearer objects keep their own disparity
        hole &= ~(disparity > np.percentile(inside, 95) + NEARER)
    return np.where(hole, filled, disparity).astype(np.float32)


def _rim_plane(disparity: np.ndarray, mask: np.ndarray, hole: np.ndarray) -> np.ndarray:
    """A plane ``a + b u + c v`` fitted robustly to the ring around ``hole`` that lies behind
    the object (disparity below the object's median), evaluated everywhere.

    Inpainting the residual from it (:func:`background_center`) fills a planar surface behind
    the object exactly, and follows the rim's own values where the rim shows several surfaces.
    """
    height, width = disparity.shape
    ring = (dilate(torch.from_numpy(hole), RING).numpy() & ~hole) & np.isfinite(disparity)
    inside = disparity[mask & np.isfinite(disparity)]
    if inside.size:
        behind = ring & (disparity < np.median(inside))
        ring = behind if behind.sum() >= 3 else ring
    rows, cols = np.nonzero(ring)
    if rows.size < 3:
        value = float(np.median(disparity[ring])) if rows.size else 0.0
        return np.full((height, width), value, dtype=np.float32)
    coef = _robust_plane(rows, cols, disparity[rows, cols])
    uu, vv = np.mgrid[0:height, 0:width]
    return (coef[0] + coef[1] * uu + coef[2] * vv).astype(np.float32)


def _robust_plane(rows: np.ndarray, cols: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``(a, b, c)`` of ``a + b u + c v`` by least squares, 4 rounds dropping the points above
    3 median errors (0.02 at least)."""
    design = np.stack([np.ones(rows.size), rows, cols], axis=1).astype(np.float64)
    values = values.astype(np.float64)
    use = np.ones(rows.size, dtype=bool)
    for _ in range(4):  # least squares, dropping the rim of other surfaces
        coef = np.linalg.lstsq(design[use], values[use], rcond=None)[0]
        error = np.abs(design @ coef - values)
        spread = max(float(np.median(error[use])) * 3.0, 0.02)
        use = error <= spread
        if use.sum() < 3:
            break
    return coef


def rim_surfaces(disparity: np.ndarray, mask: np.ndarray, grown: int = GAP,
                 surfaces: int = SURFACES) -> tuple[np.ndarray, np.ndarray]:
    """The surfaces that the rim behind an object shows, as planes ``(K, 3)``: ``a + b u + c v``.

    The ring of :data:`RING` pixels around the object's mask (grown by ``grown``) behind the
    object (disparity below its median) is split into planes one by one: a plane is fitted
    robustly, the rim pixels within :data:`ON_PLANE` of it are taken out, and the rest is
    fitted again while at least :data:`SURFACE_SHARE` of the rim is left (at most
    ``surfaces`` planes); each fit starts from the rim pixels near the most common
    disparity left. What lies behind an object is one of these surfaces (continued), e.g.
    the wall and the edge of a box partly behind it; estimates that bleed across an edge fit
    none of them.

    Parameters
    ----------
    disparity : (U, V) float array
    mask : (U, V) bool array
        The object.

    Returns
    -------
    planes : (K, 3) float64 array
        K <= ``surfaces`` (0 when the rim has under 3 pixels).
    near : (K, U, V) bool array
        The pixels within :data:`REACH` of each surface's rim pixels: where it may continue
        behind the object.
    """
    disparity = np.asarray(disparity, dtype=np.float32)
    mask = np.asarray(mask, dtype=bool)
    hole = dilate(torch.from_numpy(mask), grown).numpy()
    ring = (dilate(torch.from_numpy(hole), RING).numpy() & ~hole) & np.isfinite(disparity)
    inside = disparity[mask & np.isfinite(disparity)]
    if inside.size:
        ring &= disparity < np.median(inside)
    rows, cols = np.nonzero(ring)
    values = disparity[rows, cols]
    planes = []
    owner = np.full(disparity.shape, -1, dtype=np.int64)
    least = max(3, int(np.ceil(SURFACE_SHARE * rows.size)))
    while rows.size >= least and len(planes) < surfaces:
        # Seeded at the most common disparity (bins of SEED_BIN), so that a fit never settles
        # between two surfaces of about the same size.
        bins = np.floor(values / SEED_BIN).astype(np.int64)
        labels, counts = np.unique(bins, return_counts=True)
        mode = (labels[np.argmax(counts)] + 0.5) * SEED_BIN
        seed = np.abs(values - mode) <= SEED_REACH
        if seed.sum() < 3:
            break
        coef = _robust_plane(rows[seed], cols[seed], values[seed])
        on = np.abs(coef[0] + coef[1] * rows + coef[2] * cols - values) <= ON_PLANE
        if on.sum() < least:
            break
        owner[rows[on], cols[on]] = len(planes)
        planes.append(coef)
        rows, cols, values = rows[~on], cols[~on], values[~on]
    near = np.zeros((len(planes), *disparity.shape), dtype=bool)
    if planes:  # within REACH of each surface's rim pixels, over the rim's box
        ring_rows, ring_cols = np.nonzero(ring)
        height, width = disparity.shape
        top, left = max(0, ring_rows.min() - REACH), max(0, ring_cols.min() - REACH)
        bottom = min(height, ring_rows.max() + REACH + 1)
        right = min(width, ring_cols.max() + REACH + 1)
        box = owner[top:bottom, left:right]
        for k in range(len(planes)):
            near[k, top:bottom, left:right] = distance_transform_edt(box != k) <= REACH
    return np.array(planes, dtype=np.float64).reshape(-1, 3), near


def view_backgrounds(
    center: np.ndarray, masks: np.ndarray, offsets: torch.Tensor,
    device: str | torch.device | None = None, *, with_surfaces: bool = False,
    progress: bool = False,
) -> torch.Tensor | tuple[torch.Tensor, list[tuple[np.ndarray, np.ndarray]]]:
    """The background disparity of every view: the center's disparity carried into the view
    (:func:`lfsam.disparity.warp_center_disparity`: z-buffer, disocclusions filled from the
    farther side), the view's own object pixels then filled from its own rim
    (:func:`background_center`). Each view's rim shows what lies behind the object there, even
    where nearer objects hide it from the center view.

    Parameters
    ----------
    center : (U, V) float array
        The center view's disparity (estimated from the views, or ground truth).
    masks : (N, U, V) bool array
        The objects in each view.
    offsets : (N, 2) tensor
        ``(ds, dt)`` of each view from the center view.
    device : str or torch.device, optional
        Where the warps run.
    with_surfaces : bool
        Also return each view's rim surfaces (:func:`rim_surfaces`).
    progress : bool
        Show a progress bar over the views.

    Returns
    -------
    (N, U, V) float32 tensor
        And, with ``with_surfaces``, a list of ``(planes, near)`` pairs, one per view.
    """
    center = np.asarray(center, dtype=np.float32)
    finite = np.where(np.isfinite(center), center, np.nanmin(center[np.isfinite(center)]))

    pairs = torch.as_tensor(offsets).tolist()

    def one(k: int) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
        ds, dt = pairs[k]
        view = finite if ds == 0 and dt == 0 else warp_center_disparity(
            finite, (ds, dt), device=device)[0]
        filled = view.copy()
        planes = np.zeros((0, 3))
        near = np.zeros((0, *view.shape), dtype=bool)
        box = _box(masks[k], GAP + RING + REACH + 2)
        if box is not None:  # the work is done on a box around the object, not the view
            rows, cols = box
            filled[rows, cols] = background_center(view[rows, cols], masks[k][rows, cols])
            if with_surfaces:
                planes, inside = rim_surfaces(view[rows, cols], masks[k][rows, cols])
                # the box's plane coefficients in the view's coordinates
                planes[:, 0] -= planes[:, 1] * rows.start + planes[:, 2] * cols.start
                near = np.zeros((len(planes), *view.shape), dtype=bool)
                near[:, rows, cols] = inside
        return filled, (planes, near)

    with ThreadPoolExecutor(max_workers=view_workers(resolve_device(device))) as pool:
        done = list(tqdm(pool.map(one, range(len(pairs))), total=len(pairs),
                         desc="background disparity", unit="view",
                         disable=not progress or None, leave=False))
    out = [filled for filled, _ in done]
    surfaces = [surface for _, surface in done]
    depth = torch.from_numpy(np.stack(out))
    return (depth, surfaces) if with_surfaces else depth


def _box(mask: np.ndarray, margin: int) -> tuple[slice, slice] | None:
    """The rows and columns of ``mask``'s bounding box grown by ``margin`` (None: empty)."""
    rows = np.nonzero(np.asarray(mask).any(1))[0]
    if rows.size == 0:
        return None
    cols = np.nonzero(np.asarray(mask).any(0))[0]
    height, width = np.asarray(mask).shape
    return (slice(max(0, rows[0] - margin), min(height, rows[-1] + margin + 1)),
            slice(max(0, cols[0] - margin), min(width, cols[-1] + margin + 1)))
