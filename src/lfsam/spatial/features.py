"""2D features inside object masks, lifted to 3D (docs/design.md section 12).

SIFT keypoints and descriptors (Lowe 2004, OpenCV's implementation: the ``poses`` extra,
``opencv-python-headless``) of one view, kept where the view's label field names an object and
the disparity gives a finite depth, and moved to 3D in the center camera's frame with
:func:`lfsam.camera.back_project`. Matching two sets (the same view in two frames) uses Lowe's
ratio test; :func:`lfsam.spatial.registration.ransac_rigid` then removes the wrong pairs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lfsam.camera import Camera, back_project
from lfsam.errors import LfsamError

__all__ = ["ViewFeatures", "match_features", "refine_disparity", "view_features"]

#: Lowe's ratio: a match is kept when its distance is below this share of the second best's.
RATIO = 0.8


def _cv2():
    try:
        import cv2
    except ImportError:  # pragma: no cover - the extra is part of dev installs
        raise LfsamError(
            "6D poses need OpenCV's features; install them with pip install 'lfsam[poses]' "
            "(opencv-python-headless)"
        ) from None
    return cv2


@dataclass
class ViewFeatures:
    """One view's keypoints on objects: ``labels`` (K,) object ids, ``xyz`` (K, 3) metres in
    the center camera's frame, ``descriptors`` (K, 128) float32."""

    labels: np.ndarray
    xyz: np.ndarray
    descriptors: np.ndarray

    def of(self, object_id: int) -> tuple[np.ndarray, np.ndarray]:
        """``(xyz, descriptors)`` of one object."""
        keep = self.labels == object_id
        return self.xyz[keep], self.descriptors[keep]


def view_features(
    image: np.ndarray,
    labels: np.ndarray,
    disparity: np.ndarray,
    camera: Camera,
    view_offset: tuple[int, int] = (0, 0),
    confident: np.ndarray | None = None,
    max_features: int = 4000,
    gray: np.ndarray | None = None,
) -> ViewFeatures:
    """SIFT features of one view that fall on labelled pixels with a usable disparity.

    Parameters
    ----------
    image : (U, V, 3) uint8
    labels : (U, V) int
        The view's label field (0 = none); a keypoint takes its rounded pixel's label.
    disparity : (U, V) float
    camera : Camera
    view_offset : (s - s_c, t - t_c)
    confident : (U, V) bool, optional
        Pixels whose disparity may be used (default all).
    max_features : int
        At most this many keypoints (the strongest) per view.
    gray : (S, T, U, V) float32, optional
        Every view of the light field, grayscale: the keypoints' disparities are then refined
        by :func:`refine_disparity` (for estimated disparities; exact ones need nothing).
    """
    cv2 = _cv2()
    single = cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2GRAY)
    mask = (np.asarray(labels) > 0).astype(np.uint8)
    sift = cv2.SIFT_create(nfeatures=max_features)
    keypoints, descriptors = sift.detectAndCompute(single, mask)
    if not keypoints or descriptors is None:
        return ViewFeatures(np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 128), "f4"))
    pts = np.array([kp.pt for kp in keypoints], dtype=np.float64)  # (x = column, y = row)
    rows = np.clip(np.rint(pts[:, 1]).astype(np.int64), 0, labels.shape[0] - 1)
    cols = np.clip(np.rint(pts[:, 0]).astype(np.int64), 0, labels.shape[1] - 1)
    ids = np.asarray(labels)[rows, cols].astype(np.int64)
    d = _subpixel_disparity(np.asarray(disparity, dtype=np.float64), np.asarray(labels),
                            pts[:, 1], pts[:, 0], ids)
    keep = (ids > 0) & np.isfinite(d)
    if confident is not None:
        keep &= np.asarray(confident)[rows, cols]
    if gray is not None and keep.any():
        view = (gray.shape[0] // 2 + view_offset[0], gray.shape[1] // 2 + view_offset[1])
        d[keep] = refine_disparity(gray, view, pts[keep, 1], pts[keep, 0], d[keep])
    xyz = back_project(pts[keep, 1], pts[keep, 0], d[keep], camera, labels.shape, view_offset)
    finite = np.isfinite(xyz).all(axis=1)
    return ViewFeatures(ids[keep][finite], xyz[finite],
                        np.asarray(descriptors, dtype=np.float32)[keep][finite])


def _subpixel_disparity(disparity: np.ndarray, labels: np.ndarray, rows: np.ndarray,
                        cols: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """Bilinear disparity at sub-pixel keypoints, from the four neighbours that carry the
    keypoint's own label (renormalised weights; the rounded pixel's value if none other)."""
    height, width = labels.shape
    r0 = np.clip(np.floor(rows).astype(np.int64), 0, height - 2)
    c0 = np.clip(np.floor(cols).astype(np.int64), 0, width - 2)
    fr = np.clip(rows - r0, 0, 1)
    fc = np.clip(cols - c0, 0, 1)
    total = np.zeros(len(rows))
    weight = np.zeros(len(rows))
    for dr, dc, w in ((0, 0, (1 - fr) * (1 - fc)), (0, 1, (1 - fr) * fc),
                      (1, 0, fr * (1 - fc)), (1, 1, fr * fc)):
        value = disparity[r0 + dr, c0 + dc]
        same = (labels[r0 + dr, c0 + dc] == ids) & np.isfinite(value)
        total += np.where(same, w * np.nan_to_num(value), 0.0)
        weight += np.where(same, w, 0.0)
    rounded = disparity[np.clip(np.rint(rows).astype(np.int64), 0, height - 1),
                        np.clip(np.rint(cols).astype(np.int64), 0, width - 1)]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(weight > 1e-6, total / weight, rounded)


def match_features(a: np.ndarray, b: np.ndarray, ratio: float = RATIO) -> np.ndarray:
    """Index pairs ``(K, 2)`` of descriptors ``a`` matched to ``b`` (ratio test, and mutual:
    each of ``b`` used once, by its best)."""
    if len(a) < 2 or len(b) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    cv2 = _cv2()
    matcher = cv2.BFMatcher(cv2.NORM_L2)
    pairs = []
    for m in matcher.knnMatch(np.ascontiguousarray(a), np.ascontiguousarray(b), k=2):
        if len(m) == 2 and m[0].distance < ratio * m[1].distance:
            pairs.append((m[0].queryIdx, m[0].trainIdx, m[0].distance))
    if not pairs:
        return np.zeros((0, 2), dtype=np.int64)
    found = np.array(pairs)
    order = np.argsort(found[:, 2], kind="stable")
    _, first = np.unique(found[order, 1], return_index=True)
    return found[order[first], :2].astype(np.int64)


def _sample(gray: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Bilinear samples of one grayscale view (float32), positions clipped to the view."""
    height, width = gray.shape
    rows = np.clip(rows, 0, height - 1.001)
    cols = np.clip(cols, 0, width - 1.001)
    r0 = rows.astype(np.int64)
    c0 = cols.astype(np.int64)
    fr = rows - r0
    fc = cols - c0
    top = gray[r0, c0] * (1 - fc) + gray[r0, c0 + 1] * fc
    bottom = gray[r0 + 1, c0] * (1 - fc) + gray[r0 + 1, c0 + 1] * fc
    return top * (1 - fr) + bottom * fr


def refine_disparity(
    gray: np.ndarray,
    view: tuple[int, int],
    rows: np.ndarray,
    cols: np.ndarray,
    disparity: np.ndarray,
    *,
    search: float = 0.2,
    patch: int = 1,
) -> np.ndarray:
    """Sub-pixel disparity of points by photo-consistency across the light field's outermost
    views (the light field's own triangulation, docs/design.md section 12).

    Each point ``(rows, cols)`` of view ``view`` (absolute ``(s, t)``) is looked up, with a
    ``(2 patch + 1)^2`` patch, in the center view and the eight views at the grid's corners and
    edge middles (the longest baselines) for disparities within ``search`` of its estimate:
    the sum of squared differences to its own patch is minimised on a coarse then a fine grid,
    with a parabola through the best three. Points whose estimate is not finite are returned as
    they are.

    Parameters
    ----------
    gray : (S, T, U, V) float32
        Every view, grayscale.
    view : (s, t)
    rows, cols : (K,) float
    disparity : (K,) float
        Estimates to refine.
    """
    s_count, t_count = gray.shape[:2]
    s0, t0 = view
    targets = {(s, t) for s in (0, s_count // 2, s_count - 1)
               for t in (0, t_count // 2, t_count - 1)} - {(s0, t0)}
    targets = sorted(targets)
    d0 = np.asarray(disparity, dtype=np.float64)
    ok = np.isfinite(d0)
    out = d0.copy()
    if not ok.any() or not targets:
        return out
    r = np.asarray(rows, dtype=np.float64)[ok]
    c = np.asarray(cols, dtype=np.float64)[ok]
    steps = np.arange(-patch, patch + 1, dtype=np.float64)
    pr, pc = np.meshgrid(steps, steps, indexing="ij")
    pr, pc = pr.ravel(), pc.ravel()
    ref = _sample(gray[s0, t0], r[:, None] + pr, c[:, None] + pc)  # (K, P)

    def cost(candidates: np.ndarray) -> np.ndarray:  # (K, N) -> (K, N)
        total = np.zeros(candidates.shape)
        for s, t in targets:
            ds, dt = s - s0, t - t0
            rr = r[:, None, None] + pr[None, None, :] - candidates[:, :, None] * ds
            cc = c[:, None, None] + pc[None, None, :] - candidates[:, :, None] * dt
            seen = _sample(gray[s, t], rr, cc)
            total += ((seen - ref[:, None, :]) ** 2).sum(axis=2)
        return total

    best = d0[ok]
    for width, count in ((search, 21), (search / 10, 11)):
        grid = best[:, None] + np.linspace(-width, width, count)[None, :]
        values = cost(grid)
        k = np.clip(values.argmin(axis=1), 1, count - 2)
        left, mid, right = (values[np.arange(len(k)), k + j] for j in (-1, 0, 1))
        curve = left - 2 * mid + right
        shift = np.where(curve > 0, 0.5 * (left - right) / np.where(curve > 0, curve, 1), 0.0)
        step = 2 * width / (count - 1)
        best = grid[np.arange(len(k)), k] + np.clip(shift, -1, 1) * step
    out[ok] = best
    return out
