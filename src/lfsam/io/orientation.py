"""Establishing how a data set's view grid and disparity map onto the package's convention.

The convention (docs/design.md section 1, :mod:`lfsam.geometry`): a point at pixel ``(u, v)`` of
view
``(s, t)`` with disparity ``d`` is at ``(u - d (s' - s), v - d (t' - t))`` in view ``(s', t')``;
``s`` grows downwards, ``t`` rightwards, and larger disparity is closer.

A data set may store its views with the grid axes flipped or swapped, or its disparity with the
opposite sign. With ground-truth disparity, two checks settle it:

1. **Photo-consistency.** Warp a few extreme views into the reference view with the reference's
   disparity (:func:`lfsam.geometry.warp_to_reference`) under each candidate arrangement of the
   view axes (the 8 flips/transposes of the grid); the right one leaves the smallest residual.
   Flipping both view axes negates every view offset, which is the same warp as negating the
   disparity, so photo-consistency alone cannot tell those two apart.
2. **Occlusion order** (needs disparity in other views too). A reference pixel hidden in another
   view is hidden by something closer, so the disparity that view shows at the projected position
   is *larger* under the right sign. Counting which way the disparities jump where reference
   pixels disappear decides between "flip both view axes" and "negate the disparity".
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace

import numpy as np
import torch

from lfsam.geometry import project_pixels, warp_to_reference

__all__ = ["AS_STORED", "Orientation", "OrientationReport", "detect_orientation"]


@dataclass(frozen=True)
class Orientation:
    """A rearrangement of the stored view grid and disparity sign.

    Applied in this order: swap the view-row and view-column axes (``transpose``), reverse the
    view rows (``flip_s``), reverse the view columns (``flip_t``), negate the disparity
    (``negate``). Pixel axes are never touched: each image is what its camera saw.
    """

    transpose: bool = False
    flip_s: bool = False
    flip_t: bool = False
    negate: bool = False

    def views(self, array: np.ndarray) -> np.ndarray:
        """Rearrange an array whose first two axes are the stored ``(S, T)`` view grid."""
        out = np.swapaxes(array, 0, 1) if self.transpose else array
        if self.flip_s:
            out = out[::-1]
        if self.flip_t:
            out = out[:, ::-1]
        return out

    def disparity(self, array: np.ndarray) -> np.ndarray:
        """Rearrange a ``(S, T, U, V)`` disparity (or sign-fix a center ``(U, V)`` one)."""
        out = self.views(array) if array.ndim == 4 else array
        return -out if self.negate else out

    def position(self, s: int, t: int, grid_shape: tuple[int, int]) -> tuple[int, int]:
        """Where stored view ``(s, t)`` of a ``grid_shape`` grid ends up."""
        s_count, t_count = grid_shape
        if self.transpose:
            s, t, s_count, t_count = t, s, t_count, s_count
        if self.flip_s:
            s = s_count - 1 - s
        if self.flip_t:
            t = t_count - 1 - t
        return s, t

    def grid_shape(self, grid_shape: tuple[int, int]) -> tuple[int, int]:
        """The grid shape after rearranging."""
        return grid_shape[::-1] if self.transpose else tuple(grid_shape)

    def photometric_twin(self) -> Orientation:
        """The arrangement that warps identically: both view axes flipped, disparity negated."""
        return replace(self, flip_s=not self.flip_s, flip_t=not self.flip_t, negate=not self.negate)

    def describe(self) -> str:
        """Human-readable, e.g. ``"view rows and columns flipped; disparity as stored"``."""
        parts = []
        if self.transpose:
            parts.append("view rows and columns swapped")
        flips = [name for name, on in (("rows", self.flip_s), ("columns", self.flip_t)) if on]
        if flips:
            parts.append(f"view {' and '.join(flips)} flipped")
        if not parts:
            parts.append("views as stored")
        parts.append("disparity negated" if self.negate else "disparity as stored")
        return "; ".join(parts)


#: The identity arrangement.
AS_STORED = Orientation()

#: The 8 arrangements of a view grid (transposes and flips), disparity as stored.
GRID_ARRANGEMENTS = tuple(
    Orientation(transpose=a, flip_s=b, flip_t=c)
    for a, b, c in itertools.product((False, True), repeat=3)
)


@dataclass
class OrientationReport:
    """The outcome of :func:`detect_orientation`.

    Attributes
    ----------
    orientation : Orientation
        The arrangement to apply.
    residuals : dict of str to float
        Photo-consistency residual (:func:`photo_residual`, gray levels 0..255) of each tried
        arrangement.
    sign : str
        How the disparity sign was decided.
    """

    orientation: Orientation
    residuals: dict[str, float]
    sign: str

    def summary(self) -> str:
        """One line for ``meta["orientation_check"]``."""
        ranked = sorted(self.residuals.values())
        text = f"photo-consistency residual {ranked[0]:.2f}"
        if len(ranked) > 1:
            text += f" (next best arrangement {ranked[1]:.2f})"
        return f"{text}; {self.sign}"


def _gray(image: np.ndarray) -> torch.Tensor:
    return torch.as_tensor(np.ascontiguousarray(image), dtype=torch.float32).mean(dim=-1)


def _sample_views(grid_shape: tuple[int, int], ref: tuple[int, int]) -> list[tuple[int, int]]:
    """Extreme views around ``ref``: the ends of its row and column, and the four corners."""
    s_count, t_count = grid_shape
    candidates = [
        (0, ref[1]),
        (s_count - 1, ref[1]),
        (ref[0], 0),
        (ref[0], t_count - 1),
        (0, 0),
        (0, t_count - 1),
        (s_count - 1, 0),
        (s_count - 1, t_count - 1),
    ]
    seen, out = set(), []
    for view in candidates:
        if view != tuple(ref) and view not in seen:
            seen.add(view)
            out.append(view)
    return out


def photo_residual(
    views: np.ndarray,
    reference_disparity: np.ndarray,
    reference: tuple[int, int],
    samples: list[tuple[int, int]] | None = None,
) -> float:
    """Median absolute residual of views warped into the reference view with its disparity.

    The median ignores occlusion boundaries and specular spots, where even the right
    arrangement leaves large differences.

    Parameters
    ----------
    views : (S, T, U, V, 3) array
        Views in the package's grid order.
    reference_disparity : (U, V) array
        Disparity of the reference view, in the package's convention.
    reference : (s, t)
        The reference view.
    samples : list of (s, t), optional
        Views to warp (default: the extreme views around the reference).

    Returns
    -------
    float
        Mean over the sampled views of the median absolute gray-level difference (0..255)
        between the reference and the warped view, over pixels that land inside the view.
    """
    samples = samples or _sample_views(views.shape[:2], reference)
    ref_image = _gray(views[reference])
    disparity = torch.as_tensor(np.ascontiguousarray(reference_disparity), dtype=torch.float32)
    values = []
    for s, t in samples:
        warped = warp_to_reference(
            _gray(views[s, t]), disparity, s - reference[0], t - reference[1]
        )
        diff = (warped - ref_image).abs()
        valid = ~torch.isnan(diff)
        if valid.any():
            values.append(float(diff[valid].median()))
    return float(np.mean(values)) if values else float("inf")


def occlusion_votes(
    disparity: np.ndarray, reference: tuple[int, int], samples: list[tuple[int, int]]
) -> tuple[int, int]:
    """Count where reference pixels are hidden by larger vs smaller disparity in other views.

    Each reference pixel is projected into a sample view (package convention) and that view's
    disparity is read at the nearest pixel. Where it differs clearly from the pixel's own
    disparity, the pixel is hidden there, by a closer surface if the sign is right.

    Parameters
    ----------
    disparity : (S, T, U, V) array
        Per-view disparity in the candidate arrangement and sign.
    reference : (s, t)
        The reference view.
    samples : list of (s, t)
        Views to test.

    Returns
    -------
    larger, smaller : int
        Number of hidden reference pixels whose occluder has larger (resp. smaller) disparity.
    """
    ref = torch.as_tensor(np.ascontiguousarray(disparity[reference]), dtype=torch.float32)
    height, width = ref.shape
    finite = ref[torch.isfinite(ref)]
    if finite.numel() == 0:
        return 0, 0
    threshold = max(0.05, 0.1 * float(finite.max() - finite.min()))
    rows = torch.arange(height, dtype=torch.float32)[:, None]
    cols = torch.arange(width, dtype=torch.float32)[None, :]
    larger = smaller = 0
    for s, t in samples:
        pu, pv = project_pixels(rows, cols, ref, s - reference[0], t - reference[1])
        iu, iv = torch.round(pu).long(), torch.round(pv).long()
        inside = (iu >= 0) & (iu < height) & (iv >= 0) & (iv < width) & torch.isfinite(ref)
        other = torch.as_tensor(np.ascontiguousarray(disparity[s, t]), dtype=torch.float32)
        seen = other[iu[inside], iv[inside]]
        jump = seen - ref[inside]
        larger += int((jump > threshold).sum())
        smaller += int((jump < -threshold).sum())
    return larger, smaller


def detect_orientation(
    views: np.ndarray,
    disparity: np.ndarray,
    candidates: tuple[Orientation, ...] = GRID_ARRANGEMENTS,
    decide_sign: bool = True,
) -> OrientationReport:
    """Find the arrangement of a stored light field that fits the package's convention.

    Parameters
    ----------
    views : (S, T, U, V, 3) array
        The views as stored.
    disparity : (S, T, U, V) or (U, V) array
        Ground-truth disparity as stored (per view, or of the stored center view only).
    candidates : tuple of Orientation
        Arrangements to try by photo-consistency (default: all 8 grid flips/transposes, with the
        disparity as stored).
    decide_sign : bool
        With per-view disparity, also choose between the best arrangement and its photometric
        twin (both view axes flipped, disparity negated) by occlusion order. Otherwise the
        candidates' own signs are kept.

    Returns
    -------
    OrientationReport
    """
    grid = views.shape[:2]
    stored_center = (grid[0] // 2, grid[1] // 2)
    residuals: dict[str, float] = {}
    best: Orientation | None = None
    for candidate in candidates:
        shape = candidate.grid_shape(grid)
        ref = candidate.position(*stored_center, grid)
        if disparity.ndim == 2 and ref != (shape[0] // 2, shape[1] // 2):
            continue  # the center-only disparity would no longer belong to the center view
        oriented_disp = candidate.disparity(disparity)
        ref_disp = oriented_disp[ref] if oriented_disp.ndim == 4 else oriented_disp
        value = photo_residual(candidate.views(views), ref_disp, ref)
        residuals[candidate.describe()] = value
        if best is None or value < residuals[best.describe()]:
            best = candidate
    assert best is not None
    if not (decide_sign and disparity.ndim == 4):
        sign = (
            "disparity sign as given (larger = closer), not checked: no per-view disparity"
            if decide_sign
            else "disparity sign from the data set's definition (larger = closer)"
        )
        return OrientationReport(best, residuals, sign)
    twin = best.photometric_twin()
    ref = best.position(*stored_center, grid)
    twin_ref = twin.position(*stored_center, grid)
    shape = best.grid_shape(grid)
    if twin_ref != (shape[0] // 2, shape[1] // 2):
        return OrientationReport(best, residuals, "disparity sign as given (even grid)")
    samples = _sample_views(shape, ref)
    larger, smaller = occlusion_votes(best.disparity(disparity), ref, samples)
    evidence = f"occlusion order: {larger} hidden pixels behind larger, {smaller} behind smaller"
    if smaller > 1.5 * larger and smaller > 0:
        return OrientationReport(twin, residuals, f"{evidence} disparity -> flipped sign")
    if larger > 1.5 * smaller and larger > 0:
        return OrientationReport(best, residuals, f"{evidence} disparity -> sign confirmed")
    return OrientationReport(best, residuals, f"{evidence} disparity -> sign undecided, as given")
