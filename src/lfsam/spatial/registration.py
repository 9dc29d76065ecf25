"""Rigid registration of 3D points: Kabsch, RANSAC, normals and point-to-plane ICP (design §12).

Plain arrays in and out; transforms are 4x4 float64 arrays acting on column vectors (``y = R x +
t``). Nearest neighbours come from SciPy's ``cKDTree`` (a maintained KD-tree); the rest is a
few vectorised NumPy lines each:

- :func:`kabsch` — the least-squares rotation and translation between paired points (Kabsch
  1976; Umeyama 1991 without scale), optionally weighted;
- :func:`ransac_rigid` — the same on pairs with outliers: minimal 3-point hypotheses, all
  solved in one batched SVD, scored by inliers, the best refitted on its inliers;
- :func:`voxel_downsample` and :func:`estimate_normals` — the usual ICP preparation;
- :func:`icp` — point-to-plane ICP (Chen & Medioni 1992) with Gauss-Newton steps, a shrinking
  distance gate and, optionally, fixed point pairs (feature matches) that pin the directions a
  plane cannot (two faces of a box slide along their common edge) and a weak prior on the
  transform (a predicted motion) that holds what neither pins (a strip of one face).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

__all__ = [
    "IcpResult",
    "estimate_normals",
    "icp",
    "kabsch",
    "plane_conditioning",
    "ransac_rigid",
    "transform",
    "voxel_downsample",
]


def transform(matrix: np.ndarray, xyz: np.ndarray) -> np.ndarray:
    """``xyz`` (N, 3) moved by the 4x4 ``matrix``."""
    return xyz @ matrix[:3, :3].T + matrix[:3, 3]


def _kabsch_batch(src: np.ndarray, dst: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Batched weighted Kabsch: ``src``, ``dst`` (B, N, 3), ``w`` (B, N) -> (B, 4, 4)."""
    w = w / np.maximum(w.sum(axis=1, keepdims=True), 1e-300)
    mu_s = np.einsum("bn,bnk->bk", w, src)
    mu_d = np.einsum("bn,bnk->bk", w, dst)
    cov = np.einsum("bn,bni,bnj->bij", w, dst - mu_d[:, None], src - mu_s[:, None])
    u, _, vt = np.linalg.svd(cov)
    sign = np.sign(np.linalg.det(u @ vt))
    sign[sign == 0] = 1.0
    fix = np.ones((len(src), 3))
    fix[:, 2] = sign
    rot = (u * fix[:, None, :]) @ vt
    out = np.tile(np.eye(4), (len(src), 1, 1))
    out[:, :3, :3] = rot
    out[:, :3, 3] = mu_d - np.einsum("bij,bj->bi", rot, mu_s)
    return out


def kabsch(src: np.ndarray, dst: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """The rigid transform (4x4) that best carries ``src`` (N, 3) onto ``dst`` (N, 3).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> a = rng.normal(size=(10, 3))
    >>> move = np.eye(4); move[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]; move[:3, 3] = 1
    >>> bool(np.allclose(kabsch(a, transform(move, a)), move))
    True
    """
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    w = np.ones(len(src)) if weights is None else np.asarray(weights, dtype=np.float64)
    return _kabsch_batch(src[None], dst[None], w[None])[0]


def ransac_rigid(
    src: np.ndarray,
    dst: np.ndarray,
    threshold: float,
    *,
    iterations: int = 400,
    seed: int = 0,
) -> tuple[np.ndarray | None, np.ndarray]:
    """A rigid transform carrying ``src`` onto ``dst`` despite wrong pairs (RANSAC).

    Parameters
    ----------
    src, dst : (N, 3)
        Paired points (e.g. feature matches lifted to 3D).
    threshold : float
        The largest distance (same units) of an inlier pair.
    iterations : int
        3-point hypotheses drawn (deterministic for a ``seed``).

    Returns
    -------
    transform : (4, 4) or None
        Refitted on the best hypothesis' inliers; None with fewer than 3 pairs or 3 inliers.
    inliers : (N,) bool
    """
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    n = len(src)
    if n < 3:
        return None, np.zeros(n, dtype=bool)
    rng = np.random.default_rng(seed)
    picks = np.stack([rng.choice(n, 3, replace=False) for _ in range(iterations)])
    hypotheses = _kabsch_batch(src[picks], dst[picks], np.ones(picks.shape))
    moved = np.einsum("bij,nj->bni", hypotheses[:, :3, :3], src) + hypotheses[:, None, :3, 3]
    close = np.linalg.norm(moved - dst[None], axis=2) < threshold
    best = int(close.sum(axis=1).argmax())
    inliers = close[best]
    if inliers.sum() < 3:
        return None, inliers
    for _ in range(2):  # refit on the inliers, then take the refit's inliers
        fit = kabsch(src[inliers], dst[inliers])
        again = np.linalg.norm(transform(fit, src) - dst, axis=1) < threshold
        if again.sum() < 3:
            break
        inliers = again
    return kabsch(src[inliers], dst[inliers]), inliers


def voxel_downsample(xyz: np.ndarray, voxel: float, *extra: np.ndarray):
    """One point per occupied voxel of edge ``voxel``: the mean of its points (and of each
    ``extra`` per-point array, e.g. colours as floats). Returns ``(xyz, *extra)``."""
    xyz = np.asarray(xyz, dtype=np.float64)
    if len(xyz) == 0:
        return (xyz, *extra)
    keys = np.floor(xyz / voxel).astype(np.int64)
    keys -= keys.min(axis=0)
    span = keys.max(axis=0) + 1
    packed = (keys[:, 0] * span[1] + keys[:, 1]) * span[2] + keys[:, 2]
    _, inverse, counts = np.unique(packed, return_inverse=True, return_counts=True)
    out = []
    for array in (xyz, *extra):
        array = np.asarray(array, dtype=np.float64).reshape(len(xyz), -1)
        sums = np.stack([np.bincount(inverse, weights=array[:, k], minlength=len(counts))
                         for k in range(array.shape[1])], axis=1)
        out.append(sums / counts[:, None])
    return tuple(out)


def estimate_normals(xyz: np.ndarray, neighbours: int = 12,
                     viewpoint: np.ndarray | None = None) -> np.ndarray:
    """Unit normals (N, 3): the smallest-variance direction of each point's ``neighbours``
    nearest points, turned towards ``viewpoint`` (default the origin, the center camera)."""
    xyz = np.asarray(xyz, dtype=np.float64)
    k = min(neighbours, len(xyz))
    if k < 3:
        return np.zeros_like(xyz)
    _, idx = cKDTree(xyz).query(xyz, k=k)
    near = xyz[idx] - xyz[idx].mean(axis=1, keepdims=True)
    cov = np.einsum("nki,nkj->nij", near, near)
    _, vectors = np.linalg.eigh(cov)
    normals = vectors[:, :, 0]
    view = np.zeros(3) if viewpoint is None else np.asarray(viewpoint, dtype=np.float64)
    flip = np.einsum("ni,ni->n", normals, view - xyz) < 0
    normals[flip] *= -1
    return normals


@dataclass
class IcpResult:
    """The refined transform (4x4, source to target), the share of source points with a target
    point within the final gate (``inliers``), their RMS point-to-plane distance (``rmse``,
    same units as the points) and how well their planes pin all six directions
    (``conditioning``: the smallest eigenvalue of their point-to-plane normal equations over
    the largest, in :func:`icp`'s scaled unknowns; 0 for a plane, which leaves three free;
    NaN without inliers)."""

    transform: np.ndarray
    inliers: float
    rmse: float
    conditioning: float = float("nan")


def plane_conditioning(xyz: np.ndarray, normals: np.ndarray) -> float:
    """How well points with their surface normals pin a rigid motion, as :func:`icp` solves
    for it: the smallest eigenvalue of their point-to-plane normal equations over the largest
    (rotation about the centroid scaled by the RMS radius, and translation). 0 for one plane
    (it leaves three directions free) or a cylinder (one), about 0.1-0.3 for three faces of a
    box; 0 without points.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> face = np.c_[rng.uniform(-1, 1, (200, 2)), np.zeros(200)]
    >>> round(plane_conditioning(face, np.tile([0.0, 0.0, 1.0], (200, 1))), 6)
    0.0
    """
    xyz = np.asarray(xyz, dtype=np.float64)
    if len(xyz) == 0:
        return 0.0
    _, _, jac = _plane_jacobian(xyz, normals)
    values = np.linalg.eigvalsh(jac.T @ jac)
    return float(max(values[0], 0.0) / values[-1]) if values[-1] > 0 else 0.0


def _plane_jacobian(p: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """The point-to-plane Jacobian of points ``p`` with normals ``n`` in :func:`icp`'s unknowns
    (a rotation about their centroid scaled by their RMS radius, then a translation): the
    centroid, the radius and the ``(N, 6)`` Jacobian."""
    centre = p.mean(axis=0)
    radius = max(float(np.sqrt(((p - centre) ** 2).sum(axis=1).mean())), 1e-6)
    return centre, radius, np.concatenate([np.cross((p - centre) / radius, n), n], axis=1)


def _rotation(omega: np.ndarray) -> np.ndarray:
    angle = float(np.linalg.norm(omega))
    if angle == 0:
        return np.eye(3)
    axis = omega / angle
    cross = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * cross + (1 - np.cos(angle)) * cross @ cross


def _prior_step(prior: np.ndarray, current: np.ndarray, centre: np.ndarray,
                radius: float) -> np.ndarray:
    """The Gauss-Newton step (scaled rotation about ``centre``, translation) of :func:`icp` that
    carries ``current`` onto ``prior``."""
    update = prior @ np.linalg.inv(current)
    rot = update[:3, :3]
    shift = rot @ centre + update[:3, 3] - centre
    return np.concatenate([Rotation.from_matrix(rot).as_rotvec() * radius, shift])


def _pair_system(ps: np.ndarray, targets: np.ndarray, centre: np.ndarray, radius: float):
    """Normal equations of point-to-point pairs in :func:`icp`'s centred, scaled unknowns."""
    q = (ps - centre) / radius
    jp = np.zeros((len(ps), 3, 6))
    jp[:, 0, 1], jp[:, 0, 2] = q[:, 2], -q[:, 1]
    jp[:, 1, 0], jp[:, 1, 2] = -q[:, 2], q[:, 0]
    jp[:, 2, 0], jp[:, 2, 1] = q[:, 1], -q[:, 0]
    jp[:, :, 3:] = np.eye(3)
    jp = jp.reshape(-1, 6)
    return jp.T @ jp, jp.T @ (ps - targets).reshape(-1)


def icp(
    source: np.ndarray,
    target: np.ndarray,
    target_normals: np.ndarray,
    init: np.ndarray,
    *,
    tree: cKDTree | None = None,
    gates: tuple[float, ...] = (0.02, 0.01, 0.005, 0.003),
    iterations: int = 8,
    pairs: tuple[np.ndarray, np.ndarray] | None = None,
    pair_weight: float = 1.0,
    weak_pair_weight: float | None = None,
    weak: float = 0.02,
    prior: np.ndarray | None = None,
    prior_weight: float = 0.0,
) -> IcpResult:
    """Point-to-plane ICP of ``source`` onto ``target`` from ``init``.

    Each Gauss-Newton step solves for a small rotation about the moved points' centroid (scaled
    by their RMS radius, so rotation and translation weigh alike) and a translation.

    Parameters
    ----------
    source : (N, 3)
    target, target_normals : (M, 3)
    init : (4, 4)
        The starting transform (source to target).
    tree : cKDTree, optional
        ``cKDTree(target)``, when the caller keeps one.
    gates : distances
        Correspondences farther than the gate are left out; ``iterations`` Gauss-Newton steps
        are made at each gate in turn (coarse to fine).
    pairs : ((K, 3), (K, 3)), optional
        Fixed point pairs (source, target), e.g. feature matches, added as point-to-point
        residuals with weight ``pair_weight`` relative to all the point-to-plane residuals
        together (each pair ``pair_weight N / K``); like the points, a pair farther apart than
        the gate is left out of the step (a wrong match that RANSAC's tolerance let through
        must not pull a fit the planes pin).
    weak_pair_weight, weak : float, optional
        When the planes leave a direction nearly free (the smallest eigenvalue of their
        normal equations below ``weak`` times the largest: one face of a box, two faces sliding
        along their edge), the pairs weigh ``weak_pair_weight`` instead.
    prior, prior_weight : (4, 4), float, optional
        A transform expected beforehand (a predicted motion; source to target) and its weight,
        relative to all the point-to-plane residuals together, in the directions the planes and
        pairs leave nearly free (eigenvalues of their normal equations below ``weak`` times the
        largest: a strip of one face slides in its plane and turns about its normal): there
        each step is damped towards ``prior`` (a Gaussian prior around it); the directions
        they pin are theirs alone, so a prediction that is off (no velocity known yet) does
        not bias a well-seen object.

    Returns
    -------
    IcpResult
    """
    source = np.asarray(source, dtype=np.float64)
    tree = tree if tree is not None else cKDTree(target)
    current = np.asarray(init, dtype=np.float64).copy()
    n_src = max(len(source), 1)
    for gate in gates:
        for _ in range(iterations):
            moved = transform(current, source)
            dist, idx = tree.query(moved, distance_upper_bound=gate)
            ok = np.isfinite(dist)
            if ok.sum() < 6:
                break
            p = moved[ok]
            q = target[idx[ok]]
            n = target_normals[idx[ok]]
            centre, radius, jac = _plane_jacobian(p, n)
            residual = np.einsum("ni,ni->n", p - q, n)
            hessian = jac.T @ jac
            gradient = jac.T @ residual
            if pairs is not None and len(pairs[0]):
                ps = transform(current, pairs[0])
                near = np.linalg.norm(ps - pairs[1], axis=1) <= gate
                ps, pair_targets = ps[near], pairs[1][near]
            if pairs is not None and len(pairs[0]) and len(ps):
                weight = pair_weight
                if weak_pair_weight is not None:
                    values = np.linalg.eigvalsh(hessian)
                    if values[0] < weak * values[-1]:
                        weight = weak_pair_weight
                weight *= ok.sum() / len(ps)
                pair_h, pair_g = _pair_system(ps, pair_targets, centre, radius)
                hessian = hessian + weight * pair_h
                gradient = gradient + weight * pair_g
            if prior is not None and prior_weight > 0:
                values, vectors = np.linalg.eigh(hessian)
                free = vectors[:, values < weak * values[-1]]
                if free.shape[1]:
                    damping = prior_weight * ok.sum() * (free @ free.T)
                    hessian = hessian + damping
                    gradient = gradient - damping @ _prior_step(prior, current, centre, radius)
            step = -np.linalg.solve(hessian + 1e-9 * np.eye(6), gradient)
            rot = _rotation(step[:3] / radius)
            update = np.eye(4)
            update[:3, :3] = rot
            update[:3, 3] = centre - rot @ centre + step[3:]
            current = update @ current
            if np.linalg.norm(step[:3]) < 1e-9 and np.linalg.norm(step[3:]) < 1e-9:
                break
    moved = transform(current, source)
    gate = gates[-1]
    dist, idx = tree.query(moved, distance_upper_bound=gate)
    ok = np.isfinite(dist)
    rmse = conditioning = float("nan")
    if ok.any():
        p, n = moved[ok], target_normals[idx[ok]]
        residual = np.einsum("ni,ni->n", p - target[idx[ok]], n)
        rmse = float(np.sqrt(np.mean(residual**2)))
        conditioning = plane_conditioning(p, n)
    return IcpResult(current, float(ok.sum() / n_src), rmse, conditioning)
