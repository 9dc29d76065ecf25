"""The default disparity estimator: an occlusion-aware cost volume, edge-aware aggregation,
winner-take-all with sub-pixel refinement, and a confidence map (docs/design.md section 3.2).

Steps, all whole-image torch operations (any device, CUDA when present):

1. *Hypotheses.* ``D`` disparities evenly spaced over the range (given, or found by the coarse
   sweep of :mod:`lfsam.disparity.range`): at least ``num_hypotheses`` and at most ``max_step``
   apart.
2. *Cost volume* (:mod:`lfsam.disparity.cost_volume`): every present view of the grid resampled
   at each hypothesis, truncated differences of locally normalised intensities, the best of the
   four half-grids per pixel where one is clearly better than all views together
   (occlusion-aware view selection after Wang et al., ICCV 2015), else all views.
3. *Aggregation* (:mod:`lfsam.disparity.aggregation`). Every cost slice is smoothed by a colour
   guided filter with the reference view as the guide (He et al. 2010, as the cost-volume filter
   of Hosni et al. 2013) over a square and over a horizontal and a vertical line window, and every
   pixel keeps the window with the lowest cost: costs are averaged over a window that does not
   cross the reference's colour edges (where depth edges usually are) and, on a surface slanted in
   depth, can follow a line of constant disparity. ``aggregation="guided"`` keeps the earlier gray
   guided filter over one square window.
4. *Winner-take-all and sub-pixel refinement.* The lowest aggregated cost per pixel, refined by
   the equiangular (V-shaped) line fit through it and its two neighbours (the step between
   hypotheses is then no longer the resolution; :func:`subpixel_winner`).
5. *Confidence* (:mod:`lfsam.disparity.confidence`): the cost-curve margin times the left-right
   consistency with the outermost views of the reference's row and column.
   Steps 2-5 run with two feature scales (3 x 3 and 5 x 5 normalisation windows), and every
   pixel keeps the 5 x 5 result away from intensity edges and depth jumps
   (:mod:`lfsam.disparity.feature_scales`).
6. *Fusion* (:mod:`lfsam.disparity.fusion`, when the reference's row and column are complete):
   the structure tensor's disparity where this one is unsure, the tensor sure and its value
   farther (the bands along depth edges), the mean of the two where they agree within a
   quarter step.
   *Surface fit* (issue 45's fifth round; :mod:`lfsam.disparity.surface_fit`): the pixels away
   from intensity edges and depth jumps (those of the 5 x 5 features) take the centre of a
   robust, colour-weighted local quadratic fit of the disparity over 15 x 15 pixels: the noise
   of dark, weakly textured surfaces, slanted or curved, averaged without flattening them.
7. *Learned refinement* (optional, ``learned_refinement=True``;
   :mod:`lfsam.disparity.learned_refiner`, issue 45's fourth round): a
   small network trained on lfsam's synthetic scenes only moves each pixel to the disparity of
   a neighbour 2-6 px away where the colour and the disparity around it say so (the foreground
   spread onto the background at depth jumps); elsewhere the value stays.

Measured (``benchmarks/bench_disparity.py``; docs/performance.md, "Disparity"): BadPix(0.07) on
HCI antinous 3.8 % and cotton 2.3 % (8-pixel border excluded; over all pixels 4.5 % and 2.3 %;
5.4 % and 2.3 % before issue 45's surface fit, 7.3 % and 2.6 % border excluded before its
view-set choice and aggregation, 6.1 % and 2.2 % before its two feature scales and farther-only
fusion), lower BadPix and MSE than the sheared structure
tensor on the synthetic scenes.
"""

from __future__ import annotations

import math
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import torch

from lfsam.devices import thread_share, threads_of, view_workers
from lfsam.disparity.aggregation import aggregate_costs
from lfsam.disparity.confidence import (
    combine_confidence,
    consistency_confidence,
    margin_confidence,
)
from lfsam.disparity.cost_volume import ViewSet, build_cost_volume, matching_features, view_set
from lfsam.disparity.estimate import DisparityEstimate
from lfsam.disparity.feature_scales import fine_scale_mask
from lfsam.disparity.filters import guided_filter
from lfsam.disparity.fusion import fuse_disparities
from lfsam.disparity.learned_refiner import refine_with_network
from lfsam.disparity.range import estimate_disparity_range
from lfsam.disparity.refine import refine_disparity
from lfsam.disparity.structure_tensor import (
    estimate_disparity as estimate_disparity_structure_tensor,
)
from lfsam.disparity.surface_fit import fit_surface
from lfsam.errors import LfsamError
from lfsam.lightfield import LightField

__all__ = [
    "disparity_hypotheses",
    "estimate_disparity_occlusion_aware",
    "subpixel_winner",
]


def disparity_hypotheses(
    disparity_range: tuple[float, float], count: int = 32, max_step: float = 0.25
) -> np.ndarray:
    """Evenly spaced hypotheses from ``lo`` to ``hi`` (both included).

    Parameters
    ----------
    disparity_range : (lo, hi)
        Pixels per view step, ``lo <= hi``.
    count : int
        Fewest hypotheses (>= 3, so that every minimum has two neighbours to fit).
    max_step : float
        Largest spacing; a wide range gets more hypotheses.

    Returns
    -------
    ndarray of float64, increasing (a single value when ``lo == hi``)

    Raises
    ------
    LfsamError
        If the range is not finite and ordered, or ``count < 3`` or ``max_step <= 0``.
    """
    lo, hi = (float(x) for x in disparity_range)
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
        raise LfsamError(
            f"invalid disparity range {lo:g},{hi:g}: give LO,HI with LO <= HI in pixels per view"
        )
    if count < 3 or not max_step > 0:
        raise LfsamError(f"need at least 3 hypotheses and a positive step, got {count}, {max_step}")
    if hi == lo:
        return np.array([lo])
    total = max(count, math.ceil((hi - lo) / max_step) + 1)
    return np.linspace(lo, hi, total)


def subpixel_winner(
    cost: torch.Tensor, hypotheses: torch.Tensor, fit: str = "equiangular"
) -> tuple[torch.Tensor, torch.Tensor]:
    """Winner-take-all over the first axis, refined by a fit through the two neighbours.

    With ``c_-, c_0, c_+`` the costs at the winner and its two neighbours, the minimum lies at

    - ``fit="equiangular"`` (default): the crossing of two lines of opposite slopes through them,
      ``(c_- - c_+) / (2 max(c_- - c_0, c_+ - c_0))`` steps from the winner: the exact minimum of
      a V-shaped cost, which is what sums of absolute differences give near the true disparity
      (Shimizu & Okutomi, "Sub-pixel estimation error cancellation on area-based matching",
      IJCV 2005, compare it with the parabola; docs/design.md section 3.2);
    - ``fit="parabola"``: the vertex ``(c_- - c_+) / (2 (c_- - 2 c_0 + c_+))`` steps from it,
      the exact minimum of a quadratic cost (biased towards the hypotheses on V-shaped costs).

    The offset is clamped to half a step; winners at either end of the range are not refined.

    Parameters
    ----------
    cost : torch.Tensor, shape (D, U, V)
    hypotheses : torch.Tensor, shape (D,), evenly spaced
    fit : {"equiangular", "parabola"}

    Returns
    -------
    disparity : torch.Tensor, shape (U, V)
    index : torch.Tensor, shape (U, V), int64
        The winning hypothesis.

    Raises
    ------
    LfsamError
        If ``fit`` is not one of the two.
    """
    if fit not in ("equiangular", "parabola"):
        raise LfsamError(f"unknown sub-pixel fit {fit!r}: use 'equiangular' or 'parabola'")
    count = cost.shape[0]
    best, index = cost.min(0)
    if count < 3:
        return hypotheses[index], index
    step = float(hypotheses[1] - hypotheses[0])
    below = cost.gather(0, (index - 1).clamp(min=0)[None])[0]
    above = cost.gather(0, (index + 1).clamp(max=count - 1)[None])[0]
    if fit == "parabola":
        denominator = below - 2.0 * best + above
    else:
        denominator = torch.maximum(below - best, above - best)
    offset = torch.where(
        denominator > 1e-12, (below - above) / (2.0 * denominator.clamp(min=1e-12)), 0.0
    )
    offset = offset.clamp(-0.5, 0.5)
    offset = torch.where((index > 0) & (index < count - 1), offset, 0.0)
    return hypotheses[index] + offset * step, index


def _check_offsets(offsets: np.ndarray) -> list[tuple[int, int]]:
    """The outermost present views of the reference's row and column on each side."""
    chosen = []
    for axis in (0, 1):
        line = offsets[offsets[:, 1 - axis] == 0]
        for sign in (-1, 1):
            side = line[np.sign(line[:, axis]) == sign]
            if len(side):
                far = side[np.abs(side[:, axis]).argmax()]
                chosen.append((int(far[0]), int(far[1])))
    return chosen


def _full_cross(views: LightField | np.ndarray, offsets: np.ndarray) -> bool:
    """Whether every view of the reference's row and column is present (the structure tensor
    of a fusion then sees complete EPIs; on a sparse row it is sure and wrong too often)."""
    s_count, t_count = (views.views if isinstance(views, LightField) else views).shape[:2]
    in_row = int(np.sum(offsets[:, 0] == 0)) if len(offsets) else 0
    in_column = int(np.sum(offsets[:, 1] == 0)) if len(offsets) else 0
    return in_row == t_count - 1 and in_column == s_count - 1


def _without_grad(threads, function, *args, **kwargs):
    """``function(*args, **kwargs)`` without autograd (a thread does not inherit the caller's
    ``torch.no_grad``), at ``threads`` torch threads (:func:`lfsam.devices.thread_share`)."""
    with torch.no_grad(), threads_of(threads):
        return function(*args, **kwargs)


def _wide_scale(views_around: ViewSet, radius: int, eps: float, hypotheses: np.ndarray,
                scale_options: dict) -> tuple[torch.Tensor, torch.Tensor]:
    """The disparity and confidence of the second, wider feature window
    (:mod:`lfsam.disparity.feature_scales`)."""
    wide = views_around.with_features(
        matching_features(views_around.grays, radius, eps),
        matching_features(views_around.gray, radius, eps),
    )
    return _estimate_one_scale(wide, hypotheses, **scale_options)


def _estimate_one_scale(
    views_around: ViewSet,
    hypotheses: np.ndarray,
    *,
    truncation: float,
    selection_radius: int,
    occlusion_aware: bool,
    full_set_ratio: float | None,
    aggregation: str,
    aggregation_radius: int,
    line_radius: int,
    aggregation_eps: float,
    subpixel_fit: str,
    step: float,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Steps 2-5 of the module docstring with the features of ``views_around``: the disparity
    (winner-take-all, sub-pixel) and its confidence."""
    cost = build_cost_volume(
        views_around,
        hypotheses,
        truncation=truncation,
        selection_radius=selection_radius,
        occlusion_aware=occlusion_aware,
        full_set_ratio=full_set_ratio,
    )
    if aggregation == "oriented":
        cost = aggregate_costs(
            cost,
            views_around.colour,
            square_radius=aggregation_radius,
            line_radius=line_radius,
            eps=aggregation_eps,
        )
    else:
        cost = guided_filter(views_around.gray, cost, aggregation_radius, aggregation_eps)
    cost = cost.contiguous()
    values = torch.as_tensor(hypotheses, dtype=torch.float32, device=cost.device)
    disparity, index = subpixel_winner(cost, values, subpixel_fit)
    margin = margin_confidence(cost, index)
    agreement = consistency_confidence(
        cost, values, disparity, _check_offsets(views_around.offsets), sigma=max(step, 0.1)
    )
    return disparity, combine_confidence(margin, agreement)


def estimate_disparity_occlusion_aware(
    views: LightField | np.ndarray,
    disparity_range: tuple[float, float] | None = None,
    *,
    device: str | torch.device | None = None,
    view: tuple[int, int] | None = None,
    num_hypotheses: int = 32,
    max_step: float = 0.25,
    feature_radius: int = 1,
    feature_eps: float = 0.002,
    wide_feature_radius: int | None = 2,
    truncation: float = 1.0,
    selection_radius: int = 2,
    occlusion_aware: bool = True,
    full_set_ratio: float | None = 0.08,
    aggregation: str = "oriented",
    aggregation_radius: int = 4,
    line_radius: int = 8,
    aggregation_eps: float = 1e-4,
    edge_refinement: bool = False,
    subpixel_fit: str = "equiangular",
    surface_fit: bool = True,
    fusion: bool = True,
    learned_refinement: bool = False,
) -> DisparityEstimate:
    """Estimate a view's disparity from an occlusion-aware cost volume (module docstring).

    Parameters
    ----------
    views : LightField or ndarray, shape (S, T, U, V, 3), uint8
        The light field. Every present view takes part (absent views of a partial grid,
        ``LightField.present``, are skipped); the reference's row or column needs three present
        views.
    disparity_range : (lo, hi), optional
        Disparities to search, pixels per view step; estimated from the data when omitted
        (:func:`lfsam.disparity.range.estimate_disparity_range`). The result lies within it.
    device : str or torch.device, optional
        Where to compute; default ``auto`` (:func:`lfsam.devices.resolve_device`).
    view : (s, t), optional
        The view whose disparity is estimated (0-based view row and column, docs/design.md
        section 8); default the center view.
    num_hypotheses : int
        Fewest disparity hypotheses (the time grows linearly with their number).
    max_step : float
        Largest spacing of the hypotheses (pixels per view step).
    feature_radius, feature_eps : int, float
        Window radius and regulariser of the local intensity normalisation
        (:func:`lfsam.disparity.cost_volume.matching_features`).
    wide_feature_radius : int, optional
        Radius of the second, wider feature window, whose result replaces the fine one's away
        from intensity edges and depth jumps (:mod:`lfsam.disparity.feature_scales`; about 1.6
        times the time); None (or ``feature_radius``): one scale only (before issue 45's third
        round).
    truncation : float
        Largest cost of one view at one pixel.
    selection_radius : int
        Window radius over which the half-grids are compared.
    occlusion_aware : bool
        Keep the best half-grid where one is clearly better (True) or average all views.
    full_set_ratio : float, optional
        How much lower (relative) the best half's cost must be for it to replace all views
        (:func:`lfsam.disparity.cost_volume.build_cost_volume`); None: always the best half (the
        estimator before issue 45).
    aggregation : {"oriented", "guided"}
        ``"oriented"``: colour guided filter over a square and two line windows, the best window
        per pixel (:func:`lfsam.disparity.aggregation.aggregate_costs`); ``"guided"``: the gray
        guided filter over the square window only (before issue 45, with radius 3).
    aggregation_radius, aggregation_eps : int, float
        Radius of the square window and regulariser of the guided filter.
    line_radius : int
        Half length of the line windows of ``aggregation="oriented"`` (0: square only).
    edge_refinement : bool
        Finish with the confidence-weighted joint bilateral smoothing of
        :func:`lfsam.disparity.refine.refine_disparity` (off by default: on HCI antinous it
        blurs sub-pixel detail more than it repairs; ``benchmarks/bench_disparity.py``).
    subpixel_fit : {"equiangular", "parabola"}
        The sub-pixel fit of :func:`subpixel_winner` (the equiangular one is the more precise
        on every bench scene; docs/performance.md).
    surface_fit : bool
        Replace the disparity of the pixels away from intensity edges and depth jumps by a
        robust, colour-weighted local quadratic fit over 15 x 15 pixels
        (:func:`lfsam.disparity.surface_fit.fit_surface`, issue 45's fifth round): it averages
        the noise of dark, weakly textured surfaces, slanted or curved, without flattening
        them. About 1.4 s on 512 x 512 on one CPU thread.
    fusion : bool
        Fuse with the structure tensor's disparity over the same range
        (:func:`lfsam.disparity.fusion.fuse_disparities`): its value where this estimate is
        unsure and the tensor sure and farther (depth edges), the mean where both agree. About
        1.6 times the time; the confidence stays this estimator's. Only where the reference's
        row and column are complete (a sparse partial grid skips it).
    learned_refinement : bool
        Finish with the small network of :mod:`lfsam.disparity.learned_refiner`, trained on
        lfsam's synthetic scenes only, which corrects the disparity from the reference's colour,
        the disparity and its confidence (step 7 of the module docstring). Off by default: it
        lowers BadPix(0.07) on HCI cotton and the synthetic scenes but not on HCI antinous, and
        it moves some foreground pixels at object outlines to the background
        (docs/performance.md, "Fourth round").

    Returns
    -------
    DisparityEstimate
        ``disparity`` and ``confidence`` (in [0, 1]) of the view, the range searched, ``meta``.

    Raises
    ------
    LfsamError
        View outside the grid or absent, too few views in its row and column, an invalid range,
        or an unknown ``aggregation``.
    """
    if aggregation not in ("oriented", "guided"):
        raise LfsamError(f"unknown aggregation {aggregation!r}: use 'oriented' or 'guided'")
    start = time.perf_counter()
    with torch.no_grad():
        views_around = view_set(
            views, view, device=device, feature_radius=feature_radius, feature_eps=feature_eps
        )
        reference = views_around.reference
        source = "given"
        if disparity_range is None:
            disparity_range = estimate_disparity_range(views, device=device, view=reference)
            source = "estimated"
        hypotheses = disparity_hypotheses(disparity_range, num_hypotheses, max_step)
        lo, hi = float(hypotheses[0]), float(hypotheses[-1])
        step = float(hypotheses[1] - hypotheses[0]) if len(hypotheses) > 1 else 1.0
        scale_options = {
            "truncation": truncation,
            "selection_radius": selection_radius,
            "occlusion_aware": occlusion_aware,
            "full_set_ratio": full_set_ratio,
            "aggregation": aggregation,
            "aggregation_radius": aggregation_radius,
            "line_radius": line_radius,
            "aggregation_eps": aggregation_eps,
            "subpixel_fit": subpixel_fit,
            "step": step,
        }
        fused = fusion and _full_cross(views, views_around.offsets)
        two_scales = wide_feature_radius is not None and wide_feature_radius != feature_radius
        # the wide scale and the structure tensor do not depend on the fine scale: they run
        # beside it (threads; on a CPU one estimate's many small operations leave a core idle),
        # each giving what it gives alone, each stream at its share of torch's threads (on 2
        # cores: one each)
        share = thread_share(1 + int(fused) + int(two_scales), views_around.device)
        with ThreadPoolExecutor(max_workers=view_workers(views_around.device)) as pool:
            tensor_job = pool.submit(
                _without_grad, share, estimate_disparity_structure_tensor, views, (lo, hi),
                device=views_around.device, view=reference,
            ) if fused else None
            wide_job = pool.submit(
                _without_grad, share, _wide_scale, views_around, wide_feature_radius,
                feature_eps, hypotheses, scale_options,
            ) if two_scales else None
            with threads_of(share):
                disparity, confidence = _estimate_one_scale(views_around, hypotheses,
                                                            **scale_options)
            fine = None
            if wide_job is not None:
                wide_disparity, wide_confidence = wide_job.result()
                fine = fine_scale_mask(views_around.gray, disparity)
                disparity = torch.where(fine, disparity, wide_disparity)
                confidence = torch.where(fine, confidence, wide_confidence)
            tensor = tensor_job.result() if tensor_job is not None else None
        if fused:
            disparity = fuse_disparities(
                disparity,
                confidence,
                torch.as_tensor(tensor.disparity, device=disparity.device),
                torch.as_tensor(tensor.confidence, device=disparity.device),
                step,
            )
        if surface_fit:
            away = ~fine_scale_mask(views_around.gray, disparity) if fine is None else ~fine
            guide = views_around.colour
            guide = views_around.gray if guide is None else guide
            disparity = fit_surface(disparity, away, guide)
        if edge_refinement:
            guide = views_around.gray[None]
            disparity = refine_disparity(disparity, confidence, guide)
        if learned_refinement:
            colour = views_around.colour
            if colour is None:
                colour = views_around.gray[None].expand(3, -1, -1)
            disparity = refine_with_network(colour, disparity, confidence, (lo, hi))
        disparity = disparity.clamp(lo, hi)
    meta = {
        "method": "occlusion-aware cost volume",
        "view": list(reference),
        "range_source": source,
        "hypotheses": len(hypotheses),
        "step": round(step, 5),
        "views_used": len(views_around.offsets) + 1,
        "feature_radius": feature_radius,
        "feature_eps": feature_eps,
        "wide_feature_radius": wide_feature_radius,
        **{key: value for key, value in scale_options.items() if key != "step"},
        "edge_refinement": edge_refinement,
        "surface_fit": surface_fit,
        "fusion": fused,
        "learned_refinement": learned_refinement,
        "device": str(views_around.device),
        "seconds": time.perf_counter() - start,
    }
    return DisparityEstimate(
        disparity=disparity.float().cpu().numpy(),
        confidence=confidence.float().cpu().numpy(),
        disparity_range=(lo, hi),
        meta=meta,
    )
