"""Parts of the disparity estimator: candidates, filters, orientation, range sweep, baseline."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from lfsam.disparity import (
    candidate_disparities,
    estimate_disparity,
    estimate_disparity_baseline,
    estimate_disparity_range,
)
from lfsam.disparity.epi import epi_stacks
from lfsam.disparity.filters import box_blur, gaussian_blur
from lfsam.disparity.structure_tensor import orientation_from_tensor
from lfsam.errors import LfsamError
from lfsam.lightfield import LightField


def _cosine_plane(d: float, grid=(5, 5), size=(40, 56)) -> np.ndarray:
    """Views of a plane at disparity d with an analytic texture (exact at any sub-pixel shift).

    View pixel (u', v') of view offset (ds, dt) shows center pixel (u' + d ds, v' + d dt).
    """
    s_count, t_count = grid
    u = np.arange(size[0], dtype=float)[:, None]
    v = np.arange(size[1], dtype=float)[None, :]
    views = np.empty((*grid, *size, 3), dtype=np.uint8)
    for s in range(s_count):
        for t in range(t_count):
            uu, vv = u + d * (s - s_count // 2), v + d * (t - t_count // 2)
            tex = (np.cos(0.9 * vv + 0.3 * uu) + np.cos(0.55 * uu - 0.2 * vv + 1.0)
                   + 0.5 * np.cos(0.31 * vv + 0.77 * uu + 2.0))
            views[s, t] = np.rint(127.5 + 50.0 * tex)[..., None].astype(np.uint8)
    return views


@settings(max_examples=60, deadline=None)
@given(
    lo=st.floats(-10, 10, allow_nan=False),
    width=st.floats(0, 15, allow_nan=False),
    step=st.floats(0.2, 3, allow_nan=False),
)
def test_candidates_cover_the_range_within_half_a_step(lo, width, step):
    hi = lo + width
    cands = candidate_disparities((lo, hi), step)
    assert np.all(np.diff(cands) <= step + 1e-9) and lo <= cands[0] <= cands[-1] <= hi
    probes = np.linspace(lo, hi, 50)
    nearest = np.abs(probes[:, None] - cands[None, :]).min(1)
    assert nearest.max() <= 0.5 * step + 1e-9


@settings(max_examples=50, deadline=None)
@given(d=st.floats(-20, 20, allow_nan=False), energy=st.floats(1e-3, 10, allow_nan=False))
def test_orientation_inverts_an_ideal_tensor(d, energy):
    # E(n, x) = f(x + d n) gives J = |f'|^2 [[d^2, d], [d, 1]] (Wanner & Goldluecke 2012)
    j = [torch.tensor(energy * x, dtype=torch.float64) for x in (d * d, d, 1.0)]
    disparity, coherence = orientation_from_tensor(*j, floor=0.0)
    assert math.isclose(float(disparity), d, rel_tol=1e-6, abs_tol=1e-6)
    assert math.isclose(float(coherence), 1.0, rel_tol=1e-6)


def test_filters_keep_constants_and_match_a_direct_mean():
    const = torch.full((2, 20, 30), 3.0)
    assert torch.allclose(gaussian_blur(const, 1.3), const)
    assert torch.allclose(box_blur(const, 4), const)
    x = torch.rand(1, 15, 17, dtype=torch.float64)
    direct = x[0, 5 - 2 : 5 + 3, 8 - 2 : 8 + 3].mean()
    assert torch.isclose(box_blur(x, 2)[0, 5, 8], direct)


def test_epi_stacks_put_the_shift_axis_last():
    views = np.zeros((3, 5, 8, 10, 3), dtype=np.uint8)
    views[1, 2, 2, 7] = 255  # one bright pixel in the center view at (u=2, v=7)
    horizontal, vertical = epi_stacks(views, device="cpu")
    assert horizontal.images.shape == (5, 1, 8, 10) and horizontal.center == 2
    assert vertical.images.shape == (3, 1, 10, 8) and vertical.center == 1
    assert horizontal.images[2, 0, 2, 7] > 0.9 and vertical.images[1, 0, 7, 2] > 0.9


@pytest.mark.parametrize("d", [-3.2, 0.4, 2.6])
def test_range_sweep_brackets_the_true_disparity(d):
    lo, hi = estimate_disparity_range(_cosine_plane(d), device="cpu")
    assert lo <= d <= hi and hi - lo <= 3.0


def test_given_range_is_respected_and_invalid_range_is_an_error():
    views = _cosine_plane(1.3)
    est = estimate_disparity(views, (0.5, 2.0), device="cpu")
    assert est.disparity_range == (0.5, 2.0) and est.meta["range_source"] == "given"
    assert est.disparity.min() >= 0.5 and est.disparity.max() <= 2.0
    assert np.median(np.abs(est.disparity[8:-8, 8:-8] - 1.3)) < 0.02
    with pytest.raises(LfsamError, match="invalid disparity range"):
        estimate_disparity(views, (2.0, 1.0), device="cpu")


def test_occluding_edge_stays_sharp():
    # a near square (d = 2.5) over a far plane (d = -1.5), both with analytic textures
    near, far = _cosine_plane(2.5, size=(48, 64)), _cosine_plane(-1.5, size=(48, 64))
    far = 255 - far
    views = far.copy()
    gt = np.full((48, 64), -1.5, np.float32)
    gt[14:34, 20:44] = 2.5
    u = np.arange(48)[:, None]
    v = np.arange(64)[None, :]
    for s in range(5):
        for t in range(5):
            cu, cv = u + 2.5 * (s - 2), v + 2.5 * (t - 2)
            inside = (cu >= 14) & (cu < 34) & (cv >= 20) & (cv < 44)
            views[s, t][inside] = near[s, t][inside]
    est = estimate_disparity(LightField(views), device="cpu").disparity
    err = np.abs(est - gt)[8:-8, 8:-8]
    assert np.mean(err > 0.5) < 0.06  # wrong side of the edge: a thin band at most
    assert np.median(err) < 0.05


def test_baseline_follows_the_convention_and_clips_to_the_range():
    # the plain tensor has no shear: near 0 it is close (9 views; the Gaussian over only a few
    # views biases it towards 0 on smaller grids), and it is clipped like plenpy's vmin/vmax
    for d in (-0.5, 0.5):
        est = estimate_disparity_baseline(_cosine_plane(d, grid=(9, 9)), color=False)
        assert np.median(np.abs(est.disparity[8:-8, 8:-8] - d)) < 0.1
    clipped = estimate_disparity_baseline(_cosine_plane(3.0), disparity_range=(-1.0, 1.0))
    assert clipped.disparity.min() >= -1.0 and clipped.disparity.max() <= 1.0
    ours = estimate_disparity(_cosine_plane(3.0), device="cpu").disparity[8:-8, 8:-8]
    assert np.median(np.abs(ours - 3.0)) < 0.05


def test_baseline_needs_three_views():
    with pytest.raises(LfsamError, match="at least 3 views"):
        estimate_disparity_baseline(np.zeros((2, 2, 8, 8, 3), dtype=np.uint8))
