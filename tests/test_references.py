"""Pure helpers of the multi-reference automatic mode (issue 16): views, point grid, mask filter."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from sam2.utils.amg import build_point_grid

from lfsam.errors import LfsamError
from lfsam.pipeline.references import (
    REFERENCE_MODES,
    drop_covered_masks,
    extra_view_points,
    reference_views,
    seen_from,
    unasked_region_points,
    uncovered_points,
)
from lfsam.synth import generate_scene


def test_reference_views_of_a_9x9_grid():
    assert reference_views((9, 9), "center") == [(4, 4)]
    assert reference_views((9, 9), "corners") == [(4, 4), (0, 0), (0, 8), (8, 0), (8, 8)]
    assert reference_views((9, 9), "ring") == [
        (4, 4), (0, 0), (0, 4), (0, 8), (4, 0), (4, 8), (8, 0), (8, 4), (8, 8),
    ]  # fmt: skip
    every = reference_views((9, 9), "all")
    assert every[0] == (4, 4) and len(every) == 81 and len(set(every)) == 81


def test_reference_views_of_small_grids():
    for mode in REFERENCE_MODES:
        assert reference_views((1, 1), mode) == [(0, 0)]
    # 2 x 2: the center is (1, 1), itself a corner.
    assert reference_views((2, 2), "corners") == [(1, 1), (0, 0), (0, 1), (1, 0)]
    # 1 x 5 (a horizontal row): corners (0, 0), (0, 4); midpoints coincide with the center.
    assert reference_views((1, 5), "ring") == [(0, 2), (0, 0), (0, 4)]


@settings(max_examples=50, deadline=None)
@given(grid=st.tuples(st.integers(1, 12), st.integers(1, 12)))
def test_reference_views_nest_and_stay_inside(grid):
    views = {mode: reference_views(grid, mode) for mode in REFERENCE_MODES}
    center = (grid[0] // 2, grid[1] // 2)
    for mode, chosen in views.items():
        assert chosen[0] == center, mode
        assert len(set(chosen)) == len(chosen)
        assert all(0 <= s < grid[0] and 0 <= t < grid[1] for s, t in chosen)
    assert set(views["center"]) <= set(views["corners"]) <= set(views["ring"])
    assert set(views["ring"]) <= set(views["all"])
    assert len(views["all"]) == grid[0] * grid[1]
    assert len(views["ring"]) <= 9 and len(views["corners"]) <= 5


def test_bad_mode_is_a_one_line_error():
    with pytest.raises(LfsamError) as info:
        reference_views((9, 9), "middle")
    assert str(info.value) == "--references middle: use one of center, corners, ring, all"


@pytest.mark.parametrize("n, shape", [(4, (8, 8)), (32, (240, 320)), (5, (7, 13))])
def test_uncovered_points_match_sam2_grid_when_nothing_is_covered(n, shape):
    points = uncovered_points(n, np.zeros(shape, dtype=bool))
    np.testing.assert_allclose(points, build_point_grid(n) * np.array([shape[1], shape[0]]))
    np.testing.assert_allclose(
        uncovered_points(n, np.zeros(shape, dtype=bool), normalized=True), build_point_grid(n)
    )


def test_uncovered_points_skip_covered_pixels():
    # 4 points per side on 8 x 8: x and y at 1, 3, 5, 7. Covering rows 0..3 removes y = 1, 3.
    covered = np.zeros((8, 8), dtype=bool)
    covered[:4] = True
    points = uncovered_points(4, covered)
    assert points.shape == (8, 2)
    np.testing.assert_array_equal(np.unique(points[:, 1]), [5.0, 7.0])
    np.testing.assert_array_equal(np.unique(points[:, 0]), [1.0, 3.0, 5.0, 7.0])
    # One pixel: point (x 3, y 5) lies on pixel (row 5, column 3).
    single = np.zeros((8, 8), dtype=bool)
    single[5, 3] = True
    left = uncovered_points(4, single)
    assert len(left) == 15 and not np.any((left[:, 0] == 3) & (left[:, 1] == 5))
    # Points at pixel boundaries: 2 per side on 4 x 4 puts them at x, y = 1, 3 exactly, on
    # pixels (1, 1), (1, 3), (3, 1), (3, 3).
    edge = np.zeros((4, 4), dtype=bool)
    edge[1, 3] = True
    np.testing.assert_array_equal(uncovered_points(2, edge), [[1, 1], [1, 3], [3, 3]])
    assert uncovered_points(4, np.ones((8, 8), dtype=bool)).shape == (0, 2)


def test_drop_covered_masks_by_overlap():
    covered = np.zeros((4, 4), dtype=bool)
    covered[:, :2] = True  # left half
    masks = np.zeros((5, 4, 4), dtype=bool)
    masks[0, :, :2] = True  # entirely covered: drop
    masks[1, :, 1:3] = True  # half covered (4 of 8): keep (not more than 0.5)
    masks[2, :, 1:2] = True
    masks[2, 0, 2] = True  # 4 of 5 covered: drop
    masks[3, :, 3] = True  # none covered: keep
    # masks[4] empty: drop
    keep = drop_covered_masks(masks, covered)
    assert keep.dtype == bool
    np.testing.assert_array_equal(keep, [False, True, False, True, False])
    np.testing.assert_array_equal(
        drop_covered_masks(masks, covered, max_overlap=0.8), [False, True, True, True, False]
    )
    np.testing.assert_array_equal(
        drop_covered_masks(masks, covered, max_overlap=0.0), [False, False, False, True, False]
    )
    as_tensor = drop_covered_masks(torch.from_numpy(masks), torch.from_numpy(covered))
    assert isinstance(as_tensor, torch.Tensor)
    assert as_tensor.tolist() == [False, True, False, True, False]
    assert drop_covered_masks(np.zeros((0, 4, 4), bool), covered).shape == (0,)
    with pytest.raises(ValueError):
        drop_covered_masks(masks, covered[:3])


# --- seen_from: where the center view could look ------------------------------------------------
@settings(max_examples=40, deadline=None)
@given(
    d=st.floats(-3.0, 3.0, allow_nan=False),
    ds=st.integers(-4, 4),
    dt=st.integers(-4, 4),
)
def test_a_single_plane_is_seen_wherever_it_lands_in_the_frame(d, ds, dt):
    height, width = 12, 16
    plane = torch.full((height, width), d)
    seen = seen_from(plane, plane, ds, dt, 0.2)
    rows = torch.round(torch.arange(height, dtype=torch.float32)[:, None] - plane * ds)
    cols = torch.round(torch.arange(width, dtype=torch.float32)[None, :] - plane * dt)
    inside = (rows >= 0) & (rows < height) & (cols >= 0) & (cols < width)
    assert torch.equal(seen, inside)


def test_non_finite_disparity_is_never_seen():
    disp = torch.zeros(4, 5)
    disp[1, 2] = float("nan")
    disp[2, 3] = float("inf")
    seen = seen_from(disp, torch.zeros(4, 5), 1, 1, 0.2)
    assert not seen[1, 2] and not seen[2, 3] and seen[0, 0]


@pytest.mark.parametrize("view", [(0, 0), (0, 4), (4, 0), (4, 4)])
def test_corner_pixels_seen_from_the_center_show_the_same_object_there(view):
    """Exact ground truth: a pixel the center sees shows the same object at its landing pixel;
    every pixel of a hidden object is unseen; most of a corner view is seen (the rest: strips
    entering at the frame border and disocclusions at depth edges)."""
    lf = generate_scene(grid=(5, 5), size=(64, 96), seed=0, num_objects=5, hidden_objects=2)
    center = lf.center
    disp = torch.as_tensor(lf.disparity[view])
    ds, dt = center[0] - view[0], center[1] - view[1]
    seen = seen_from(disp, torch.as_tensor(lf.disparity[center]), ds, dt, 0.2).numpy()
    labels = lf.labels[view]
    rows, cols = np.nonzero(seen)
    d = lf.disparity[view][rows, cols]
    to_rows, to_cols = np.round(rows - d * ds).astype(int), np.round(cols - d * dt).astype(int)
    there = lf.center_labels[to_rows, to_cols]
    assert np.mean(there == labels[rows, cols]) >= 0.97  # the rest: anti-aliased label edges
    for label in lf.meta["generator"]["hidden_labels"]:
        assert not seen[labels == label].any()
    assert seen.mean() >= 0.8


# --- extra_view_points: where an extra reference view asks --------------------------------------
@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**16),
    shape=st.tuples(st.integers(8, 60), st.integers(8, 60)),
    density=st.floats(0.5, 0.98),
    per_side=st.integers(2, 32),
    min_region=st.integers(1, 30),
)
def test_every_large_uncovered_region_gets_a_point_and_points_are_uncovered(
    seed, shape, density, per_side, min_region
):
    from scipy import ndimage

    rng = np.random.default_rng(seed)
    covered = ndimage.binary_opening(rng.random(shape) < density, np.ones((2, 2)))
    points = extra_view_points(per_side, covered, min_region)
    rows, cols = np.floor(points[:, 1]).astype(int), np.floor(points[:, 0]).astype(int)
    assert not covered[rows, cols].any()
    regions, count = ndimage.label(~covered, structure=np.ones((3, 3)))
    sizes = np.bincount(regions.ravel(), minlength=count + 1)
    reached = set(regions[rows, cols].tolist())
    for region in range(1, count + 1):
        if sizes[region] >= min_region:
            assert region in reached
    # the half-density grid, then at most one point per region
    thinned = uncovered_points(max(per_side // 2, 1), covered)
    assert np.array_equal(points[: len(thinned)], thinned)
    assert len(points) - len(thinned) <= int((sizes[1:] >= min_region).sum())


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**16),
    shape=st.tuples(st.integers(4, 50), st.integers(4, 50)),
    density=st.floats(0.3, 0.95),
    asked_count=st.integers(0, 12),
    min_region=st.integers(1, 20),
)
def test_unasked_regions_get_one_point_each_at_a_free_pixel(
    seed, shape, density, asked_count, min_region
):
    from scipy import ndimage

    rng = np.random.default_rng(seed)
    free = rng.random(shape) >= density
    asked = rng.random((asked_count, 2)) * np.array([shape[1], shape[0]])
    points = unasked_region_points(free, min_region, asked)
    rows, cols = np.floor(points[:, 1]).astype(int), np.floor(points[:, 0]).astype(int)
    assert free[rows, cols].all()
    regions, count = ndimage.label(free, structure=np.ones((3, 3)))
    sizes = np.bincount(regions.ravel(), minlength=count + 1)
    hit = set(regions[np.floor(asked[:, 1]).astype(int), np.floor(asked[:, 0]).astype(int)])
    expected = {r for r in range(1, count + 1) if sizes[r] >= min_region and r not in hit}
    got = regions[rows, cols].tolist()
    assert sorted(got) == sorted(expected)  # each such region once, and no other
    # the deepest pixel: as far from the non-free pixels (and the frame) as any in its region
    depth = ndimage.distance_transform_edt(np.pad(free, 1))[1:-1, 1:-1]
    for row, col, region in zip(rows, cols, got, strict=True):
        assert depth[row, col] == depth[regions == region].max()


def test_nothing_uncovered_asks_nowhere():
    assert extra_view_points(64, np.ones((30, 40), dtype=bool), 5).shape == (0, 2)
