"""Tests of epipolar-plane images (lfsam.viz.epi): lines of slope -d, layout and overlays."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lfsam.errors import LfsamError
from lfsam.viz.epi import (
    MARK_COLOR,
    epi_figure,
    epi_overlays,
    horizontal_epi,
    upsample_views,
    vertical_epi,
)
from lfsam.viz.overlay import overlay_labels
from test_viz_scene import make_scene


def _box_lightfield(grid, size, box, d):
    """A bright box of constant integer disparity ``d`` over black, and its labels (id 1).

    Center-view box ``[u0, u1) x [v0, v1)`` is at ``[u0 - d ds, u1 - d ds) x [v0 - d dt, ...)``
    in view ``(s_c + ds, t_c + dt)`` (docs/design.md section 1).
    """
    s_count, t_count = grid
    u_count, v_count = size
    u0, u1, v0, v1 = box
    ds = np.arange(s_count)[:, None, None, None] - s_count // 2
    dt = np.arange(t_count)[None, :, None, None] - t_count // 2
    u = np.arange(u_count)[None, None, :, None]
    v = np.arange(v_count)[None, None, None, :]
    inside = (u + d * ds >= u0) & (u + d * ds < u1) & (v + d * dt >= v0) & (v + d * dt < v1)
    labels = inside.astype(np.int32)
    views = np.repeat((inside * 200).astype(np.uint8)[..., None], 3, axis=-1)
    return views, labels


def _slope(rows_first: np.ndarray) -> float:
    """Least-squares slope of the first column where each row is non-zero, against row index."""
    first = np.argmax(rows_first != 0, axis=1)
    return float(np.polyfit(np.arange(len(first)), first, 1)[0])


@settings(max_examples=40, deadline=None)
@given(
    s_count=st.integers(2, 7),
    t_count=st.integers(2, 7),
    d=st.integers(-3, 3),
    row=st.integers(20, 27),
    col=st.integers(25, 34),
)
def test_constant_disparity_traces_straight_lines_of_slope_minus_d(s_count, t_count, d, row, col):
    views, labels = _box_lightfield((s_count, t_count), (48, 64), (18, 30, 24, 36), d)
    h = horizontal_epi(views, row)
    v = vertical_epi(views, col)
    assert h.shape == (t_count, 64, 3) and v.shape == (s_count, 48, 3)
    # Horizontal EPI: v(t) = 24 - d (t - t_c); vertical EPI: u(s) = 18 - d (s - s_c).
    assert _slope(h[..., 0]) == pytest.approx(-d, abs=1e-9)
    assert _slope(v[..., 0]) == pytest.approx(-d, abs=1e-9)
    t_c, s_c = t_count // 2, s_count // 2
    np.testing.assert_array_equal(
        np.argmax(horizontal_epi(labels, row) != 0, axis=1), 24 - d * (np.arange(t_count) - t_c)
    )
    np.testing.assert_array_equal(
        np.argmax(vertical_epi(labels, col) != 0, axis=1), 18 - d * (np.arange(s_count) - s_c)
    )
    # Every EPI line of the box has width 12 in every view: the label is consistent.
    assert ((horizontal_epi(labels, row) != 0).sum(axis=1) == 12).all()


@settings(max_examples=40, deadline=None)
@given(d=st.floats(-3.0, 3.0), t_count=st.integers(3, 9))
def test_sub_pixel_disparity_centroids_lie_on_a_line_of_slope_minus_d(d, t_count):
    # A Gaussian ridge centred at c_t = 30.25 - d (t - t_c), sampled at pixel centres: by the
    # Poisson summation formula its sampled centroid equals c_t to ~exp(-2 pi^2 sigma^2), so the
    # EPI's centroids follow a line of slope -d.
    t_c = t_count // 2
    center = 30.25 - d * (np.arange(t_count) - t_c)
    v = np.arange(64)
    ridge = np.exp(-0.5 * ((v + 0.5 - center[:, None]) / 2.0) ** 2)
    views = np.zeros((3, t_count, 8, 64, 3))
    views[...] = ridge[None, :, None, :, None]
    epi = horizontal_epi(views, row=4)[..., 1]
    centroid = (epi * (v + 0.5)).sum(axis=1) / epi.sum(axis=1)
    slope, _ = np.polyfit(np.arange(t_count), centroid, 1)
    assert slope == pytest.approx(-d, abs=1e-9)
    assert centroid[t_c] == pytest.approx(30.25, abs=1e-9)


def test_scene_epi_edges_follow_each_objects_disparity():
    lf = make_scene(grid=(5, 7))
    # Object 2 (d = 2, center rows 22..39, columns 22..43) is in front of everything.
    h = horizontal_epi(lf.labels, row=30)
    assert _slope(h == 2) == pytest.approx(-2, abs=1e-9)
    v = vertical_epi(lf.labels, col=40)
    assert _slope(v == 2) == pytest.approx(-2, abs=1e-9)


def test_upsampling_repeats_each_view():
    epi = np.arange(12).reshape(3, 4)
    up = upsample_views(epi, 4)
    assert up.shape == (12, 4)
    for t in range(3):
        np.testing.assert_array_equal(up[4 * t : 4 * t + 4], np.tile(epi[t], (4, 1)))
    np.testing.assert_array_equal(upsample_views(epi, 2, axis=1)[:, ::2], epi)
    with pytest.raises(LfsamError, match="upsample"):
        upsample_views(epi, 0)


def test_epi_overlays_are_the_overlays_of_the_upsampled_epis():
    lf = make_scene(grid=(5, 5))
    k, row, col = 6, 25, 40
    h, v = epi_overlays(lf.views, lf.labels, row=row, col=col, upsample=k, alpha=0.3)
    assert h.shape == (5 * k, 64, 3)
    assert v.shape == (48, 5 * k, 3)
    expected_h = overlay_labels(
        np.repeat(lf.views[2, :, row], k, axis=0), np.repeat(lf.labels[2, :, row], k, 0), alpha=0.3
    )
    expected_v = overlay_labels(
        np.repeat(lf.views[:, 2, :, col], k, axis=0).transpose(1, 0, 2),
        np.repeat(lf.labels[:, 2, :, col], k, axis=0).T,
        alpha=0.3,
    )
    np.testing.assert_array_equal(h, expected_h)
    np.testing.assert_array_equal(v, expected_v)


@pytest.mark.parametrize(("grid", "k", "gap"), [((5, 5), 8, 4), ((3, 5), 3, 0), ((4, 2), 1, 7)])
def test_epi_figure_layout(grid, k, gap):
    lf = make_scene(grid=grid)
    s_count, t_count = grid
    row, col = 21, 33
    fig = epi_figure(lf.views, lf.labels, row=row, col=col, upsample=k, gap=gap, mark=False)
    assert fig.shape == (48 + gap + t_count * k, 64 + gap + s_count * k, 3)
    h, v = epi_overlays(lf.views, lf.labels, row=row, col=col, upsample=k)
    center = overlay_labels(lf.views[s_count // 2, t_count // 2], lf.labels[lf.center])
    np.testing.assert_array_equal(fig[:48, :64], center)
    np.testing.assert_array_equal(fig[:48, 64 + gap :], v)
    np.testing.assert_array_equal(fig[48 + gap :, :64], h)
    assert (fig[48 + gap :, 64:] == 255).all()  # blank corner and gaps


def test_epi_figure_marks_the_row_and_column():
    lf = make_scene()
    fig = epi_figure(lf.views, None, row=10, col=50, upsample=2)
    assert (fig[10, 0:3] == MARK_COLOR).all() and (fig[10, 6:9] == MARK_COLOR).all()
    assert (fig[0:3, 50] == MARK_COLOR).all()
    # Without labels the EPI panels are the raw EPIs.
    np.testing.assert_array_equal(fig[48 + 4 :, :64], np.repeat(lf.views[2, :, 10], 2, axis=0))


def test_bad_rows_columns_and_labels_are_user_errors():
    lf = make_scene()
    with pytest.raises(LfsamError, match="--row"):
        epi_figure(lf.views, lf.labels, row=48)
    with pytest.raises(LfsamError, match="--col"):
        epi_figure(lf.views, lf.labels, col=-65)
    with pytest.raises(LfsamError, match="same light field"):
        epi_overlays(lf.views, lf.labels[:, :, :, :10])
