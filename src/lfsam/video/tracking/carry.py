"""Carrying an object from one frame to the next in its reference view (docs/design.md
section 10), for segmenters without memory (the oracle, SAM 2's image model).

The object's last mask and the pixels under it (the *template*) are matched against the new
frame's reference view by masked sum of squared differences over integer shifts (three FFT
correlations, :func:`locate`): the shift with the lowest mean squared difference per
overlapping pixel wins; part of the template may fall outside the frame (objects leaving or
coming back through the border). The shifted mask, kept where the new pixels still look like
the template (not covered by something that moved in front), gives the prompt: a positive
point at its deepest pixel (away from negative clicks given in that frame), and a box around
the shifted mask widened by a margin. The search of issue 47 (:mod:`lfsam.video.tracking.search`)
prompts with :func:`positive_points` (several, apart) and :func:`neighbour_points` (negative
points on objects placed earlier) and compares colours with :func:`looks_alike`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage, signal

__all__ = [
    "Carried", "Template", "carry", "cost_map", "locate", "looks_alike", "masked_cost",
    "neighbour_points", "positive_points", "search_window", "shifted", "window_within",
]

#: Fraction of the carried mask (inside the frame) that must still look like the template.
MIN_SUPPORT = 0.5
#: Per-pixel RGB distance (summed over channels) under which a pixel still looks the same.
MAX_PIXEL_DIFFERENCE = 60.0
#: Fewest matching pixels an object needs to be carried.
MIN_PIXELS = 12


@dataclass(frozen=True)
class Template:
    """An object's look in its reference view: the mask's bounding crop of the image."""

    image: np.ndarray  # (h, w, 3) float32
    mask: np.ndarray  # (h, w) bool
    origin: tuple[int, int]  # (row, column) of the crop's top-left pixel

    @classmethod
    def from_mask(cls, image: np.ndarray, mask: np.ndarray) -> Template | None:
        """The template of ``mask`` (None when it is empty)."""
        rows, cols = np.nonzero(mask)
        if rows.size == 0:
            return None
        r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
        return cls(image[r0:r1, c0:c1].astype(np.float32), mask[r0:r1, c0:c1].copy(),
                   (int(r0), int(c0)))


@dataclass(frozen=True)
class Carried:
    """Where an object is in the new frame."""

    point: tuple[float, float]  # (x, y): column, row
    box: tuple[float, float, float, float]  # x0, y0, x1, y1
    mask: np.ndarray  # (U, V) bool: the shifted template mask, clipped to the frame
    cost: float


def cost_map(template: Template, image: np.ndarray, radius: int | None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The masked mean squared difference of ``template`` at every integer shift within
    ``radius`` pixels of its place (None: every shift where it overlaps the frame); inf where
    it overlaps the frame by less than :data:`MIN_PIXELS` and a fifth of its mask.

    Returns
    -------
    cost : (H, W) float array
    du, dv : (H, W) int arrays
        The shift of each entry.
    """
    region, valid, margins = search_window(template, image, radius)
    m = template.mask.astype(np.float32)
    a = template.image * m[..., None]

    def corr(x: np.ndarray, k: np.ndarray) -> np.ndarray:
        return signal.correlate(x, k, mode="valid", method="fft")

    count = corr(valid, m)
    cross = sum(corr(region[..., c], a[..., c]) for c in range(region.shape[-1]))
    energy = corr((region**2).sum(-1), m)
    own = corr(valid, (a**2).sum(-1))
    return masked_cost(own, cross, energy, count, float(m.sum()), margins)


def search_window(template: Template, image: np.ndarray, radius: int | None
                  ) -> tuple[np.ndarray, np.ndarray, tuple[int, int, int, int]]:
    """The region of ``image`` that ``template`` can land on within ``radius`` pixels of its
    place (None: anywhere it overlaps the frame), zero-padded outside the frame.

    Returns
    -------
    region : (rh, rw, C) float32 array
    valid : (rh, rw) float32 array
        1 inside the frame, 0 in the padding.
    margins : (top, left, bottom, right)
        The reach of the shifts upwards, leftwards, downwards and rightwards.
    """
    height, width = image.shape[:2]
    h, w = template.mask.shape
    r0, c0 = template.origin
    if radius is None:
        margins = (r0 + h, c0 + w, height - r0, width - c0)
    else:
        margins = (int(radius),) * 4
    return window_within(template, image, margins)


def window_within(template: Template, image: np.ndarray,
                  margins: tuple[int, int, int, int]
                  ) -> tuple[np.ndarray, np.ndarray, tuple[int, int, int, int]]:
    """The region of ``image`` that ``template`` can land on with shifts reaching
    ``margins`` = (top, left, bottom, right) pixels from its place, zero-padded outside the
    frame (:func:`search_window`'s window, for any reach)."""
    height, width = image.shape[:2]
    h, w = template.mask.shape
    top, left, bottom, right = margins
    region_r0, region_c0 = template.origin[0] - top, template.origin[1] - left
    rh, rw = h + top + bottom, w + left + right
    region = np.zeros((rh, rw, image.shape[-1]), np.float32)
    valid = np.zeros((rh, rw), np.float32)
    sr0, sc0 = max(region_r0, 0), max(region_c0, 0)
    sr1, sc1 = min(region_r0 + rh, height), min(region_c0 + rw, width)
    if sr1 > sr0 and sc1 > sc0:
        region[sr0 - region_r0:sr1 - region_r0, sc0 - region_c0:sc1 - region_c0] = (
            image[sr0:sr1, sc0:sc1])
        valid[sr0 - region_r0:sr1 - region_r0, sc0 - region_c0:sc1 - region_c0] = 1.0
    return region, valid, margins


def masked_cost(own: np.ndarray, cross: np.ndarray, energy: np.ndarray, count: np.ndarray,
                mask_pixels: float, margins: tuple[int, int, int, int]
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The masked mean squared difference ``(own - 2 cross + energy) / count`` from its
    correlation terms, inf where the overlap is under :data:`MIN_PIXELS` and a fifth of the
    mask's ``mask_pixels``, with the shift ``(du, dv)`` of each entry (``margins`` from
    :func:`search_window`)."""
    top, left, bottom, right = margins
    with np.errstate(invalid="ignore", divide="ignore"):
        cost = (own - 2 * cross + energy) / count
    needed = max(MIN_PIXELS, 0.2 * mask_pixels)
    cost[count < needed - 0.5] = np.inf
    du, dv = np.mgrid[-top:bottom + 1, -left:right + 1]
    return cost, du, dv


def locate(template: Template, image: np.ndarray, radius: int | None) -> tuple[int, int, float]:
    """The shift ``(du, dv)`` of ``template`` into ``image`` with the least masked mean
    squared difference, searched within ``radius`` pixels of its place (None: anywhere the
    template overlaps the frame by at least :data:`MIN_PIXELS` and a fifth of its mask).

    Returns
    -------
    du, dv : int
    cost : float
        Mean squared RGB difference per overlapping pixel (inf when nothing qualifies).
    """
    cost, du, dv = cost_map(template, image, radius)
    if not np.isfinite(cost).any():
        return 0, 0, float("inf")
    order = np.lexsort((np.abs(du).ravel() + np.abs(dv).ravel(), cost.ravel()))
    best = order[0]
    return int(du.ravel()[best]), int(dv.ravel()[best]), float(cost.ravel()[best])


def shifted(template: Template, image: np.ndarray, du: int, dv: int
            ) -> tuple[np.ndarray, np.ndarray] | None:
    """``template``'s mask shifted by ``(du, dv)`` into the frame of ``image`` (clipped) and
    its *support*: the pixels of it that still look like the template (not covered by
    something in front). None when it falls outside the frame."""
    height, width = image.shape[:2]
    h, w = template.mask.shape
    r0, c0 = template.origin[0] + du, template.origin[1] + dv
    tr0, tc0 = max(-r0, 0), max(-c0, 0)
    ir0, ic0 = max(r0, 0), max(c0, 0)
    ir1, ic1 = min(r0 + h, height), min(c0 + w, width)
    if ir1 <= ir0 or ic1 <= ic0:
        return None
    mask = np.zeros((height, width), bool)
    support = np.zeros((height, width), bool)
    sub = template.mask[tr0:tr0 + ir1 - ir0, tc0:tc0 + ic1 - ic0]
    look = template.image[tr0:tr0 + ir1 - ir0, tc0:tc0 + ic1 - ic0]
    mask[ir0:ir1, ic0:ic1] = sub
    same = np.abs(image[ir0:ir1, ic0:ic1] - look).sum(-1) < MAX_PIXEL_DIFFERENCE
    support[ir0:ir1, ic0:ic1] = sub & same
    return mask, support


def deepest(seeds: np.ndarray) -> tuple[int, int, float]:
    """``(row, col, depth)`` of the pixel of ``seeds`` farthest from its border."""
    depth = ndimage.distance_transform_edt(np.pad(seeds, 1))[1:-1, 1:-1]
    row, col = np.unravel_index(int(np.argmax(depth)), depth.shape)
    return int(row), int(col), float(depth[row, col])


def box_around(mask: np.ndarray, margin: float) -> tuple[float, float, float, float]:
    """``(x0, y0, x1, y1)`` around ``mask`` widened by ``margin`` of its size plus 2 pixels,
    clipped to the frame."""
    height, width = mask.shape
    rows, cols = np.nonzero(mask)
    margin_r = 2 + margin * (rows.max() - rows.min() + 1)
    margin_c = 2 + margin * (cols.max() - cols.min() + 1)
    return (
        float(max(cols.min() - margin_c, 0)), float(max(rows.min() - margin_r, 0)),
        float(min(cols.max() + margin_c, width - 1)), float(min(rows.max() + margin_r, height - 1)),
    )


def carry(template: Template, image: np.ndarray, radius: int | None,
          box_margin: float = 0.15,
          avoid: tuple[tuple[float, float], ...] = ()) -> Carried | None:
    """Prompts for the object of ``template`` in ``image`` (None: not found, e.g. hidden or
    out of the frame).

    ``avoid`` holds ``(x, y)`` negative clicks the user gave in this frame: the positive point
    is the supported pixel farthest from the mask's border *and* from them (a correction that
    removes part of the carried mask must not be answered by a point on that part).
    """
    image = image.astype(np.float32)
    du, dv, cost = locate(template, image, radius)
    if not np.isfinite(cost):
        return None
    height, width = image.shape[:2]
    placed = shifted(template, image, du, dv)
    if placed is None:
        return None
    mask, support = placed
    if support.sum() < max(MIN_PIXELS, MIN_SUPPORT * mask.sum()):
        return None
    seeds = support.copy()
    for x, y in avoid:
        row, col = round(y), round(x)
        if 0 <= row < height and 0 <= col < width:
            seeds[row, col] = False
    row, col, _ = deepest(seeds)
    return Carried((float(col), float(row)), box_around(mask, box_margin), mask, cost)


def positive_points(support: np.ndarray, count: int = 3) -> list[tuple[float, float]]:
    """Up to ``count`` ``(x, y)`` points at the deepest supported pixels, apart."""
    rows, cols = np.nonzero(support)
    if rows.size == 0:
        return []
    r0, c0 = rows.min(), cols.min()
    seeds = support[r0:rows.max() + 1, c0:cols.max() + 1].copy()
    grid_r, grid_c = np.indices(seeds.shape)
    points: list[tuple[float, float]] = []
    for _ in range(count):
        if not seeds.any():
            break
        row, col, depth = deepest(seeds)
        if points and depth < 2.5:
            break
        points.append((float(col + c0), float(row + r0)))
        seeds &= (grid_r - row) ** 2 + (grid_c - col) ** 2 > (2 * max(depth, 2.0)) ** 2
    return points


def neighbour_points(carried: np.ndarray, support: np.ndarray, placed_ids: np.ndarray | None
                      ) -> list[tuple[float, float]]:
    """A negative ``(x, y)`` point on each object placed earlier that touches ``carried``."""
    if placed_ids is None or not carried.any():
        return []
    rows, cols = np.nonzero(carried)
    r0, c0 = max(rows.min() - 5, 0), max(cols.min() - 5, 0)
    crop = (slice(r0, rows.max() + 6), slice(c0, cols.max() + 6))
    near = ndimage.binary_dilation(carried[crop], iterations=4)  # the same, in its crop
    points = []
    for other in np.unique(placed_ids[crop][near]):
        if other == 0:
            continue
        region = (placed_ids == other) & ~support
        if region.sum() >= MIN_PIXELS:
            rows, cols = np.nonzero(region)  # the deepest pixel found in the region's crop
            r0, c0 = rows.min(), cols.min()
            row, col, _ = deepest(region[r0:rows.max() + 1, c0:cols.max() + 1])
            points.append((float(col + c0), float(row + r0)))
    return points


def looks_alike(a: np.ndarray, b: np.ndarray, bins: int = 6) -> float:
    """Intersection of the joint RGB histograms of two pixel sets ``(N, 3)`` (1: equal)."""
    if len(a) == 0 or len(b) == 0:
        return 0.0

    def hist(x: np.ndarray) -> np.ndarray:
        q = np.clip((x.astype(np.float64) * bins / 256.0).astype(int), 0, bins - 1)
        h = np.bincount((q[:, 0] * bins + q[:, 1]) * bins + q[:, 2], minlength=bins**3)
        return h / h.sum()

    return float(np.minimum(hist(a), hist(b)).sum())
