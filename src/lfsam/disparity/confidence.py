"""Per-pixel confidence of a cost-volume disparity: a clear minimum, consistent across views.

Two cues, each in [0, 1], multiplied (docs/design.md section 3.2):

- *Cost-curve margin* (:func:`margin_confidence`). A reliable pixel has one clear minimum along
  its aggregated cost curve. With ``c1`` its best cost and ``c2`` the lowest cost more than
  ``exclude`` hypotheses away from the best one (the second-best minimum), the margin
  ``(c2 - c1) / (c2 + floor)`` is near 0 where several disparities explain the views equally well
  (textureless regions, repeated texture, a specular highlight that moves with the view) and near
  1 for a sharp, unique minimum (Hu & Mordohai, "A quantitative evaluation of confidence measures
  for stereo vision", TPAMI 2012, the "peak ratio" family).
- *Left-right consistency* (:func:`consistency_confidence`). The same cost volume, re-indexed for
  an outer view ``o`` (``C_o(q, d) = C(q + d o, d)``: the reference pixel that view ``o`` sees at
  ``q`` if the disparity is ``d``), gives by winner-take-all the disparity map of view ``o``; a
  reference pixel whose disparity ``d`` points to a pixel of view ``o`` with a different winner is
  occluded there or wrong (the left-right check of two-view stereo, here between the reference and
  the outermost views of its row and column; Chen et al., "Light field stereo matching using
  bilateral statistics of surface cameras", CVPR 2014, detect such occlusions from the
  consistency of a pixel's samples across views). The agreement is
  ``exp(-(|d - d_o| / sigma)^2)``, the smallest over the views checked.

Low values therefore mark occlusion edges, textureless and non-Lambertian regions. The confidence
can weigh a disparity map in any later step (e.g. a confidence-weighted smoothing, or a sparse
fill that keeps only confident pixels and prefers refined sources elsewhere).
"""

from __future__ import annotations

import torch

__all__ = ["combine_confidence", "consistency_confidence", "margin_confidence"]


def margin_confidence(
    cost: torch.Tensor, best_index: torch.Tensor, exclude: int = 2, floor: float = 1e-3
) -> torch.Tensor:
    """``(c2 - c1) / (c2 + floor)`` from an aggregated cost volume (module docstring).

    Parameters
    ----------
    cost : torch.Tensor, shape (D, U, V)
        Aggregated costs (lower = better).
    best_index : torch.Tensor, shape (U, V), int64
        The winner-take-all hypothesis of every pixel.
    exclude : int
        Hypotheses within this many steps of the best one belong to its minimum and are not
        candidates for the second-best.
    floor : float
        Regulariser of the denominator (costs near 0 everywhere are not a clear minimum).

    Returns
    -------
    torch.Tensor, shape (U, V), in [0, 1]
    """
    count = cost.shape[0]
    best = cost.gather(0, best_index[None])[0]
    hypothesis = torch.arange(count, device=cost.device).view(count, 1, 1)
    near = (hypothesis - best_index[None]).abs() <= exclude
    if bool(near.all()):
        return torch.zeros_like(best)
    second = cost.masked_fill(near, float("inf")).amin(0)
    return ((second - best) / (second + floor)).clamp(0.0, 1.0)


def _view_disparity(cost: torch.Tensor, hypotheses: torch.Tensor, offset: tuple[int, int]):
    """Winner-take-all disparity of the view at ``offset`` from the reference's cost volume.

    Slice ``k`` is shifted by ``hypotheses[k] * offset`` (rounded to whole pixels): view pixel
    ``q`` takes the cost of reference pixel ``q + d offset``; pixels that fall outside the frame
    cost ``inf``.
    """
    count, rows, cols = cost.shape
    shift_u = torch.round(hypotheses * offset[0]).long().tolist()
    shift_v = torch.round(hypotheses * offset[1]).long().tolist()
    best = torch.full((rows, cols), float("inf"), device=cost.device)
    winner = torch.zeros((rows, cols), device=cost.device)
    covered = torch.zeros((rows, cols), dtype=torch.bool, device=cost.device)
    # slice by slice, the running minimum (the first hypothesis wins a tie, as argmin): each
    # slice moves by whole pixels, so only its overlap with the frame is compared
    for k in range(count):
        du, dv = shift_u[k], shift_v[k]
        target_u = slice(max(0, -du), min(rows, rows - du))
        target_v = slice(max(0, -dv), min(cols, cols - dv))
        if target_u.start >= target_u.stop or target_v.start >= target_v.stop:
            continue
        source = cost[k, target_u.start + du : target_u.stop + du,
                      target_v.start + dv : target_v.stop + dv]
        region = best[target_u, target_v]
        lower = source < region
        region.copy_(torch.minimum(region, source))
        winner[target_u, target_v].masked_fill_(lower, float(k))
        covered[target_u, target_v] = True
    return hypotheses[winner.long()], covered


def consistency_confidence(
    cost: torch.Tensor,
    hypotheses: torch.Tensor,
    disparity: torch.Tensor,
    offsets: list[tuple[int, int]],
    sigma: float,
) -> torch.Tensor:
    """Agreement of the reference's disparity with the views at ``offsets`` (module docstring).

    Parameters
    ----------
    cost : torch.Tensor, shape (D, U, V)
        Aggregated cost volume of the reference view.
    hypotheses : torch.Tensor, shape (D,)
        Its disparity hypotheses.
    disparity : torch.Tensor, shape (U, V)
        The reference's disparity (winner-take-all, possibly sub-pixel).
    offsets : list of (ds, dt)
        View offsets to check (e.g. the outermost views of the reference's row and column).
    sigma : float
        Disagreement (pixels per view step) at which the agreement falls to ``1/e``.

    Returns
    -------
    torch.Tensor, shape (U, V), in [0, 1]
        1 where every checked view agrees; pixels that leave a view's frame are not judged by it.
    """
    rows, cols = disparity.shape
    device = disparity.device
    u = torch.arange(rows, device=device, dtype=torch.float32)[:, None]
    v = torch.arange(cols, device=device, dtype=torch.float32)[None, :]
    agreement = torch.ones_like(disparity)
    for offset in offsets:
        other, covered = _view_disparity(cost, hypotheses, offset)
        # reference pixel p is seen in the view at p - d offset (docs/design.md section 1)
        q_u = torch.round(u - disparity * offset[0]).long()
        q_v = torch.round(v - disparity * offset[1]).long()
        inside = (q_u >= 0) & (q_u < rows) & (q_v >= 0) & (q_v < cols)
        q_u, q_v = q_u.clamp(0, rows - 1), q_v.clamp(0, cols - 1)
        seen = other[q_u, q_v]
        judged = inside & covered[q_u, q_v]
        score = torch.exp(-(((disparity - seen) / sigma) ** 2))
        agreement = torch.minimum(agreement, torch.where(judged, score, 1.0))
    return agreement


def combine_confidence(*parts: torch.Tensor) -> torch.Tensor:
    """The product of confidence cues (each in [0, 1]), clamped to [0, 1]."""
    result = parts[0]
    for part in parts[1:]:
        result = result * part
    return result.clamp(0.0, 1.0)
