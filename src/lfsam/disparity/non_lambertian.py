"""Glass and mirrors: find where the views disagree once aligned, and give those regions the
depth of the surface around them (docs/design.md section 3.2, issue 45).

Inside a glass or a mirror every view sees something else than the surface: the scene behind
(refracted) or a reflection, mixed with the surface's own tint and dirt. A disparity estimator
there measures the depth of what is seen, not of the object. Two steps repair that:

1. *Photo-consistency residual* (:func:`photo_residual`): every present view is sampled where the
   estimated disparity says the reference pixel is seen (bilinear, gray levels in [0, 1]); the
   residual of a pixel is the mean absolute difference to the reference over the best of the four
   half-grids (as the cost volume's view selection: a pixel hidden from one side by an occluder
   is not flagged), averaged over a small window. On a Lambertian surface at the right disparity
   it is the interpolation and noise level; where two layers moving with different disparities
   are mixed, no disparity aligns both and it stays high.
2. *Surface fill* (:func:`fill_non_lambertian`): pixels whose residual exceeds ``threshold`` form
   regions (opened to drop the thin lines along depth edges, small ones dropped). For each region
   the ring of pixels just around it (the object's opaque rim or frame, its Lambertian part: the
   silhouette's own depth) gives, from its confident disparities, a plane by robust least squares
   (iteratively reweighted); the region takes the plane's disparity. A region whose ring has too
   few confident pixels or does not fit a plane (the median deviation above ``max_deviation``) is
   left alone.

Limits: a region is filled from what surrounds it, so a pane of glass without any opaque rim
would take the depth of the scene around it; a curved object gets a plane.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from scipy import ndimage

from lfsam.devices import resolve_device
from lfsam.disparity.cost_volume import halves_of
from lfsam.disparity.filters import box_blur

__all__ = [
    "gray_views",
    "photo_residual",
    "rim_plane",
    "surface_disparity",
    "surface_disparity_of_view",
    "sweep_points",
]

#: Most rim pixels a sweep looks at (:func:`sweep_points`); a larger rim is evenly thinned.
MAX_SWEEP_POINTS = 4096


def photo_residual(
    gray: torch.Tensor,
    reference: torch.Tensor,
    offsets: np.ndarray,
    disparity: torch.Tensor,
    radius: int = 2,
) -> torch.Tensor:
    """Mean absolute gray difference after alignment by ``disparity`` (module docstring).

    Parameters
    ----------
    gray : torch.Tensor, shape (N, U, V)
        The other present views, gray levels in [0, 1].
    reference : torch.Tensor, shape (U, V)
        The reference view.
    offsets : ndarray, shape (N, 2)
        View offsets ``(ds, dt)`` from the reference.
    disparity : torch.Tensor, shape (U, V)
        The reference's disparity (docs/design.md section 1).
    radius : int
        Radius of the box window the residual is averaged over.

    Returns
    -------
    torch.Tensor, shape (U, V)
        The residual of the best half-grid; a pixel no view sees gets 0.
    """
    rows, cols = reference.shape
    device = reference.device
    u = torch.arange(rows, device=device, dtype=torch.float32)[:, None]
    v = torch.arange(cols, device=device, dtype=torch.float32)[None, :]
    sums = torch.zeros((4, rows, cols), device=device)
    seen = torch.zeros((4, rows, cols), device=device)
    for k, (ds, dt) in enumerate(np.asarray(offsets).tolist()):
        pu = u - disparity * ds
        pv = v - disparity * dt
        inside = (pu >= 0) & (pu <= rows - 1) & (pv >= 0) & (pv <= cols - 1)
        grid = torch.stack(
            (2.0 * pv / max(cols - 1, 1) - 1.0, 2.0 * pu / max(rows - 1, 1) - 1.0), dim=-1
        )
        sampled = F.grid_sample(
            gray[k][None, None], grid[None], mode="bilinear", align_corners=True
        )[0, 0]
        diff = (sampled - reference).abs() * inside
        for half in halves_of(ds, dt):
            sums[half] += diff
            seen[half] += inside.float()
    means = torch.where(seen > 0.5, sums / seen.clamp(min=1.0), torch.inf)
    means = torch.where(torch.isfinite(means), means, means.new_tensor(1.0))
    best = box_blur(means, radius).amin(0)
    return torch.where(seen.sum(0) > 0, best, 0.0)


def _plane_fit(
    rows: np.ndarray, cols: np.ndarray, values: np.ndarray, weights: np.ndarray, iterations: int = 5
) -> tuple[np.ndarray, float]:
    """Weighted robust plane ``d = a + b u + c v`` (Tukey-like reweighting); returns the
    coefficients and the median absolute deviation of the points from it."""
    design = np.stack([np.ones_like(rows), rows, cols], axis=1).astype(np.float64)
    w = weights.astype(np.float64)
    coef = np.zeros(3)
    for _ in range(iterations):
        sw = np.sqrt(w)[:, None]
        coef, *_ = np.linalg.lstsq(design * sw, values * sw[:, 0], rcond=None)
        residual = np.abs(values - design @ coef)
        scale = max(1.4826 * float(np.median(residual)), 0.02)
        w = weights * np.clip(1.0 - (residual / (4.685 * scale)) ** 2, 0.0, None) ** 2
        if w.sum() <= 0:
            break
    return coef, float(np.median(np.abs(values - design @ coef)))


def gray_views(
    views: np.ndarray, reference: tuple[int, int], present: np.ndarray | None = None,
    device: str | torch.device | None = "cpu",
) -> tuple[torch.Tensor, torch.Tensor, np.ndarray]:
    """The reference and the other present views in gray levels, with their offsets (the
    arguments of :func:`photo_residual`)."""
    device = resolve_device(device)
    luma = torch.tensor((0.299, 0.587, 0.114), device=device)
    s_count, t_count = views.shape[:2]
    present = np.ones((s_count, t_count), bool) if present is None else present
    others = [(s, t) for s in range(s_count) for t in range(t_count)
              if present[s, t] and (s, t) != tuple(reference)]

    def gray(index: tuple[int, int]) -> torch.Tensor:
        rgb = torch.from_numpy(np.ascontiguousarray(views[index])).to(device).float()
        return (rgb @ luma) / 255.0

    offsets = np.array([(s - reference[0], t - reference[1]) for s, t in others]).reshape(-1, 2)
    return gray(tuple(reference)), torch.stack([gray(i) for i in others]), offsets


def _sample_views(grays: torch.Tensor, rows: torch.Tensor, cols: torch.Tensor) -> torch.Tensor:
    """Bilinear samples of each view ``grays[k]`` (N, U, V) at its own points ``(rows[k],
    cols[k])`` (N, P), all views in one call; NaN outside the frame."""
    _, height, width = grays.shape
    grid = torch.stack((2.0 * cols / max(width - 1, 1) - 1.0,
                        2.0 * rows / max(height - 1, 1) - 1.0), dim=-1)[:, None]  # (N, 1, P, 2)
    out = F.grid_sample(grays[:, None], grid, mode="bilinear", align_corners=True)[:, 0, 0]
    inside = (rows >= 0) & (rows <= height - 1) & (cols >= 0) & (cols <= width - 1)
    return torch.where(inside, out, torch.nan)


def _point_costs(
    grays: torch.Tensor,
    offsets: np.ndarray,
    rows: torch.Tensor,
    cols: torch.Tensor,
    ref: torch.Tensor,
    disparity: torch.Tensor,
    half_grids: bool,
) -> torch.Tensor:
    """Per point, the mean absolute gray difference to the reference over all views (or over
    the best half-grid) that see it at ``disparity`` (every view sampled in one batched call)."""
    pairs = np.asarray(offsets).reshape(-1, 2)
    steps = torch.as_tensor(pairs, dtype=torch.float32, device=rows.device)
    shifted_rows = rows[None] - disparity[None] * steps[:, :1]
    shifted_cols = cols[None] - disparity[None] * steps[:, 1:]
    diffs = (_sample_views(grays, shifted_rows, shifted_cols) - ref[None]).abs()  # (N, P)
    if not half_grids:
        return torch.nanmean(diffs, 0).nan_to_num(1.0)
    halves = [[k for k, (ds, dt) in enumerate(pairs.tolist()) if half in halves_of(ds, dt)]
              for half in range(4)]
    means = [torch.nanmean(diffs[half], 0) for half in halves if half]
    return torch.stack(means).nan_to_num(1.0).amin(0)


def sweep_points(
    grays: torch.Tensor,
    reference: torch.Tensor,
    offsets: np.ndarray,
    rows: np.ndarray,
    cols: np.ndarray,
    hypotheses: np.ndarray,
    base: np.ndarray | None = None,
    margin: list[float] | None = None,
    half_grids: bool = False,
) -> float:
    """The one disparity at which a set of reference pixels (e.g. an object's rim) is most
    photo-consistent (with ``base``, per pixel: the offset added to ``base`` at which they are):
    for each hypothesis every view is sampled where each pixel would be seen, a pixel's
    residual is the mean absolute gray difference over all views that see it, and the
    hypothesis with the lowest median residual over the pixels wins, refined by a parabola
    through its neighbours.

    ``half_grids=True`` takes each pixel's best half-grid instead (as before issue 45's second
    round): the minimum over four view sets at every hypothesis flattens the curve (on a
    generator object's rim, with its true slope, the median residual varied by 0.0003 between
    -0.2 and +0.2 px per view step around the true level and the sweep missed it by 0.10, while
    over all views it rose from 0.0013 to 0.0054 and the sweep hit it; docs/design.md 3.2); the
    median over the rim's pixels already discounts the few an occluder hides.

    A rim of more than :data:`MAX_SWEEP_POINTS` pixels is swept on that many of them, evenly
    spaced in its (raster) order: the median of a few thousand pixels moves little, and a large
    ragged mask (a 154,000-pixel mask of an untrained model on HCI antinous had a 63,700-pixel
    rim) would otherwise cost a minute (docs/design.md 3.2)."""
    rows, cols = np.asarray(rows), np.asarray(cols)
    if len(rows) > MAX_SWEEP_POINTS:
        keep = np.unique(np.linspace(0, len(rows) - 1, MAX_SWEEP_POINTS).round().astype(int))
        rows, cols = rows[keep], cols[keep]
        base = None if base is None else np.asarray(base)[keep]
    device = reference.device
    r = torch.as_tensor(rows, dtype=torch.float32, device=device)
    c = torch.as_tensor(cols, dtype=torch.float32, device=device)
    ref = reference[r.long(), c.long()]
    shift = torch.zeros_like(r) if base is None else torch.as_tensor(
        base, dtype=torch.float32, device=device)
    costs_arr = np.asarray([
        float(_point_costs(grays, offsets, r, c, ref, shift + value, half_grids).median())
        for value in np.asarray(hypotheses, dtype=np.float64).tolist()
    ])
    i = int(np.argmin(costs_arr))
    if margin is not None:  # the cost-curve margin of the winner (as margin_confidence)
        far = np.abs(np.arange(len(costs_arr)) - i) > 2
        second = float(costs_arr[far].min()) if far.any() else float(costs_arr[i])
        margin.append(max(0.0, (second - float(costs_arr[i])) / (second + 1e-3)))
    value = float(hypotheses[i])
    if 0 < i < len(costs_arr) - 1:
        below, mid, above = costs_arr[i - 1], costs_arr[i], costs_arr[i + 1]
        denominator = below - 2 * mid + above
        if denominator > 1e-12:
            step = float(hypotheses[1] - hypotheses[0])
            value += float(np.clip((below - above) / (2 * denominator), -0.5, 0.5)) * step
    return value


def rim_plane(
    views: tuple[torch.Tensor, torch.Tensor, np.ndarray],
    rows: np.ndarray,
    cols: np.ndarray,
    estimate: np.ndarray,
    search: tuple[float, float],
    margin: list[float] | None = None,
    slope_rounds: int = 1,
    sectors: int = 6,
) -> np.ndarray:
    """The plane ``d = a + b u + c v`` of an object's rim, from the silhouette itself.

    A first slope ``(b, c)`` is the robust plane fit to the estimate on the rim; the level ``a``
    is swept (:func:`sweep_points` with that slope as ``base``: steps of 0.1 over ``search``,
    then of 0.02 within 0.2 of the best): the rim's own pixels decide it, not the estimator's
    windows, which straddle a thin rim and the inside and pull its level towards the inside's.
    Those windows bend the estimate's slope too (a generator glass: 0.0199, -0.0226 px per
    pixel against the true 0.0169, 0.0017, its inside's median disparity 0.11 off), so the
    slope is then measured on the silhouette as well: the rim is cut into ``sectors`` sectors
    by angle about its centroid, each sector's level is swept the same way (offsets from the
    current plane, 0.05 steps within 0.5, then 0.01 within 0.05: over a sector's short span a
    wrong slope misaligns little), a plane is fitted robustly to the sectors' centroids at their
    levels, and the whole rim's level is swept finely again with its slope; ``slope_rounds``
    times.

    Parameters
    ----------
    views : (reference, grays, offsets)
        As :func:`gray_views` returns them.
    rows, cols : ndarray
        The rim's pixels.
    estimate : ndarray
        The estimated disparity at those pixels.
    search : (lo, hi)
        Disparities to search.
    margin : list, optional
        Receives the coarse sweep's cost-curve margin ``(c2 - c1) / (c2 + 0.001)`` (``c2`` the
        best cost more than two steps away): how clearly the silhouette decides.
    slope_rounds : int
        Rounds of the sectors' slope measurement (0: the estimate's slope, as before issue 45's
        second round).
    sectors : int
        Sectors of the rim for the slope (at least 3 with 8 pixels each take part).
    """
    reference, grays, offsets = views
    u = rows.astype(np.float64)
    v = cols.astype(np.float64)
    coef, _ = _plane_fit(u, v, estimate.astype(np.float64), np.ones(len(rows)))

    def sweep(values: np.ndarray, plane: np.ndarray, out: list[float] | None = None) -> float:
        base = plane[0] + plane[1] * u + plane[2] * v
        return sweep_points(grays, reference, offsets, rows, cols, values, base, out)

    plane = np.array([0.0, coef[1], coef[2]])
    base = plane[1] * u + plane[2] * v
    lo, hi = search[0] - float(base.max()), search[1] - float(base.min())
    coarse = np.arange(lo, hi + 1e-9, 0.1)
    if len(coarse) < 3:
        coarse = np.linspace(lo, hi, 3)
    plane[0] = sweep(coarse, plane, margin)
    fine = np.arange(-0.2, 0.2 + 1e-9, 0.02)
    plane[0] += sweep(fine, plane)
    angle = np.arctan2(u - u.mean(), v - v.mean())
    part = np.minimum(((angle + np.pi) / (2 * np.pi) * sectors).astype(int), sectors - 1)
    local = (np.arange(-0.5, 0.5 + 1e-9, 0.05), np.arange(-0.05, 0.05 + 1e-9, 0.01))
    for _ in range(slope_rounds):
        points = []
        for k in range(sectors):
            pick = part == k
            if pick.sum() < 8:
                continue
            base = plane[0] + plane[1] * u[pick] + plane[2] * v[pick]
            offset = 0.0
            for values in local:
                offset += sweep_points(grays, reference, offsets, rows[pick], cols[pick],
                                       values, base + offset)
            uk, vk = float(u[pick].mean()), float(v[pick].mean())
            points.append((uk, vk, plane[0] + plane[1] * uk + plane[2] * vk + offset,
                           float(pick.sum())))
        if len(points) < 3:
            break
        pu, pv, pd, pw = np.array(points).T
        plane, _ = _plane_fit(pu, pv, pd, pw)
        plane[0] += sweep(fine, plane)
    return plane


def surface_disparity(
    disparity: np.ndarray,
    masks: np.ndarray,
    residual: np.ndarray,
    views: tuple[torch.Tensor, torch.Tensor, np.ndarray],
    *,
    rim: int = 2,
    ratio: float = 1.25,
    min_residual: float = 0.006,
    margin: float = 0.25,
    far: float = 3.0,
    confidence: np.ndarray | None = None,
) -> tuple[np.ndarray, list[dict]]:
    """Objects whose inside shows something else than their surface get their rim's depth.

    For each mask (an object's silhouette in the view the disparity belongs to) the rim is the
    band of ``rim`` pixels inside its outline, the inside the rest. The rim's plane comes from
    the silhouette itself (:func:`rim_plane`: the outline moves with the object's surface, and
    an opaque rim or frame is Lambertian). The inside is non-Lambertian when both

    - its median photo-consistency residual (:func:`photo_residual`) is at least ``ratio`` times
      the rim's and at least ``min_residual``: the views disagree there once aligned, and
    - its disparity lies more than ``margin`` pixels per view step behind the rim's plane (its
      lower quartile: the inside starts with the rest of a wide frame): what is seen is farther
      than the outline that encloses it (the scene through a glass, the virtual image in a
      mirror; a Lambertian concave object keeps a low residual),

    and then takes the plane's disparity. An inside more than ``far * margin`` behind its rim
    is filled without the residual: a mirror whose reflection dominates is photo-consistent at
    the reflection's virtual depth (measured on the generator's mirrors: inside residual 0.004
    against 0.010 on the rim), so there only the geometry tells.

    Parameters
    ----------
    disparity : ndarray, shape (U, V)
    masks : ndarray, shape (N, U, V), bool
    residual : ndarray, shape (U, V)
        The photo-consistency residual at ``disparity``.
    views : (reference, grays, offsets)
        The view's light field in gray levels (:func:`gray_views`).
    rim, ratio, min_residual, margin, far
        See above.
    confidence : ndarray, shape (U, V), optional
        The disparity's confidence, updated in place: a filled inside takes the margin of its
        rim's sweep (:func:`rim_plane`; ``confidence`` in the report).

    Returns
    -------
    disparity : ndarray, shape (U, V), float32
    objects : list of dict
        Per mask: ``index``, ``inside_residual``, ``rim_residual``, ``behind`` (lower quartile
        of the inside minus the rim's plane), ``filled``.
    """
    out = np.array(disparity, dtype=np.float32, copy=True)
    search = (float(np.nanmin(disparity)) - 0.5, float(np.nanmax(disparity)) + 0.5)
    report = []
    for index, mask in enumerate(np.asarray(masks, dtype=bool)):
        inside_part = ndimage.binary_erosion(mask, np.ones((3, 3), bool), iterations=rim)
        rim_part = mask & ~inside_part
        info = {"index": index, "inside_residual": None, "rim_residual": None, "behind": None,
                "filled": False}
        report.append(info)
        if inside_part.sum() < 30 or rim_part.sum() < 20:
            continue
        rr, cc = np.nonzero(rim_part)
        iu, iv = np.nonzero(inside_part)
        inside_res = float(np.median(residual[iu, iv]))
        rim_res = float(np.median(residual[rr, cc]))
        info.update(inside_residual=round(inside_res, 5), rim_residual=round(rim_res, 5))
        disagree = inside_res >= max(ratio * rim_res, min_residual)
        # cheap first look: the estimate's own inside against its rim
        if float(np.percentile(disparity[iu, iv], 25) - np.median(disparity[rr, cc])) >= -margin:
            continue
        sharpness: list[float] = []
        coef = rim_plane(views, rr, cc, disparity[rr, cc], search, sharpness)
        plane = coef[0] + coef[1] * iu + coef[2] * iv
        behind = float(np.percentile(disparity[iu, iv] - plane, 25))
        info["behind"] = round(behind, 4)
        if behind < -margin and (disagree or behind < -far * margin):
            out[iu, iv] = plane
            info["filled"] = True
            info["confidence"] = round(sharpness[0], 4)
            if confidence is not None:
                confidence[iu, iv] = sharpness[0]
    return out, report


def surface_disparity_of_view(
    views: np.ndarray,
    view: tuple[int, int],
    disparity: np.ndarray,
    masks: np.ndarray,
    present: np.ndarray | None = None,
    device: str | torch.device | None = "cpu",
    confidence: np.ndarray | None = None,
) -> tuple[np.ndarray, list[dict]]:
    """:func:`surface_disparity` for one view of a light field: its residual is measured first.

    Parameters
    ----------
    views : ndarray, shape (S, T, U, V, 3), uint8
    view : (s, t)
        The view ``disparity`` and ``masks`` belong to.
    disparity : ndarray, shape (U, V)
    masks : ndarray, shape (N, U, V), bool
        The objects' silhouettes in that view.
    present : ndarray, shape (S, T), bool, optional
        Views present (absent ones are skipped).
    device : str or torch.device
    confidence : ndarray, shape (U, V), optional
        Updated in place (:func:`surface_disparity`).
    """
    masks = np.asarray(masks, dtype=bool)
    if masks.size == 0 or not masks.any():
        return np.asarray(disparity, dtype=np.float32), []
    reference, grays, offsets = gray_views(views, view, present, device)
    with torch.no_grad():
        values = torch.tensor(np.asarray(disparity), dtype=torch.float32, device=reference.device)
        residual = photo_residual(grays, reference, offsets, values)
        return surface_disparity(
            disparity, masks, residual.cpu().numpy(), (reference, grays, offsets),
            confidence=confidence,
        )
