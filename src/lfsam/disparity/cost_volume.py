"""An occlusion-aware matching cost volume over disparity hypotheses (plane sweep over all views).

This is the data term of the default disparity estimator (docs/design.md section 3.2;
:mod:`lfsam.disparity.occlusion_aware`). For a reference view ``r`` and a disparity hypothesis
``d``, every other present view ``k`` at view offset ``(ds, dt)`` from ``r`` is resampled at
``(u - d ds, v - d dt)``, where it sees the scene point that ``r`` sees at ``(u, v)`` if that point
has disparity ``d`` (docs/design.md section 1; a plane sweep, Collins, "A space-sweep approach to
true multi-image matching", CVPR 1996). Its photo-consistency with the reference is the
truncated absolute difference of *locally normalised* intensities:

    c_k(u, v, d) = min(|f_k(u - d ds, v - d dt) - f_r(u, v)|, tau),
    f = (g - mean_w(g)) / (std_w(g) + eps_n)

with ``g`` the gray view and ``mean_w``, ``std_w`` over a small window: normalising the contrast
makes the cost as discriminative in the shadows and on the dark floor of HCI scenes as on bright
texture and tolerates smooth brightness changes between views (as zero-mean normalised
cross-correlation does). On HCI antinous it lowered BadPix(0.07) from 23 % (colour differences) to
11 % before any other change.

Occlusion-aware view selection. A pixel next to an occluding edge is hidden from some of the views;
their costs are high even at the true disparity. As the occluder covers the views on one side of
the reference first, the views are split into four half-grids, left (``dt < 0``), right
(``dt > 0``), top (``ds < 0``) and bottom (``ds > 0``), whose mean costs are kept separately; for
each hypothesis every pixel uses the half whose mean cost, box-averaged over a small window to
make the choice robust, is lowest (Wang, Efros & Ramamoorthi, "Occlusion-aware depth estimation
using light-field cameras", ICCV 2015, section 4, split the angular patch along the occlusion
edge; Zhang et al., "Robust depth estimation for light field via spinning parallelogram
operator", CVIU 2016, compare the two halves of a parallelogram window). The four fixed halves
need no edge detection and contain every orientation of an occluder within 45 degrees of an axis
(a diagonal occluder leaves at least one half mostly unoccluded). A reference view at a corner or
edge of the grid simply has fewer non-empty halves.

All views unless a half is clearly better. Half of the views is twice the noise: where nothing
occludes, the mean over all views is the better cost. With ``full_set_ratio = rho`` the selection
keeps the mean over every view unless the best half's window-averaged cost is below
``(1 - rho)`` times that of all views (an occluder raises the cost of the views it hides, so the
halves then differ markedly). On HCI antinous / cotton this took BadPix(0.07) from 6.28 / 2.49 %
to 6.06 / 2.25 % with the aggregation of :mod:`lfsam.disparity.aggregation` (docs/performance.md,
"Disparity"); ``full_set_ratio=None`` keeps the best half always (Wang et al.'s choice).

Views that do not see a pixel at a hypothesis (the resampling position falls outside the frame)
are left out of that pixel's half means; a half without any valid view costs ``tau``.

Cost. One hypothesis at a time, one view at a time: each resampling is a bilinear combination of
(up to) four shifted slices of the padded feature image, so the memory is that of the ``(D, U, V)``
result plus one ``(5, U, V)`` accumulator, never ``views x D x U x V``.
"""

from __future__ import annotations

import math

import numpy as np
import torch
import torch.nn.functional as F

from lfsam.devices import resolve_device
from lfsam.disparity.epi import checked_reference
from lfsam.disparity.filters import box_blur, slice_chunks
from lfsam.lightfield import LightField

__all__ = ["HALVES", "ViewSet", "build_cost_volume", "halves_of", "matching_features", "view_set"]

#: The four half-grids, in the order of the accumulator's first axis.
HALVES = ("left", "right", "top", "bottom")

# ITU-R BT.601 luma weights (as lfsam.disparity.epi).
_LUMA = (0.299, 0.587, 0.114)


def matching_features(gray: torch.Tensor, radius: int = 1, eps: float = 0.002) -> torch.Tensor:
    """Locally normalised intensities ``(g - mean) / (std + eps)`` over ``(2 radius + 1)^2``.

    Parameters
    ----------
    gray : torch.Tensor, shape (..., U, V)
        Gray views, intensities in [0, 1].
    radius : int
        Radius of the normalisation window (pixels).
    eps : float
        Added to the local standard deviation: contrast below it is treated as noise, so a flat
        region stays near 0 instead of amplifying quantisation noise.

    Returns
    -------
    torch.Tensor, shape of ``gray``
    """
    flat = gray.reshape(-1, *gray.shape[-2:])
    out = torch.empty_like(flat)
    # a few views at a time, in a CPU's cache (lfsam.disparity.filters.slice_chunks)
    for chunk in slice_chunks(flat.shape[0], flat[0].numel()):
        part = flat[chunk]
        mean = box_blur(part, radius)
        deviation = box_blur(part * part, radius).addcmul_(mean, mean, value=-1.0)
        deviation = deviation.clamp_(min=0.0).sqrt_().add_(eps)
        out[chunk] = (part - mean).div_(deviation)
    return out.reshape(gray.shape)


class ViewSet:
    """The present views of a light field, as seen from a reference view.

    Attributes
    ----------
    reference : (int, int)
        The reference view ``(s, t)`` (0-based).
    gray : torch.Tensor, shape (U, V)
        The reference view in gray levels, [0, 1] (the guide of the aggregation).
    features : torch.Tensor, shape (N, U, V)
        Matching features (:func:`matching_features`) of the present views other than the
        reference.
    reference_features : torch.Tensor, shape (U, V)
        Matching features of the reference view.
    offsets : ndarray, shape (N, 2), int
        View offsets ``(ds, dt)`` of those views from the reference.
    colour : torch.Tensor, shape (3, U, V), or None
        The reference view in RGB, [0, 1] (the colour guide of the aggregation); None when the
        set was built without it.
    grays : torch.Tensor, shape (N, U, V), or None
        The other views in gray levels, [0, 1] (the photo-consistency residual of
        :mod:`lfsam.disparity.non_lambertian`).
    """

    def __init__(
        self,
        reference: tuple[int, int],
        gray: torch.Tensor,
        features: torch.Tensor,
        reference_features: torch.Tensor,
        offsets: np.ndarray,
        colour: torch.Tensor | None = None,
        grays: torch.Tensor | None = None,
    ) -> None:
        self.reference = reference
        self.gray = gray
        self.features = features
        self.reference_features = reference_features
        self.offsets = offsets
        self.colour = colour
        self.grays = grays

    @property
    def device(self) -> torch.device:
        """Where the views are."""
        return self.gray.device

    def with_features(self, features: torch.Tensor, reference_features: torch.Tensor) -> ViewSet:
        """The same views with other matching features (e.g. a wider normalisation window,
        :mod:`lfsam.disparity.feature_scales`)."""
        return ViewSet(
            self.reference, self.gray, features, reference_features, self.offsets, self.colour,
            self.grays,
        )


def view_set(
    views: LightField | np.ndarray,
    view: tuple[int, int] | None = None,
    *,
    device: str | torch.device | None = None,
    feature_radius: int = 1,
    feature_eps: float = 0.002,
) -> ViewSet:
    """Gather the present views around the reference ``view`` (default: the center view).

    Every present view of the grid takes part (not only the reference's row and column); absent
    views of a partial grid (``LightField.present``) are skipped. The same requirement as the
    EPI-based estimators applies, so that every method accepts the same light fields: at least
    three present views in the reference's row or column.

    Raises
    ------
    LfsamError
        If the view is outside the grid or absent, or neither its row nor its column has three
        present views.
    """
    array, present, (s_r, t_r), _ = checked_reference(views, view)
    s_count, t_count = array.shape[:2]
    dev = resolve_device(device)
    luma = torch.tensor(_LUMA, device=dev, dtype=torch.float32)
    others = [
        (s, t)
        for s in range(s_count)
        for t in range(t_count)
        if present[s, t] and (s, t) != (s_r, t_r)
    ]

    def gray_of(index: tuple[int, int]) -> torch.Tensor:
        rgb = torch.from_numpy(np.ascontiguousarray(array[index])).to(dev).float()
        return (rgb @ luma) / 255.0

    reference_gray = gray_of((s_r, t_r))
    colour = torch.from_numpy(np.ascontiguousarray(array[s_r, t_r])).to(dev).float()
    colour = colour.permute(2, 0, 1) / 255.0
    stack = torch.stack([gray_of(index) for index in others])
    features = matching_features(stack, feature_radius, feature_eps)
    reference_features = matching_features(reference_gray, feature_radius, feature_eps)
    offsets = np.array([(s - s_r, t - t_r) for s, t in others], dtype=np.int64).reshape(-1, 2)
    return ViewSet(
        (s_r, t_r), reference_gray, features, reference_features, offsets, colour.contiguous(),
        stack,
    )


def halves_of(ds: float, dt: float) -> list[int]:
    """Indices into :data:`HALVES` of the half-grids a view offset ``(ds, dt)`` belongs to
    (docs/design.md section 3.2, step 3)."""
    halves = []
    if dt < 0:
        halves.append(0)
    if dt > 0:
        halves.append(1)
    if ds < 0:
        halves.append(2)
    if ds > 0:
        halves.append(3)
    return halves


def _visible(shift: float, length: int) -> tuple[int, int]:
    """The pixels ``[first, stop)`` along an axis of ``length`` whose position ``x + shift``
    lies inside the frame ``[0, length - 1]``."""
    first = max(0, math.ceil(-shift))
    stop = min(length, math.floor(length - 1 - shift) + 1)
    return first, stop


def _resample(
    padded: torch.Tensor, pad: int, shift_u: float, shift_v: float, rows: slice, cols: slice
) -> torch.Tensor:
    """``image(u + shift_u, v + shift_v)`` for ``u`` in ``rows``, ``v`` in ``cols``, by bilinear
    interpolation of the image replicate-padded by ``pad`` (``|shift| <= pad - 1``)."""
    iu, iv = math.floor(shift_u), math.floor(shift_v)
    fu, fv = shift_u - iu, shift_v - iv
    r0, c0 = pad + iu + rows.start, pad + iv + cols.start
    block = padded[r0 : r0 + rows.stop - rows.start + 1, c0 : c0 + cols.stop - cols.start + 1]
    block = torch.lerp(block[:, :-1], block[:, 1:], fv) if fv > 1e-6 else block[:, :-1]
    return torch.lerp(block[:-1], block[1:], fu) if fu > 1e-6 else block[:-1]


def build_cost_volume(
    views: ViewSet,
    hypotheses: np.ndarray,
    *,
    truncation: float = 1.0,
    selection_radius: int = 2,
    occlusion_aware: bool = True,
    full_set_ratio: float | None = None,
) -> torch.Tensor:
    """The occlusion-aware matching cost of every pixel of the reference at every hypothesis.

    Parameters
    ----------
    views : ViewSet
        The views around the reference (:func:`view_set`).
    hypotheses : ndarray, shape (D,)
        Disparity hypotheses, pixels per view step.
    truncation : float
        ``tau``: largest cost of one view at one pixel (robustness to occlusion and specular
        highlights; in units of the normalised features).
    selection_radius : int
        Radius of the box window over which the half-grids' costs are compared (0: per pixel).
    occlusion_aware : bool
        Keep the best half-grid per pixel and hypothesis (module docstring); False averages all
        views.
    full_set_ratio : float, optional
        With occlusion-aware selection: keep the mean over all views unless the best half's
        window-averaged cost is below ``(1 - full_set_ratio)`` times theirs (module docstring);
        None (default here) always keeps the best half.

    Returns
    -------
    cost : torch.Tensor, shape (D, U, V), float32
        Mean truncated feature difference of the chosen half-grid (lower = more consistent).
    """
    rows, cols = views.gray.shape
    device = views.device
    offsets = views.offsets
    reach = int(np.abs(offsets).max()) if len(offsets) else 0
    pad = math.ceil(float(np.abs(hypotheses).max()) * reach) + 2
    padded = F.pad(views.features[:, None], (pad, pad, pad, pad), mode="replicate")[:, 0]
    with_all = occlusion_aware and full_set_ratio is not None
    groups = _view_groups(offsets, occlusion_aware, with_all)
    # each view's cost is added to the sum of its side class (the sign of its offset along each
    # axis, 3 x 3 classes), and each half-grid sums its classes: one addition per view, not one
    # per half it belongs to
    side_class = ((np.sign(offsets[:, 0]) + 1) * 3 + np.sign(offsets[:, 1]) + 1).tolist()
    member = torch.as_tensor(_membership(groups, side_class), device=device)
    volume = torch.empty((len(hypotheses), rows, cols), device=device, dtype=torch.float32)
    # the views' planes taken apart once: indexing a tensor per view and hypothesis is a torch
    # call each (a third of a small view's cost volume went to such calls)
    planes = padded.unbind(0)
    reference = views.reference_features
    row_index, col_index = np.arange(rows), np.arange(cols)
    for index, d in enumerate(np.asarray(hypotheses, dtype=np.float64)):
        class_sums = torch.zeros((9, rows, cols), device=device)
        class_planes = class_sums.unbind(0)
        shifts = [(-d * ds, -d * dt) for ds, dt in offsets.tolist()]
        # only the pixels a view sees at this hypothesis (a rectangle) are compared
        spans = [(_visible(su, rows), _visible(sv, cols)) for su, sv in shifts]
        for k, ((u0, u1), (v0, v1)) in enumerate(spans):
            if u0 >= u1 or v0 >= v1:
                continue
            in_u, in_v = slice(u0, u1), slice(v0, v1)
            warped = _resample(planes[k], pad, *shifts[k], in_u, in_v)
            cost = (warped - reference[in_u, in_v]).abs_().clamp_(max=truncation)
            class_planes[side_class[k]][in_u, in_v] += cost
        # each view's visible rows and columns (none where its rectangle is empty)
        spans_np = np.array([(u0, u1, v0, v1) if u0 < u1 and v0 < v1 else (0, 0, 0, 0)
                             for (u0, u1), (v0, v1) in spans]).reshape(-1, 4)
        seen_rows = torch.from_numpy(((row_index >= spans_np[:, :1])
                                      & (row_index < spans_np[:, 1:2])).astype(np.float32))
        seen_cols = torch.from_numpy(((col_index >= spans_np[:, 2:3])
                                      & (col_index < spans_np[:, 3:4])).astype(np.float32))
        seen_rows, seen_cols = seen_rows.to(device), seen_cols.to(device)
        sums = torch.stack([_summed(class_sums, group) for group in groups])
        # how many views of each group see each pixel: a sum of the views' visible rectangles,
        # each the outer product of its visible rows and columns
        seen = torch.einsum("gk,ku,kv->guv", member, seen_rows, seen_cols)
        means = torch.where(seen > 0.5, sums / seen.clamp(min=1.0), truncation)
        if len(groups) == 1:
            volume[index] = means[0]
            continue
        judged = box_blur(means, selection_radius) if selection_radius > 0 else means
        best, choice = judged[:4].min(0, keepdim=True)
        volume[index] = means[:4].gather(0, choice)[0]
        if with_all:
            clear = best[0] < (1.0 - float(full_set_ratio)) * judged[4]
            volume[index] = torch.where(clear, volume[index], means[4])
    return volume


#: The side classes (``3 (sign(ds) + 1) + sign(dt) + 1``) of each half-grid of :data:`HALVES`,
#: and of all views.
_HALF_CLASSES = ((0, 3, 6), (2, 5, 8), (0, 1, 2), (6, 7, 8))
_ALL_CLASSES = (0, 1, 2, 3, 5, 6, 7, 8)


def _view_groups(
    offsets: np.ndarray, occlusion_aware: bool, with_all: bool
) -> list[tuple[int, ...]]:
    """The view groups whose mean costs :func:`build_cost_volume` keeps, as side classes: the
    four half-grids (and all views), or all views only."""
    if not occlusion_aware:
        return [_ALL_CLASSES]
    return list(_HALF_CLASSES) + ([_ALL_CLASSES] if with_all else [])


def _summed(class_sums: torch.Tensor, classes: tuple[int, ...]) -> torch.Tensor:
    """The sum of the given side classes' cost sums, always added in the same order."""
    total = class_sums[classes[0]].clone()
    for side in classes[1:]:
        total += class_sums[side]
    return total


def _membership(groups: list[tuple[int, ...]], side_class: list[int]) -> np.ndarray:
    """``(groups, views)`` float32: 1 where a view belongs to a group."""
    return np.array(
        [[1.0 if side in group else 0.0 for side in side_class] for group in groups],
        dtype=np.float32,
    ).reshape(len(groups), len(side_class))
