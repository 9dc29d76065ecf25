"""Center-view prompts carried to another view by disparity (video baseline, start="first")."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from lfsam.baseline import transfer_prompts
from lfsam.segmenters.base import Prompts
from lfsam.synth import generate_scene


def test_constant_disparity_moves_points_and_boxes_exactly():
    disparity = np.full((40, 60), 1.5, np.float32)
    prompts = Prompts(
        points=[[[20.0, 10.0], [30.0, 25.0]]],
        point_labels=[[1, 0]],
        boxes=[[10.0, 5.0, 30.0, 20.0]],
    )
    # First view of a 3x3 grid: offset (-1, -1) from the center; u' = u + 1.5, v' = v + 1.5.
    moved = transfer_prompts(prompts, disparity, (-1, -1))
    np.testing.assert_allclose(moved.points, [[[21.5, 11.5], [31.5, 26.5]]])
    np.testing.assert_array_equal(moved.point_labels, [[1, 0]])
    np.testing.assert_allclose(moved.boxes, [[11.5, 6.5, 31.5, 21.5]])
    # Two views right and one up: u' = u + 1.5, v' = v - 3.
    moved = transfer_prompts(prompts, disparity, (-1, 2))
    np.testing.assert_allclose(moved.points, [[[17.0, 11.5], [27.0, 26.5]]])


def test_points_follow_each_pixels_own_disparity():
    disparity = np.zeros((30, 30), np.float32)
    disparity[:, 15:] = -2.0
    prompts = Prompts(points=[[[5.0, 5.0]], [[20.0, 5.0]]], point_labels=[[1], [1]])
    moved = transfer_prompts(prompts, disparity, (0, 1))
    np.testing.assert_allclose(moved.points[:, 0], [[5.0, 5.0], [22.0, 5.0]])


def _photo_residual(lf, prompts, disparity):
    """Median colour difference between center pixels and their transfers in the corner views."""
    from scipy.ndimage import map_coordinates

    (s_c, t_c), (s_n, t_n) = lf.center, lf.grid_shape
    xy = prompts.points[:, 0]
    reference = lf.center_view[xy[:, 1].astype(int), xy[:, 0].astype(int)].astype(float)
    residuals = []
    for s, t in [(0, 0), (0, t_n - 1), (s_n - 1, 0), (s_n - 1, t_n - 1)]:
        moved = transfer_prompts(prompts, disparity, (s - s_c, t - t_c)).points[:, 0]
        sampled = np.stack(
            [
                map_coordinates(lf.views[s, t, ..., c].astype(float), moved[:, ::-1].T, order=1)
                for c in range(3)
            ],
            axis=1,
        )
        residuals.append(np.abs(sampled - reference).mean(axis=1))
    return float(np.median(np.concatenate(residuals)))


def test_transferred_points_see_the_same_scene_point():
    """Photo-consistency on a synthetic scene: a transferred point sees the colour it had."""
    lf = generate_scene(grid=(3, 3), size=(48, 64), seed=3, num_objects=4)
    rng = np.random.default_rng(0)
    rows, cols = np.nonzero(lf.center_labels > 0)
    pick = rng.choice(len(rows), 60, replace=False)
    points = np.stack([cols[pick], rows[pick]], axis=1).astype(np.float32)
    prompts = Prompts(points=points[:, None, :], point_labels=np.ones((60, 1)))
    right = _photo_residual(lf, prompts, lf.center_disparity)
    wrong_sign = _photo_residual(lf, prompts, -lf.center_disparity)
    not_moved = _photo_residual(lf, prompts, np.zeros_like(lf.center_disparity))
    assert right < 3.0, right
    assert right < 0.4 * min(wrong_sign, not_moved), (right, wrong_sign, not_moved)


@settings(max_examples=60, deadline=None)
@given(
    x=st.floats(0, 47),
    y=st.floats(0, 31),
    w=st.floats(1, 40),
    h=st.floats(1, 30),
    d=st.floats(-8, 8),
    ds=st.integers(-4, 4),
    dt=st.integers(-4, 4),
)
def test_transferred_prompts_stay_inside_and_boxes_never_empty(x, y, w, h, d, ds, dt):
    disparity = np.full((32, 48), d, np.float32)
    box = [x, y, min(x + w, 47.0), min(y + h, 31.0)]
    if box[2] <= box[0] or box[3] <= box[1]:
        box = [x - 1, y - 1, x, y] if x >= 1 and y >= 1 else [x, y, x + 1, y + 1]
    prompts = Prompts(points=[[[x, y]]], point_labels=[[1]], boxes=[box])
    moved = transfer_prompts(prompts, disparity, (ds, dt))
    px, py = moved.points[0, 0]
    assert 0 <= px <= 47 and 0 <= py <= 31
    x0, y0, x1, y1 = moved.boxes[0]
    assert 0 <= x0 < x1 <= 47 and 0 <= y0 < y1 <= 31
    # Away from the border, the move is exactly the convention's shift.
    tx, ty = x - d * dt, y - d * ds
    if 0 <= tx <= 47 and 0 <= ty <= 31:
        np.testing.assert_allclose([px, py], [tx, ty], atol=1e-4)
