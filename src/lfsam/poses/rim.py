"""Which pixels of a mask a pose may trust (issue 64; docs/design.md section 12, "Imperfect
masks").

No segmenter gives an exact mask: a trained SAM's boundary, or the oracle's ``--oracle-jitter``,
is off by a pixel or two, so a mask's rim carries pixels of what lies behind or in front of the
object. Lifted to 3D those pixels are points of the wall or of the occluder; fed to the
registration they pull the motion towards the static background (a turning box reported as
barely turning). The light field tells them apart without knowing which way the mask is off:

- **behind a jump**: a rim pixel that is not the object lies behind it, across a jump in
  depth (the wall behind a mask grown too wide). A pixel with a pixel within
  :attr:`RimOptions.jump_px` that is nearer by more than :attr:`RimOptions.jump` (relative: a
  share of the absolute disparity, the camera's zero-disparity offset added, i.e. of depth) is
  not trusted (nor, rightly, the object's own pixels next to a nearer occluder);
- **the mask's interior**: a pixel closer than :attr:`RimOptions.inside_px` to another label
  (another object, or none) is not trusted either, where the background lies at the object's
  own depth (a box on a table: no jump marks the rim), *unless* it is the near side of a jump
  within that distance: the object's own silhouette against what lies behind it, whose points
  carry the object's edges (left out, a box's faces slid by up to 1.9 degrees on a held-out
  seed with exact masks).

:func:`trusted_labels` returns the label field with the untrusted pixels set to 0; the pose
tracker lifts and matches only the rest (:class:`lfsam.poses.PoseTracker`). Both tests are
separable minimum/maximum filters over the whole view (vectorised, no per-object loop).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

__all__ = ["RimOptions", "covered_share", "trusted_labels"]

_SQUARE = np.ones((3, 3), bool)


@dataclass(frozen=True)
class RimOptions:
    """How much of a mask's rim :func:`trusted_labels` leaves out (module docstring).

    Attributes
    ----------
    inside_px : int
        A pixel this close (Chebyshev distance, pixels) to another label is not trusted unless
        it is the near side of a depth jump within that distance (the object's silhouette): a
        mask off by up to this many pixels adds no foreign pixel where no jump marks the rim.
        0 turns the test off.
    jump_px : int
        A pixel with a pixel this close that is nearer by a depth jump (it lies behind an
        edge) is not trusted. 0 turns the test off.
    jump : float
        A depth jump: a difference in absolute disparity (disparity plus the zero-disparity
        offset, proportional to inverse depth) above this share of the pixel's own (0.05: 5 cm
        at 1 m; a box face seen at 70 degrees changes by under 2 % across 5 pixels at 1 m and
        f = 400 px).
    min_left : float
        Where the tests would leave an object fewer than this share of its pixels in a view (a
        thin or far object), its mask there is kept whole: few points are worse than a rim.
    """

    inside_px: int = 2
    jump_px: int = 1
    jump: float = 0.05
    min_left: float = 0.25


def trusted_labels(labels: np.ndarray, disparity: np.ndarray,
                   options: RimOptions | None = None, *,
                   zero_disparity_offset: float = 0.0) -> np.ndarray:
    """``labels`` with the pixels of each mask's rim that a pose must not trust set to 0
    (module docstring).

    Parameters
    ----------
    labels : (U, V) int array
        A view's label field (0 = none).
    disparity : (U, V) float array
        The view's disparity (non-finite values count as jumps).
    options : RimOptions, optional
    zero_disparity_offset : float
        :attr:`lfsam.camera.Camera.zero_disparity_offset`: ``disparity`` plus it is
        proportional to inverse depth, so a jump's share of it is a share of depth.

    Returns
    -------
    (U, V) array of ``labels``' dtype

    Examples
    --------
    A square mask one pixel too wide over a farther wall: its wrong ring goes, the object's own
    pixels (its silhouette included) stay.

    >>> labels = np.zeros((9, 9), int); labels[1:8, 1:8] = 1
    >>> disparity = np.full((9, 9), 2.0); disparity[2:7, 2:7] = 4.0
    >>> kept = trusted_labels(labels, disparity, RimOptions(inside_px=1, jump_px=1))
    >>> int((kept == 1).sum()), bool(kept[1].any())
    (25, False)
    """
    opts = options or RimOptions()
    labels = np.asarray(labels)
    trusted = labels != 0
    d = np.asarray(disparity, dtype=np.float64) + zero_disparity_offset  # ~ inverse depth
    finite = np.isfinite(d)
    if opts.jump_px > 0:
        # behind a nearer neighbour by a jump: the far side of an edge (a wall pixel in a mask
        # grown past the object, the object's own pixels next to an occluder)
        nearest = ndimage.maximum_filter(np.where(finite, d, np.inf), size=2 * opts.jump_px + 1,
                                         mode="nearest")
        with np.errstate(invalid="ignore"):
            trusted &= finite & ~(nearest - d > opts.jump * np.abs(d))
    if opts.inside_px > 0:
        size = 2 * opts.inside_px + 1
        other = ((ndimage.minimum_filter(labels, size=size, mode="nearest") != labels)
                 | (ndimage.maximum_filter(labels, size=size, mode="nearest") != labels))
        # the near side of an edge is the object's own silhouette against what lies behind it
        farthest = ndimage.minimum_filter(np.where(finite, d, -np.inf), size=size,
                                          mode="nearest")
        with np.errstate(invalid="ignore"):
            silhouette = d - farthest > opts.jump * np.abs(d)
        trusted &= ~other | silhouette
    out = np.where(trusted, labels, 0).astype(labels.dtype, copy=False)
    if opts.min_left > 0:
        total = np.bincount(labels.ravel().clip(0))
        left = np.bincount(out.ravel().clip(0), minlength=len(total))
        thin = np.flatnonzero((total > 0) & (left < opts.min_left * total))
        thin = thin[thin != 0]
        if len(thin):
            restore = np.isin(labels, thin)
            out[restore] = labels[restore]
    return out


def covered_share(labels: np.ndarray, disparity: np.ndarray, options: RimOptions | None = None,
                  *, zero_disparity_offset: float = 0.0,
                  object_ids: list[int] | None = None) -> dict[int, float]:
    """Per label, the share of the ring just outside its mask (pixels within 2
    :attr:`RimOptions.inside_px` + :attr:`RimOptions.jump_px` of it, Chebyshev: past a mask
    eroded by :attr:`RimOptions.inside_px`) that lies nearer than the
    object by a jump (:attr:`RimOptions.jump` of its median absolute disparity): 0 for an
    object seen whole against what lies behind it, high for one partly covered by a nearer
    object, whichever way its mask is a pixel or two off (issue 64; docs/design.md section 12,
    "Poses through occlusions"). ``object_ids``: only these labels (default every one in
    ``labels``).

    Examples
    --------
    A square partly covered by a nearer bar, its mask one pixel too wide over the bar: the ring
    beside the bar is nearer, the rest is the farther wall.

    >>> labels = np.zeros((16, 16), int); labels[4:12, 4:11] = 1
    >>> disparity = np.full((16, 16), 1.0); disparity[4:12, 4:12] = 2.0
    >>> disparity[:, 10:13] = 4.0
    >>> round(covered_share(labels, disparity, RimOptions(inside_px=2, jump_px=1))[1], 2)
    0.2
    """
    opts = options or RimOptions()
    labels = np.asarray(labels)
    d = np.asarray(disparity, dtype=np.float64) + zero_disparity_offset
    # a mask eroded by inside_px still reaches past its object's own pixels into the cover
    reach = max(2 * opts.inside_px + opts.jump_px, 1)
    out = {}
    for label in np.unique(labels) if object_ids is None else object_ids:
        if label == 0:
            continue
        mask = labels == label
        own = d[mask & np.isfinite(d)]
        if not len(own):
            continue
        level = float(np.median(own))
        ring = ndimage.binary_dilation(mask, _SQUARE, iterations=reach) & ~mask
        with np.errstate(invalid="ignore"):
            nearer = d[ring] - level > opts.jump * abs(level)
        out[int(label)] = float(nearer.mean()) if ring.any() else 0.0
    return out
