"""Object removal: a whole light field without the objects (docs/design.md section 13).

Jarabo et al. (2014), "How do people edit light fields?": edits of a light field must stay
consistent across its views. Each view's object pixels (the mask grown by a pixel) are filled
from the other views where the surface behind is visible. What lies behind a pixel is one of a
few candidates: its background disparity (:mod:`lfsam.render.background_disparity`, never the
object's own) and the planes of the surfaces the object's rim shows in that view
(:func:`~lfsam.render.background_disparity.rim_surfaces`). A candidate ``d`` of a pixel of view
``(s, t)`` is seen by view ``(s', t')`` at ``(u - d (s' - s), v - d (t' - t))``: that view's
colour there counts if its ray misses the objects (none of the four bilinear neighbours masked;
where no ray does, a bilinear keep weight above :data:`LOOSE`; a ray's colour is that of its
neighbours off the objects themselves: normalised convolution) and the view sees that surface
there (the nearest background disparity within a pixel of the sample within
:data:`DEPTH_TOLERANCE` of it, so another object in front, or its anti-aliased edge, does not
count). Of the candidates seen there, the nearest is taken (a z-buffer), and its colours are
averaged with weights falling with the distance between the views (nearer views differ less in
sampling and lighting). Pixels no other view sees are inpainted by OpenCV
(:mod:`lfsam.render.inpaint`) and flagged.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import torch
import torch.nn.functional as F
from scipy.ndimage import distance_transform_edt
from tqdm import tqdm

from lfsam.devices import resolve_device, view_workers
from lfsam.render.background_disparity import dilate, view_backgrounds
from lfsam.render.inpaint import inpaint, require_cv2
from lfsam.render.views import check_masks, select_views, views_tensor

__all__ = ["DEPTH_TOLERANCE", "remove_objects"]

#: Largest difference (pixels per view step) between the disparity a view shows and the one
#: sought for its colour to count.
DEPTH_TOLERANCE = 0.5
#: Spread of the weights over the view distance, view steps.
SIGMA = 1.0
#: Keep weight above which a ray counts where no ray is wholly clear of the grown masks.
LOOSE = 0.5
#: Candidates closer than this (pixels per view step) are looked at once.
SAME = 0.05
#: Pixels added to a ray's reach before a pixel is found too deep inside the masks to be seen.
PRUNE_MARGIN = 3.0
#: Rays a candidate surface needs to be taken where any candidate has that many.
MIN_RAYS = 2
#: Pixels filled at a time (their arrays over the other views stay small).
PIECE = 8192


def _sample_grid(u, v, height, width):
    """``grid_sample``'s grid (``align_corners=True``) for pixel rows ``u`` and columns ``v``."""
    return torch.stack([2 * v / max(width - 1, 1) - 1, 2 * u / max(height - 1, 1) - 1], -1)


def _gather(sources, n, ys, xs, d, offsets, sigma):
    """Colours of target view ``n``'s pixels ``(ys, xs)`` seen at background disparity ``d``
    by the other views, how many rays saw each, and which a ray refutes.

    ``sources`` is ``(N, 6, U, V)``: RGB times the share off the objects themselves, the keep
    weight (1 clear of the grown masks, 0 on them), the (nearest) background disparity and
    that share (1 off the objects' own masks, 0 on them) of every view.
    """
    _, _, height, width = sources.shape
    rel = (offsets - offsets[n]).float()  # (N, 2): source minus target
    others = torch.ones(offsets.shape[0], dtype=torch.bool, device=rel.device)
    others[n] = False
    u = ys.float()[None] - d[None] * rel[:, :1]
    v = xs.float()[None] - d[None] * rel[:, 1:]
    grid = _sample_grid(u, v, height, width)
    # Every view is sampled (the target's own rays dropped after): indexing ``sources`` would
    # copy all its views at every call.
    sampled = F.grid_sample(sources, grid[:, None], mode="bilinear",
                            padding_mode="zeros", align_corners=True)[others, :, 0]  # (M, 5, K)
    rel = rel[others]
    on_surface = (sampled[:, 4] - d[None]).abs() < DEPTH_TOLERANCE
    clear = (sampled[:, 3] > 0.999) & on_surface
    missed = sampled[:, 3] > LOOSE
    # Rays clear of the grown masks; where none is, rays whose nearest neighbours are (keep
    # weight above LOOSE): an anti-aliased edge's colour mixed in beats an inpainted guess.
    loose = missed & on_surface
    valid = torch.where(clear.any(0, keepdim=True), clear, loose)
    # A ray that misses the objects and sees only farther surfaces there: nothing at d.
    refuted = missed & (sampled[:, 4] < d[None] - DEPTH_TOLERANCE)
    dist2 = (rel ** 2).sum(1)  # (M,)
    far = torch.full_like(dist2, float("inf"))
    nearest = torch.where(valid, dist2[:, None], far[:, None]).amin(0)
    # Relative to the nearest view that sees the pixel: no underflow however far it is.
    weight = valid * torch.exp((nearest.clamp(max=1e9)[None] - dist2[:, None]) / (2 * sigma**2))
    total = weight.sum(0)
    # Colours are stored times the share off the objects themselves: a ray's colour is that
    # of its neighbours off the objects (normalised convolution), never the objects' own.
    rays = sampled[:, :3] / sampled[:, 5:6].clamp_min(1e-6)
    colour = torch.einsum("mcp,mp->cp", rays, weight) / total.clamp_min(1e-12)
    return colour, valid.sum(0), refuted.any(0)


def _choose(sources, n, ys, xs, candidates, near, offsets, sigma):
    """Colours of target view ``n``'s pixels ``(ys, xs)`` from the other views, and which got
    any, given their candidates (a list of C disparities per pixel, the background disparity
    first) and where each plane candidate's rim is near (``near``, ``(C - 1, U, V)``).

    Each pixel's candidates for what lies behind it are its background disparity and the
    planes of the surfaces its rim shows (:func:`lfsam.render.background_disparity.
    rim_surfaces`); of those that other views see there (a ray that misses the objects and
    lands on a surface of that disparity), the nearest is taken: a surface seen at that
    disparity there lies in front of any farther one (a z-buffer over the candidates). At
    least :data:`MIN_RAYS` rays where any candidate has that many. Not seen: where the surface
    whose rim is near (:data:`lfsam.render.background_disparity.REACH`) and nearer than the one
    taken is neither seen nor refuted by any ray; where no ray sees any candidate.
    """
    # A plane that gives (about) the background disparity's value is the same candidate there:
    # its rays are looked at only where it departs from it.
    first = _gather(sources, n, ys, xs, candidates[0], offsets, sigma)
    colours, counts, refuted = [first[0]], [first[1]], [first[2]]
    for d in candidates[1:]:
        apart = (d - candidates[0]).abs() > SAME
        colour, count, refute = first[0].clone(), first[1].clone(), first[2].clone()
        if apart.any():
            part = _gather(sources, n, ys[apart], xs[apart], d[apart], offsets, sigma)
            colour[:, apart], count[apart], refute[apart] = part
        colours.append(colour)
        counts.append(count)
        refuted.append(refute)
    d = torch.stack(candidates)  # (C, P)
    count = torch.stack(counts)
    need = torch.where(count.amax(0) >= MIN_RAYS, MIN_RAYS, 1)
    supported = count >= need[None]
    score = torch.where(supported, d, torch.full_like(d, -float("inf")))
    best = score.argmax(0)
    colour = torch.stack(colours).gather(0, best[None, None].expand(1, 3, -1))[0]
    seen = count.gather(0, best[None])[0] >= need
    # A surface whose rim is near, nearer than the one taken, that no ray sees and none refutes
    # (every ray toward it hits the objects) may well continue there: not seen.
    likely = torch.zeros_like(d, dtype=torch.bool)
    if len(candidates) > 1:
        likely[1:] = torch.from_numpy(near[:, ys.cpu().numpy(), xs.cpu().numpy()]).to(d.device)
    open_ = likely & (count == 0) & ~torch.stack(refuted)
    open_ &= d > score.amax(0)[None] + DEPTH_TOLERANCE
    seen &= ~open_.any(0)
    return colour, seen


def _fill_view(sources, inside, n, hidden, offsets, depth, surfaces, sigma):
    """Colours of target view ``n``'s ``hidden`` pixels from the other views, and which got any.

    The candidates of each pixel (:func:`_choose`) span ``[lo, hi]``; the ray of view ``k``
    toward any of them lands within ``(hi - lo) / 2`` times the two views' distance of the ray
    toward their middle. Where that lies deeper inside view ``k``'s grown mask than this reach
    (``inside``: the distance to its edge; plus :data:`PRUNE_MARGIN` for the bilinear footprint)
    for every view ``k``, no ray can see the pixel: it is not seen, and its rays are never
    gathered (the same answer, for a fraction of the work on a large object). Each pixel's
    answer is its own: they go through in pieces of :data:`PIECE` (the same answer; the arrays
    over the views stay small).
    """
    ys, xs = torch.nonzero(hidden, as_tuple=True)
    planes, near = surfaces  # (K, 3) planes, (K, U, V) within reach of their rim
    candidates = [depth[n][ys, xs]]
    for a, b, c in planes:
        candidates.append((a + b * ys.double() + c * xs.double()).to(depth.dtype))
    colour = torch.zeros((3, ys.numel()), dtype=sources.dtype, device=sources.device)
    seen = torch.zeros(ys.numel(), dtype=torch.bool, device=sources.device)
    for start in range(0, ys.numel(), PIECE):
        piece = slice(start, start + PIECE)
        part = [c[piece] for c in candidates]
        open_ = _reachable(inside, n, ys[piece], xs[piece], part, offsets)
        if open_.any():
            index = torch.nonzero(open_)[:, 0] + start
            colour[:, index], seen[index] = _choose(
                sources, n, ys[index], xs[index], [c[open_] for c in part], near, offsets,
                sigma)
    return ys, xs, colour, seen


def _reachable(inside, n, ys, xs, candidates, offsets):
    """Which of target view ``n``'s pixels ``(ys, xs)`` some other view's ray may see at one
    of their candidates (:func:`_fill_view`)."""
    stacked = torch.stack(candidates)
    low, high = stacked.amin(0), stacked.amax(0)
    _, height, width = inside.shape
    rel = (offsets - offsets[n]).float()  # (N, 2): every view minus the target (0 for itself)
    middle = (low + high)[None] / 2
    u = ys.float()[None] - middle * rel[:, :1]
    v = xs.float()[None] - middle * rel[:, 1:]
    grid = _sample_grid(u, v, height, width)
    depth_in = F.grid_sample(inside[:, None], grid[:, None], mode="bilinear",
                             padding_mode="zeros", align_corners=True)[:, 0, 0]  # (N, P)
    reach = (high - low)[None] / 2 * rel.norm(dim=1)[:, None] + PRUNE_MARGIN
    others = torch.ones(rel.shape[0], dtype=torch.bool, device=rel.device)
    others[n] = False
    return ~(depth_in[others] > reach[others]).all(0)


def remove_objects(
    views: np.ndarray,
    masks: np.ndarray,
    disparity: np.ndarray,
    *,
    present: np.ndarray | None = None,
    grow: int = 1,
    sigma: float = SIGMA,
    device: str | torch.device | None = None,
    progress: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """The light field without the objects of ``masks``.

    Parameters
    ----------
    views : (S, T, U, V, 3) uint8 array
    masks : (S, T, U, V) bool array
        The objects to remove in every view (e.g. the union of a result's masks).
    disparity : (U, V) float array
        The center view's disparity (estimated from the views); the objects' own is replaced
        by what lies behind them (:func:`lfsam.render.background_disparity.background_center`).
    present : (S, T) bool array, optional
        Views that exist; absent views are neither filled nor used.
    grow : int
        Pixels by which the masks grow (their anti-aliased edges are replaced too).
    sigma : float
        Spread of the view weights, view steps.
    device : str or torch.device, optional
        Where to compute (default CPU).
    progress : bool
        Show progress bars over the views (their background disparities, then their fills).

    Returns
    -------
    views : (S, T, U, V, 3) uint8 array
        Every view with the objects' pixels filled.
    unseen : (S, T, U, V) bool array
        Pixels no other view sees, inpainted (flagged: never counted as filled from the views).

    Raises
    ------
    LfsamError
        If OpenCV is missing (``pip install 'lfsam[render]'``) or the masks do not fit.
    """
    require_cv2()
    views = np.asarray(views)
    masks = check_masks(masks, views)
    device = resolve_device("cpu" if device is None else device)
    chosen, offsets = select_views(views.shape[:2], present, None)
    hit = dilate(torch.from_numpy(np.stack([masks[s, t] for s, t in chosen])), grow)
    own = np.stack([masks[s, t] for s, t in chosen])
    depth, surfaces = view_backgrounds(disparity, own, offsets, device=device,
                                       with_surfaces=True, progress=progress)
    images = views_tensor(views, chosen, torch.device("cpu"))
    # The nearest surface within a pixel of each sample: a ray grazing a nearer object's
    # (anti-aliased) edge does not count as seeing the surface behind.
    nearest = F.max_pool2d(depth[:, None], 3, stride=1, padding=1)
    off = (~torch.from_numpy(own)).float()[:, None]  # off the objects themselves
    sources = torch.cat([images * off, (~hit).float()[:, None], nearest, off],
                        dim=1).to(device)
    # How deep inside its grown mask each pixel of each view lies (0 outside).
    inside = torch.from_numpy(np.stack([distance_transform_edt(h) for h in hit.numpy()]))
    inside = inside.float().to(device)
    out = np.array(views, copy=True)
    unseen = np.zeros(views.shape[:4], dtype=bool)
    offsets = offsets.to(device)
    depth = depth.to(device)

    def fill(n: int) -> None:
        s, t = chosen[n]
        if not hit[n].any():
            return
        ys, xs, colour, seen = _fill_view(sources, inside, n, hit[n].to(device), offsets,
                                          depth, surfaces[n], sigma)
        view = out[s, t]
        ys_np, xs_np = ys.cpu().numpy(), xs.cpu().numpy()
        filled = colour.T.round().clamp(0, 255).to(torch.uint8).cpu().numpy()
        seen_np = seen.cpu().numpy()
        view[ys_np[seen_np], xs_np[seen_np]] = filled[seen_np]
        holes = np.zeros(view.shape[:2], dtype=bool)
        holes[ys_np[~seen_np], xs_np[~seen_np]] = True
        if holes.any():
            out[s, t] = inpaint(view, holes)
            unseen[s, t] = holes

    # Each view is filled on its own (its own slices of ``out`` and ``unseen``).
    with ThreadPoolExecutor(max_workers=view_workers(device)) as pool:
        for _ in tqdm(pool.map(fill, range(len(chosen))), total=len(chosen), desc="removing",
                      unit="view", disable=not progress or None, leave=False):
            pass
    return out, unseen
