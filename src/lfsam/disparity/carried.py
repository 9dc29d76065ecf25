"""One view's estimate carried to every other view (docs/design.md section 12, "Depth per frame").

Estimating each view's disparity from scratch costs a full cost volume per view; a light field's
views share one scene, so the reference view's estimate already says where every surface it sees
lies in every other view. :func:`carry_estimate` forward-warps the reference's disparity into a
view (:func:`lfsam.disparity.center_warp.warp_center_disparity`: z-buffer, cracks closed, holes
filled along the epipolar line) and gives each carried pixel the reference's confidence at the
pixel it came from. A pixel the reference does not see gets confidence 0, so that consumers which
leave out unsure pixels (:func:`lfsam.spatial.points.object_points`, the pose tracker's
features) leave it out: its disparity was filled, not seen. These are

- holes of the forward warp (disocclusions, the strip entering at the frame's border), and
- pixels whose carried disparity the reference view does not confirm: at ``q + d (ds, dt)``,
  where the view's pixel ``q`` with disparity ``d`` is seen from the reference, the reference
  shows a surface more than ``agree`` pixels per view step away from ``d``.

The carried disparity is the reference's, so it has the reference's errors and no others; it
cannot see what only the other views see (an object's side hidden from the reference), and the
points of several carried views repeat the reference's errors instead of averaging them out.
For the pose tracker (issue 65) it is one estimate per frame instead of one per view, at a cost
in accuracy (docs/design.md section 12: on held-out seed 4 a median rotation error of 1.58
degrees against 0.87 from the center's and the corners' own estimates).
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import torch

from lfsam.devices import thread_share, threads_of, view_workers
from lfsam.disparity.center_warp import warp_center_disparity
from lfsam.disparity.epi import resolve_device
from lfsam.disparity.methods import estimate_disparity
from lfsam.errors import LfsamError
from lfsam.lightfield import LightField

__all__ = ["CARRY_AGREE", "ESTIMATE_MODES", "LIGHT_ESTIMATE", "carry_estimate", "estimate_views"]

#: How :func:`estimate_views` gets each view's disparity: each view's own estimate with the
#: estimator's light settings (:data:`LIGHT_ESTIMATE`, one per view), each view's own estimate
#: with ``lfsam disparity``'s defaults (one per view, about 3.5 times the time), or the center
#: view's estimate carried to the others (one estimate).
ESTIMATE_MODES = ("light", "own", "carried")

#: The occlusion-aware estimator's options of ``mode="light"`` (docs/design.md section 12,
#: "Depth per frame"): one feature scale, no structure-tensor fusion, no surface fit: the
#: half-grid cost volume, its oriented aggregation and the sub-pixel winner. Those three steps
#: sharpen depth edges and smooth weakly textured surfaces of a single map; the pose tracker
#: leaves out an object's rim and averages thousands of points over five views, where they
#: changed no pose beyond the targets (docs/performance.md, "Poses with estimated depth by
#: default") at 3.5 times the time.
LIGHT_ESTIMATE = {"wide_feature_radius": None, "fusion": False, "surface_fit": False}

#: A carried pixel keeps the reference's confidence when the reference shows its disparity
#: within this (pixels per view step) where it would see the pixel.
CARRY_AGREE = 0.1


def carry_estimate(
    disparity: np.ndarray | torch.Tensor,
    confidence: np.ndarray | torch.Tensor | None,
    offset: tuple[float, float],
    *,
    agree: float = CARRY_AGREE,
    device: str | torch.device | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The reference view's disparity and confidence carried into the view at ``offset``.

    Parameters
    ----------
    disparity : (U, V) array or tensor
        The reference view's disparity (pixels per view step, docs/design.md section 1).
    confidence : (U, V) array or tensor, optional
        Its confidence in [0, 1] (None: 1 everywhere, e.g. a ground truth).
    offset : (ds, dt)
        View-row and view-column offset of the target view from the reference view.
    agree : float
        How far (pixels per view step) the reference's disparity may differ from the carried
        one where it sees the pixel for the pixel to keep its confidence.
    device : str or torch.device, optional
        Where to compute; default CUDA when present, else the CPU.

    Returns
    -------
    disparity : (U, V) float32 ndarray
        The target view's disparity (module docstring).
    confidence : (U, V) float32 ndarray
        The reference's confidence at the pixel each carried pixel came from; 0 on holes and
        where the reference does not confirm the carried disparity.

    Examples
    --------
    >>> import numpy as np
    >>> d = np.full((4, 6), 1.0, dtype=np.float32)
    >>> carried, conf = carry_estimate(d, None, (0, 1))
    >>> carried[0].tolist(), conf[0].tolist()
    ([1.0, 1.0, 1.0, 1.0, 1.0, 1.0], [1.0, 1.0, 1.0, 1.0, 1.0, 0.0])
    """
    target = resolve_device(device)
    reference = torch.as_tensor(np.asarray(disparity, dtype=np.float32), device=target)
    if confidence is None:
        trust = torch.ones_like(reference)
    else:
        trust = torch.as_tensor(np.asarray(confidence, dtype=np.float32), device=target)
    carried, holes = warp_center_disparity(reference, offset, device=target)
    d = torch.as_tensor(carried, device=target)
    height, width = d.shape
    rows = torch.arange(height, device=target, dtype=torch.float32)[:, None]
    cols = torch.arange(width, device=target, dtype=torch.float32)[None, :]
    u = torch.round(rows + d * float(offset[0])).long()
    v = torch.round(cols + d * float(offset[1])).long()
    inside = (u >= 0) & (u < height) & (v >= 0) & (v < width)
    u, v = u.clamp(0, height - 1), v.clamp(0, width - 1)
    seen = (reference[u, v] - d).abs() <= agree
    keep = inside & seen & ~torch.as_tensor(holes, device=target)
    out = torch.where(keep, trust[u, v], torch.zeros_like(d))
    return carried.astype(np.float32), out.cpu().numpy().astype(np.float32)


def estimate_views(
    lightfield: LightField,
    views: Sequence[tuple[int, int]],
    *,
    mode: str = "own",
    device: str | torch.device | None = None,
) -> dict[tuple[int, int], tuple[np.ndarray, np.ndarray]]:
    """Estimated disparity and confidence of each of ``views`` (module docstring).

    Parameters
    ----------
    lightfield : LightField
        One frame's light field.
    views : sequence of (s, t)
        The views wanted (0-based view row and column).
    mode : {"light", "own", "carried"}
        ``"light"``: every view is estimated on its own with :data:`LIGHT_ESTIMATE` (a cost
        volume per view: as many times the cost as there are views) over the disparity range
        found with the first view (:func:`lfsam.disparity.range.estimate_disparity_range`, once:
        the views share one scene), the other views two at a time on a CPU
        (:func:`lfsam.devices.view_workers`, threads; the same arrays as one at a time);
        ``"own"``: the same with the estimator's defaults (``lfsam
        disparity``'s estimate); ``"carried"``: the center view is estimated once with the
        defaults and carried to every other view (:func:`carry_estimate`).
    device : str or torch.device, optional

    Returns
    -------
    dict of (s, t) -> (disparity, confidence), float32 (U, V) arrays

    Raises
    ------
    LfsamError
        An unknown mode, or what the estimator raises.
    """
    if mode not in ESTIMATE_MODES:
        raise LfsamError(f"estimate mode must be one of {ESTIMATE_MODES}, got {mode!r}")
    wanted = [(int(s), int(t)) for s, t in views]
    if mode in ("light", "own"):
        options = LIGHT_ESTIMATE if mode == "light" else {}
        if not wanted:
            return {}

        def estimate(view: tuple[int, int], span: tuple[float, float] | None):
            found = estimate_disparity(lightfield, span, device=device, view=view, **options)
            return found.disparity_range, (np.asarray(found.disparity),
                                           np.asarray(found.confidence))

        # the scene's disparity range: found with the first view, kept for the rest, which are
        # estimated a few at a time (each view's estimate is its own: the same arrays as one
        # after the other)
        span, first = estimate(wanted[0], None)
        out = {wanted[0]: first}
        rest = list(dict.fromkeys(view for view in wanted[1:] if view != wanted[0]))
        target = resolve_device(device)
        workers = view_workers(target)
        share = thread_share(workers, target)

        def estimate_rest(view: tuple[int, int]):
            with threads_of(share):  # each view at its share of torch's threads
                return estimate(view, span)

        with ThreadPoolExecutor(max_workers=workers) as pool:
            for view, (_, found) in zip(rest, pool.map(estimate_rest, rest), strict=True):
                out[view] = found
        return out
    center = tuple(int(x) for x in lightfield.center)
    found = estimate_disparity(lightfield, device=device, view=center)
    reference = np.asarray(found.disparity, dtype=np.float32)
    trust = np.asarray(found.confidence, dtype=np.float32)
    return {
        view: (reference, trust) if view == center else carry_estimate(
            reference, trust, (view[0] - center[0], view[1] - center[1]), device=device
        )
        for view in wanted
    }
