"""The disparity convention (docs/design.md section 1) and the light-field model."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from lfsam.errors import LfsamError
from lfsam.geometry import project_pixels, view_offsets, warp_to_reference
from lfsam.lightfield import LightField, snake_order


@settings(max_examples=50, deadline=None)
@given(
    u=st.floats(-50, 50), v=st.floats(-50, 50), d=st.floats(-4, 4),
    a=st.tuples(st.integers(-4, 4), st.integers(-4, 4)),
    b=st.tuples(st.integers(-4, 4), st.integers(-4, 4)),
)
def test_projection_composes_and_inverts(u, v, d, a, b):
    # Moving a -> b equals moving a -> center -> b, and b -> a undoes a -> b.
    u1, v1 = project_pixels(u, v, d, b[0] - a[0], b[1] - a[1])
    uc, vc = project_pixels(u, v, d, -a[0], -a[1])
    u2, v2 = project_pixels(uc, vc, d, b[0], b[1])
    assert u1 == pytest.approx(u2, abs=1e-9) and v1 == pytest.approx(v2, abs=1e-9)
    u3, v3 = project_pixels(u1, v1, d, a[0] - b[0], a[1] - b[1])
    assert u3 == pytest.approx(u, abs=1e-9) and v3 == pytest.approx(v, abs=1e-9)


def test_warp_to_reference_undoes_an_integer_shift():
    rng = np.random.default_rng(0)
    center = rng.random((20, 30)).astype(np.float32)
    d, ds, dt = 2.0, 1, -1
    # The view sees center pixel (u, v) at (u - d ds, v - d dt) = (u - 2, v + 2).
    view = np.full_like(center, np.nan)
    view[: 20 - 2, 2:] = center[2:, : 30 - 2]
    warped = warp_to_reference(view, np.full((20, 30), d, np.float32), ds, dt)
    ok = np.isfinite(warped)
    assert ok.sum() > 400
    np.testing.assert_allclose(warped[ok], center[ok], atol=1e-6)
    assert isinstance(warp_to_reference(torch.as_tensor(view), torch.full((20, 30), d), 1, -1),
                      torch.Tensor)


def test_view_offsets_and_snake_order():
    ds, dt = view_offsets((3, 5), (1, 2))
    assert ds[0, 0] == -1 and dt[0, 0] == -2 and ds[2, 4] == 1 and dt[2, 4] == 2
    order = snake_order((3, 3))
    assert order == [(0, 0), (0, 1), (0, 2), (1, 2), (1, 1), (1, 0), (2, 0), (2, 1), (2, 2)]


@settings(max_examples=25, deadline=None)
@given(s=st.integers(1, 6), t=st.integers(1, 6))
def test_snake_order_visits_every_view_once_through_neighbours(s, t):
    order = snake_order((s, t))
    assert sorted(order) == [(i, j) for i in range(s) for j in range(t)]
    for (a, b), (c, d) in itertools.pairwise(order):
        assert abs(a - c) + abs(b - d) == 1


def test_lightfield_validation_and_center():
    views = np.zeros((3, 5, 4, 6, 3), dtype=np.uint8)
    lf = LightField(views, disparity=np.zeros((4, 6)), labels=np.ones((3, 5, 4, 6)))
    assert lf.center == (1, 2) and lf.grid_shape == (3, 5) and lf.view_shape == (4, 6)
    assert lf.center_disparity.shape == (4, 6) and lf.has_full_labels
    assert lf.labels.dtype == np.int32
    with pytest.raises(LfsamError, match=r"\(S, T, U, V, 3\)"):
        LightField(np.zeros((3, 4, 6, 3), dtype=np.uint8))
    with pytest.raises(LfsamError, match="disparity must have shape"):
        LightField(views, disparity=np.zeros((4, 5)))
    with pytest.raises(LfsamError, match=">= 0"):
        LightField(views, labels=-np.ones((4, 6)))
    floats = LightField(np.full((1, 1, 2, 2, 3), 0.5))
    assert floats.views.dtype == np.uint8 and floats.views[0, 0, 0, 0, 0] == 128
