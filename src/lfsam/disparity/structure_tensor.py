"""A view's disparity from the structure tensor on sheared EPIs (torch, vectorised).

This is the disparity step of the pipeline (paper section 3.2; docs/design.md section 3.2).

Orientation. On an epipolar-plane image ``E(n, x)`` (view ``n`` along one direction, pixel ``x``
along the same direction) a scene point of disparity ``d`` draws the line ``x = x_0 - d (n - n_c)``
(docs/design.md section 1), so ``E(n, x) = f(x + d (n - n_c))``. The structure tensor

    J = G_outer * (grad E  grad E^T),   grad E = (dE/dn, dE/dx)

of the pre-smoothed EPI (inner scale) has the dominant eigenvector ``(d, 1) / |(d, 1)|``; its angle
gives the disparity and its coherence ``sqrt((J_xx - J_nn)^2 + 4 J_nx^2) / (J_nn + J_xx)`` says how
line-like the neighbourhood is (Wanner & Goldluecke, "Globally consistent depth labeling of 4D
light fields", CVPR 2012, section 3.1; "Variational light field analysis for disparity estimation
and super-resolution", TPAMI 2014, section 4.1). The reference view's row of views (the center
view by default; any view, docs/design.md section 8) gives the horizontal EPIs, its column the
vertical ones, absent views of a partial grid left out; per pixel, the direction with the lower
photo-consistency cost (below) wins (Wanner & Goldluecke fuse by coherence; on our benchmark
scenes and on HCI antinous the cost is the better judge).

Large disparities (multi-hypothesis scheme). Derivatives across views alias once a line moves by
more than about a pixel per view, so the plain structure tensor breaks beyond about +-1 to 2 px
per view step. As in Diebold & Goldluecke ("Epipolar plane image refocusing for improved depth
estimation and occlusion handling", VMV 2013), the EPI is *sheared* to candidate disparities ``c``
spaced at most ``candidate_step`` apart (view ``n`` shifted by ``c (n - n_c)`` pixels, so that
structures at disparity ``c`` become vertical) and the structure tensor measures the small residual
``r`` on each sheared EPI, clamped to the candidate's band ``|r| <= step / 2 + margin``. Each pixel
keeps ``c + r`` from the candidate that best explains the views:

- *Residual-corrected photo-consistency.* The score of a candidate is the mean squared difference
  between each view of the sheared stack and the reference view, linearised around the residual,
  ``sum_n (E_n - E_c - r o_n dE_n/dx)^2`` (the Lucas-Kanade data term, Lucas & Kanade, IJCAI
  1981), aggregated by the outer Gaussian. Without the correction a candidate whose residual is
  0.5 would lose to a neighbour that only looks closer.
- *Occlusion-aware halves.* Terms are accumulated separately for the views before and after the
  reference view (half-EPIs); each candidate uses the half with the lower score, because an
  occluder enters the EPI from one side only (Wang, Efros & Ramamoorthi, "Occlusion-aware depth
  estimation using light-field cameras", ICCV 2015, section 4). A reference view at the end of
  its row or column (edge and corner views, docs/design.md section 8) has views on one side only;
  its halves are then the nearer and the farther half of that side.
- *Shiftable windows.* Each candidate's score is taken as the minimum over aggregation windows
  centred up to ``shift_radius`` pixels away, with the residual of that window (Bobick & Intille,
  "Large occlusion stereo", IJCV 1999), which keeps foreground structure from leaking across
  depth edges into the background ("edge fattening").

Implementation notes. The shear is an exact sub-pixel shift in the Fourier domain along the pixel
axis (after replicate padding, so nothing wraps around); the inner Gaussian and the spatial
derivative are applied there too (both commute with the shift), so each candidate costs one
inverse FFT of the stack. Derivatives across views are central differences paired with the Scharr
smoothing ``[3, 10, 3] / 16`` of the spatial derivative: for ``E = f(x + r n)`` their Taylor errors
cancel to order ``r^3`` (``1/6`` against ``6/32``), which keeps the residual unbiased to a few
thousandths of a pixel for ``|r| <= 0.5``. Candidates are spaced 0.5 px per view step by default:
the linearised cost is then used only for residuals up to 0.25, i.e. at most one pixel of motion
at the outermost view of a 9-view EPI (with 1 px spacing the wall of HCI antinous, at -3, fell
between candidates and its BadPix(0.07) rose by 8 points).

Refinement. The local estimate is finished by a confidence-weighted joint bilateral filter guided
by the reference view (:mod:`lfsam.disparity.refine`), which averages the noise of weakly textured
regions and votes away isolated gross errors at occlusion edges.
"""

from __future__ import annotations

import math
import time

import numpy as np
import torch
import torch.nn.functional as F

from lfsam.disparity.epi import EpiStack, as_views, epi_stacks, resolve_view
from lfsam.disparity.estimate import DisparityEstimate
from lfsam.disparity.filters import (
    CHUNK_ELEMENTS,
    gaussian_blur,
    gaussian_kernel1d,
    smooth_axis,
)
from lfsam.disparity.range import estimate_disparity_range
from lfsam.disparity.refine import refine_disparity
from lfsam.errors import LfsamError
from lfsam.lightfield import LightField

__all__ = ["candidate_disparities", "estimate_disparity", "orientation_from_tensor"]

# Regularises the coherence denominator: gradient energy below this (intensities in [0, 1],
# squared per pixel) counts as no texture, so flat regions get coherence -> 0 instead of 0 / 0.
_TEXTURE_FLOOR = 2e-5
# An off-centre window replaces the centred one when its cost is below this fraction of it.
_SHIFT_GAIN = 0.5
# Costs below this count as a perfect fit (no reason to look for a better window).
_COST_FLOOR = 1e-4


def candidate_disparities(disparity_range: tuple[float, float], step: float) -> np.ndarray:
    """Shear candidates covering ``disparity_range`` with spacing at most ``step``.

    The range is split into ``ceil((hi - lo) / step)`` equal bands (at least one) and each band is
    represented by its midpoint, so every disparity of the range is within half a spacing of a
    candidate.

    Parameters
    ----------
    disparity_range : (lo, hi)
        Disparities to cover, in pixels per view step.
    step : float
        Largest spacing between candidates (> 0).

    Returns
    -------
    candidates : ndarray of float64, increasing
    """
    lo, hi = float(disparity_range[0]), float(disparity_range[1])
    if step <= 0:
        raise LfsamError(f"candidate step must be positive, got {step}")
    count = max(1, math.ceil((hi - lo) / step - 1e-9))
    spacing = (hi - lo) / count
    return lo + spacing * (np.arange(count) + 0.5)


def orientation_from_tensor(
    j_nn: torch.Tensor, j_nx: torch.Tensor, j_xx: torch.Tensor, floor: float = _TEXTURE_FLOOR
) -> tuple[torch.Tensor, torch.Tensor]:
    """Disparity and coherence from EPI structure-tensor components.

    For ``E(n, x) = f(x + d n)`` the gradient is ``f' (d, 1)``, so ``J`` is proportional to
    ``[[d^2, d], [d, 1]]``; its dominant eigenvector makes the angle ``phi = atan(d)`` with the
    pixel axis, where ``tan(2 phi) = 2 J_nx / (J_xx - J_nn)`` (Wanner & Goldluecke 2012, eq. 3).

    Parameters
    ----------
    j_nn, j_nx, j_xx : torch.Tensor
        Smoothed products of the derivatives across views (``n``) and along pixels (``x``).
    floor : float
        Added to the trace in the coherence's denominator (a texture threshold).

    Returns
    -------
    disparity : torch.Tensor
        ``tan(phi)``, pixels per view step.
    coherence : torch.Tensor
        ``sqrt((J_xx - J_nn)^2 + 4 J_nx^2) / (J_nn + J_xx + floor)``, in [0, 1).
    """
    diff = j_xx - j_nn
    two_phi = torch.atan2(2.0 * j_nx, diff)
    disparity = torch.tan(0.5 * two_phi)
    coherence = torch.sqrt(diff * diff + 4.0 * j_nx * j_nx) / (j_nn + j_xx + floor)
    return disparity, coherence


class _ShearedStack:
    """One EPI stack, ready to be sheared to any candidate disparity.

    Precomputes the padded Fourier spectrum of the stack (smoothed by the inner scale) and the
    per-view weights of the two half-EPIs; :meth:`evaluate` then scores one candidate.
    """

    def __init__(
        self,
        stack: EpiStack,
        max_shift: float,
        inner_scale: float,
        outer_scale: float,
        angular_scale: float | None,
        band: float,
        shift_radius: int,
        occlusion_aware: bool,
    ) -> None:
        images = stack.images  # (N, C, rows, cols)
        count, channels, rows, cols = images.shape
        device = images.device
        self.cols = cols
        self.center = stack.center
        self.outer_scale = outer_scale
        self.band = band
        self.shift_radius = shift_radius
        self.occlusion_aware = occlusion_aware
        offsets = stack.offsets
        self.offsets = offsets.view(count, 1, 1, 1)
        # inner scale: along pixel rows here, along the shift axis in the Fourier domain below
        if inner_scale > 0:
            images = smooth_axis(images, gaussian_kernel1d(inner_scale, device), -2)
        self.pad = math.ceil(max_shift) + 2
        padded = F.pad(
            images.reshape(count * channels, 1, rows, cols), (self.pad, self.pad, 0, 0),
            mode="replicate",
        ).reshape(count, channels, rows, cols + 2 * self.pad)
        self.length = padded.shape[-1]
        omega = 2.0 * math.pi * torch.fft.rfftfreq(self.length, device=device)
        self.omega = omega
        self.spectrum = torch.fft.rfft(padded, dim=-1) * torch.exp(
            -0.5 * (inner_scale * omega) ** 2
        )
        derivative = 1j * omega
        if self.length % 2 == 0:
            derivative[-1] = 0.0  # the Nyquist bin has no odd (derivative) part
        self.derivative = derivative
        # weights over views, split into the half before the reference view and the half after
        # it; absent views (partial grids) weigh nothing
        if angular_scale is None or angular_scale <= 0:
            weights = torch.ones_like(offsets)
        else:
            weights = torch.exp(-0.5 * (offsets / angular_scale) ** 2)
        present = stack.present.float()
        weights = weights * present
        before = (offsets < 0).float() + 0.5 * (offsets == 0).float()
        after = (offsets > 0).float() + 0.5 * (offsets == 0).float()
        # structure tensor rows n = 1 .. N-2 where the central difference exists (views n - 1,
        # n and n + 1 present); the reference row is shared half-and-half so that the two halves
        # add up to the full EPI
        inner = weights[1:-1] * (present[:-2] * present[2:])
        self.tensor_weights = torch.stack([inner * before[1:-1], inner * after[1:-1]]) / (
            inner.sum().clamp(min=1e-12)
        )
        # photo-consistency over the other views of each half; a half without views (the
        # reference at the end of its row or column) is never chosen
        others = weights * (offsets != 0)
        halves = torch.stack([others * (offsets < 0), others * (offsets > 0)])
        if occlusion_aware and bool((halves.sum(1) <= 0).any()):
            # the reference view ends its row or column: all views lie on one side, so an
            # occluder entering the EPI covers the far views first; the two "halves" become the
            # nearer and the farther half of that side (the nearer one with its own tensor rows,
            # the farther one with the whole side's tensor, too few rows of its own on small
            # grids). Measured on synthetic 7 x 7 scenes, this lowers the corner views' MSE by
            # a fifth against using the whole side at once.
            side = halves.sum(0)
            reach = math.ceil(float(offsets.abs()[side > 0].max()) / 2)
            near = (offsets.abs() <= reach).float()
            halves = torch.stack([side * near, side * (1.0 - near)])
            whole = self.tensor_weights.sum(0)
            self.tensor_weights = torch.stack([whole * near[1:-1], whole])
        # a half with no three consecutive views (gaps of a partial grid) has no tensor rows
        self.no_tensor = (self.tensor_weights.sum(1) <= 0).view(2, 1, 1)
        half_sums = halves.sum(1, keepdim=True)
        self.cost_weights = halves / half_sums.clamp(min=1e-12)
        self.empty_halves = (half_sums[:, 0] <= 0).view(2, 1, 1)

    def _terms(self, sheared: torch.Tensor) -> torch.Tensor:
        """The structure tensor's and the linearised cost's terms per half of the views, shape
        ``(2, 6, rows, cols)``, from the sheared spectrum of some rows ``(N, C, rows, freq)``."""
        both = torch.fft.irfft(torch.stack([sheared, sheared * self.derivative]), n=self.length)
        values, dx = both[..., self.pad : self.pad + self.cols].unbind(0)  # (N, C, rows, cols)
        # structure tensor products on rows 1 .. N-2, summed over colour channels
        e_n = 0.5 * (values[2:] - values[:-2])
        e_x = (3.0 * dx[:-2] + 10.0 * dx[1:-1] + 3.0 * dx[2:]) * (1.0 / 16.0)
        tensor_terms = torch.stack([(e_n * e_n).sum(1), (e_n * e_x).sum(1), (e_x * e_x).sum(1)])
        # linearised photo-consistency terms against the reference view, per view
        diff = values - values[self.center : self.center + 1]
        grad = self.offsets * dx
        cost_terms = torch.stack([(diff * diff).sum(1), (diff * grad).sum(1), (grad * grad).sum(1)])
        return torch.cat(
            [
                torch.einsum("kn,jnrc->kjrc", self.tensor_weights, tensor_terms),
                torch.einsum("kn,jnrc->kjrc", self.cost_weights, cost_terms),
            ],
            dim=1,
        )  # (2 halves, 6 terms, rows, cols)

    def evaluate(self, candidate: float) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Score the candidate disparity ``candidate`` at every pixel.

        Returns
        -------
        residual, coherence, cost : torch.Tensor, shape (rows, cols)
            The clamped residual disparity, the coherence and the residual-corrected
            photo-consistency cost of the better half (or of all views when not occlusion-aware).
        """
        # view n shifted by candidate * offset_n: g(x) = f(x - a)  <->  G = F exp(-i omega a)
        phase = torch.exp(-1j * self.omega * (candidate * self.offsets))
        count, channels, rows = self.spectrum.shape[:3]
        halves = torch.empty((2, 6, rows, self.cols), device=self.spectrum.device)
        # a few rows at a time (every row of an EPI stack is independent up to here): the
        # intermediates stay in a CPU's cache
        step = max(1, CHUNK_ELEMENTS // (count * channels * self.length))
        for first in range(0, rows, step):
            part = slice(first, min(first + step, rows))
            halves[:, :, part] = self._terms(self.spectrum[:, :, part] * phase)
        empty = self.empty_halves
        if not self.occlusion_aware:
            full = halves.sum(0, keepdim=True)
            # the cost terms are means over each non-empty half
            full[:, 3:] *= 1.0 / int((~empty).sum())
            halves = full
            empty = empty[:1] & False
            no_tensor = self.no_tensor.all(0, keepdim=True)
        else:
            no_tensor = self.no_tensor
        smooth = gaussian_blur(halves, self.outer_scale)
        residual, coherence = orientation_from_tensor(smooth[:, 0], smooth[:, 1], smooth[:, 2])
        r = residual.clamp(-self.band, self.band)
        if bool(no_tensor.any()):
            # no tensor: the residual minimising the linearised cost (Lucas-Kanade)
            lk = (smooth[:, 4] / smooth[:, 5].clamp(min=1e-12)).clamp(-self.band, self.band)
            r = torch.where(no_tensor, lk, r)
        cost = smooth[:, 3] - 2.0 * r * smooth[:, 4] + r * r * smooth[:, 5]
        if bool(empty.any()):
            cost = cost.masked_fill(empty, math.inf)
        if self.shift_radius > 0:
            cost, r, coherence = _shiftable_window(cost, r, coherence, self.shift_radius)
        cost, side = cost.min(0)
        r = r.gather(0, side[None])[0]
        coherence = coherence.gather(0, side[None])[0]
        return r, coherence, cost


def _shiftable_window(
    cost: torch.Tensor, residual: torch.Tensor, coherence: torch.Tensor, radius: int
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Per pixel, the lowest cost among windows centred up to ``radius`` pixels away, with the
    residual and coherence of that window (``cost`` etc. have shape ``(K, rows, cols)``).

    A displaced window replaces the centred one only where it is clearly better (cost below
    :data:`_SHIFT_GAIN` times the centred cost): on smooth slanted surfaces the centred window is
    as good and a displaced one would bring the disparity of its own position.
    """
    shifted, residual_at, coherence_at = _window_minimum(cost, (residual, coherence), radius)
    use = (shifted < _SHIFT_GAIN * cost) & (cost > _COST_FLOOR)
    residual = torch.where(use, residual_at, residual)
    coherence = torch.where(use, coherence_at, coherence)
    return torch.where(use, shifted, cost), residual, coherence


def _window_minimum(
    values: torch.Tensor, carried: tuple[torch.Tensor, ...], radius: int
) -> tuple[torch.Tensor, ...]:
    """The minimum of ``values`` (shape ``(K, rows, cols)``) over the ``(2 radius + 1)^2`` window
    around each pixel (positions outside the frame count as infinite), with the ``carried``
    tensors' values at the position of that minimum.

    Separable, each axis by doubling: the minimum over ``w`` positions is that of two
    overlapping windows of ``2^floor(log2 w)`` positions, so a 7-wide window takes three steps
    per axis. The position of the minimum travels along as a flat index held in float32 (exact
    below 2^24 elements), updated arithmetically (``i + lower (j - i)``, faster on a CPU than
    ``torch.where``); the carried tensors are gathered there at the end.

    Raises
    ------
    ValueError
        If ``values`` has 2^24 elements or more (the caller's code is at fault: split the call).
    """
    count, rows, cols = values.shape
    if count * rows * cols >= 1 << 24:
        raise ValueError("too many elements for float32 indices; split the call")
    size = 2 * radius + 1
    index = torch.arange(count * rows * cols, device=values.device, dtype=torch.float32)
    best, index = values, index.view(values.shape)
    for dim in (-1, -2):
        length = values.shape[dim]
        pad = (radius, radius) if dim == -1 else (0, 0, radius, radius)
        best, index = F.pad(best, pad, value=math.inf), F.pad(index, pad)
        width = 1
        while 2 * width <= size:
            best, index = _lower_of(best, index, dim, width, best.shape[dim] - width)
            width *= 2
        # two windows of `width` positions cover the `size` ones (they overlap when size < 2w)
        best, index = _lower_of(best, index, dim, size - width, length)
    flat = index.long().flatten()
    return (best, *(extra.flatten()[flat].view(values.shape) for extra in carried))


def _lower_of(
    values: torch.Tensor, index: torch.Tensor, dim: int, shift: int, length: int
) -> tuple[torch.Tensor, torch.Tensor]:
    """Per position along ``dim`` (``length`` of them), the lower of ``values`` there and
    ``shift`` positions further, with its ``index`` (the nearer one on a tie)."""
    near, far = values.narrow(dim, 0, length), values.narrow(dim, shift, length)
    near_index, far_index = index.narrow(dim, 0, length), index.narrow(dim, shift, length)
    lower = (far < near).float()
    return torch.minimum(near, far), near_index + lower * (far_index - near_index)


def _estimate_direction(
    stack: EpiStack, candidates: np.ndarray, band: float, **options
) -> tuple[torch.Tensor, torch.Tensor]:
    """Multi-candidate estimate of one stack: disparity and coherence in center-view layout."""
    max_shift = float(np.abs(candidates).max()) * float(stack.offsets.abs().max())
    sheared = _ShearedStack(stack, max_shift, band=band, **options)
    rows, cols = stack.images.shape[-2:]
    device = stack.images.device
    best_cost = torch.full((rows, cols), math.inf, device=device)
    best_disp = torch.zeros((rows, cols), device=device)
    best_coh = torch.zeros((rows, cols), device=device)
    for candidate in candidates:
        residual, coherence, cost = sheared.evaluate(float(candidate))
        better = cost < best_cost
        best_cost = torch.where(better, cost, best_cost)
        best_disp = torch.where(better, float(candidate) + residual, best_disp)
        best_coh = torch.where(better, coherence, best_coh)
    layout = stack.to_center_layout
    return layout(best_disp), layout(best_coh), layout(best_cost)


def estimate_disparity(
    views: LightField | np.ndarray,
    disparity_range: tuple[float, float] | None = None,
    *,
    device: str | torch.device | None = None,
    inner_scale: float = 0.65,
    outer_scale: float = 1.5,
    angular_scale: float | None = None,
    candidate_step: float = 0.5,
    band_margin: float = 0.1,
    shift_radius: int = 3,
    occlusion_aware: bool = True,
    color: bool = False,
    edge_refinement: bool = True,
    view: tuple[int, int] | None = None,
) -> DisparityEstimate:
    """Estimate a view's disparity with the structure tensor on sheared EPIs.

    Parameters
    ----------
    views : LightField or ndarray, shape (S, T, U, V, 3), uint8
        The light field; the center view is ``(S // 2, T // 2)``. A direction needs at least
        three present views (a 1 x T or S x 1 light field uses its one direction); absent views
        of a partial grid (``LightField.present``) are left out of the EPIs.
    disparity_range : (lo, hi), optional
        Disparities to search, in pixels per view step; estimated from the data when omitted
        (:func:`lfsam.disparity.range.estimate_disparity_range`). The result is clipped to it.
    device : str or torch.device, optional
        Where to compute; default ``auto`` (:func:`lfsam.devices.resolve_device`).
    inner_scale : float
        Standard deviation (pixels) of the Gaussian pre-smoothing of the EPIs.
    outer_scale : float
        Standard deviation (pixels) of the Gaussian that aggregates the tensor over pixels.
    angular_scale : float, optional
        Standard deviation (views) of a Gaussian weighting of the views around the center;
        ``None`` weighs all views equally.
    candidate_step : float
        Largest spacing between shear candidates, pixels per view step (the time grows with
        the number of candidates).
    band_margin : float
        Extra half-width (pixels per view step) of each candidate's residual band.
    shift_radius : int
        Largest offset (pixels) of the shiftable aggregation windows; 0 disables them.
    occlusion_aware : bool
        Score each candidate on the better half of the views (before / after the reference view;
        nearer / farther half of the one side for a view at the end of its row or column).
    color : bool
        Sum the terms of the three colour channels instead of using gray levels.
    edge_refinement : bool
        Finish with the confidence-weighted joint bilateral refinement guided by the reference
        view (:func:`lfsam.disparity.refine.refine_disparity`); on by default because it
        measurably helps (``benchmarks/bench_disparity.py`` prints both).
    view : (s, t), optional
        The view whose disparity is estimated (0-based view row and column, docs/design.md
        section 8); default the center view. Its row of views gives the horizontal EPIs and its
        column the vertical ones; for a view at the end of a row or column the occlusion-aware
        scheme uses the one half of the views that exists.

    Returns
    -------
    DisparityEstimate
        ``disparity`` and ``confidence`` of the view, the range searched and ``meta``.

    Raises
    ------
    LfsamError
        If the view is outside the grid or absent, its row and column both have fewer than three
        present views, or the range is invalid.
    """
    start = time.perf_counter()
    stacks = epi_stacks(views, device=device, color=color, view=view)
    reference = resolve_view(as_views(views).shape[:2], view)
    source = "given"
    if disparity_range is None:
        disparity_range = estimate_disparity_range(views, device=device, view=reference)
        source = "estimated"
    lo, hi = (float(x) for x in disparity_range)
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
        raise LfsamError(
            f"invalid disparity range {lo:g},{hi:g}: give LO,HI with LO <= HI in pixels per view"
        )
    candidates = candidate_disparities((lo, hi), candidate_step)
    band = 0.5 * (hi - lo) / len(candidates) + band_margin
    options = {
        "inner_scale": inner_scale,
        "outer_scale": outer_scale,
        "angular_scale": angular_scale,
        "shift_radius": shift_radius,
        "occlusion_aware": occlusion_aware,
    }
    with torch.no_grad():
        estimates = [_estimate_direction(stack, candidates, band, **options) for stack in stacks]
        disparities = torch.stack([d for d, _, _ in estimates])
        coherences = torch.stack([c for _, c, _ in estimates])
        # per pixel, the direction whose best candidate explains the views better
        winner = torch.stack([cost for _, _, cost in estimates]).argmin(0, keepdim=True)
        disparity = disparities.gather(0, winner)[0].clamp(lo, hi)
        # the larger coherence: a pixel is trustworthy when either direction sees clear structure
        # (it weights the refinement below; on the benchmark it beats the winner's coherence)
        confidence = coherences.amax(0).clamp(0.0, 1.0)
        if edge_refinement:
            guide = as_views(views)[reference]
            image = torch.from_numpy(np.ascontiguousarray(guide)).to(disparity.device)
            image = image.permute(2, 0, 1).float() / 255.0
            disparity = refine_disparity(disparity.float(), confidence.float(), image).clamp(lo, hi)
    meta = {
        "method": "sheared structure tensor",
        "view": list(reference),
        "range_source": source,
        "candidates": [round(float(c), 4) for c in candidates],
        "directions": [s.direction for s in stacks],
        **options,
        "candidate_step": candidate_step,
        "color": color,
        "edge_refinement": edge_refinement,
        "device": str(stacks[0].images.device),
        "seconds": time.perf_counter() - start,
    }
    return DisparityEstimate(
        disparity=disparity.float().cpu().numpy(),
        confidence=confidence.float().cpu().numpy(),
        disparity_range=(lo, hi),
        meta=meta,
    )
