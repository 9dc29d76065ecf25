"""Hidden objects in synthetic scenes (issue 16): unseen by the center view, seen by a corner.

Checked against the rendered ground truth and the exact geometry (sample_geometry), independent of
the placement's own bookkeeping.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from lfsam.cli.main import main
from lfsam.errors import LfsamError
from lfsam.io import read_lightfield
from lfsam.synth import random_scene, render_scene, sample_geometry
from lfsam.synth.hidden import default_min_area
from test_convention import _extreme_views, _residual, _visible

GRID, SIZE, OBJECTS, HIDDEN = (5, 5), (64, 96), 5, 2


@pytest.fixture(scope="module")
def scenes():
    spec = random_scene(grid=GRID, size=SIZE, seed=0, num_objects=OBJECTS, hidden_objects=HIDDEN)
    plain = random_scene(grid=GRID, size=SIZE, seed=0, num_objects=OBJECTS)
    return spec, render_scene(spec), render_scene(plain)


def _corners(grid):
    return [(0, 0), (0, grid[1] - 1), (grid[0] - 1, 0), (grid[0] - 1, grid[1] - 1)]


def test_hidden_labels_are_recorded_after_the_other_objects(scenes):
    _, lf, _ = scenes
    generator = lf.meta["generator"]
    # Background 1, objects 2..6, hidden 7, 8.
    assert generator["hidden_objects"] == HIDDEN
    assert generator["hidden_labels"] == [7, 8]
    assert [o["label"] for o in generator["objects"]] == list(range(1, 9))


def test_center_view_cannot_see_them_but_a_corner_view_can(scenes):
    _, lf, _ = scenes
    for label in lf.meta["generator"]["hidden_labels"]:
        assert int((lf.center_labels == label).sum()) == 0
        in_corners = [int((lf.labels[s, t] == label).sum()) for s, t in _corners(GRID)]
        assert max(in_corners) >= default_min_area(SIZE) >= 12, (label, in_corners)


def test_the_rest_of_the_scene_is_the_scene_without_them(scenes):
    _, lf, plain = scenes
    sc, tc = lf.center
    # The center view is byte-identical: labels, disparity and the anti-aliased RGB.
    np.testing.assert_array_equal(lf.views[sc, tc], plain.views[sc, tc])
    np.testing.assert_array_equal(lf.labels[sc, tc], plain.labels[sc, tc])
    np.testing.assert_array_equal(lf.disparity[sc, tc], plain.disparity[sc, tc])
    hidden = np.isin(lf.labels, lf.meta["generator"]["hidden_labels"])
    assert hidden.any()
    np.testing.assert_array_equal(lf.labels[~hidden], plain.labels[~hidden])
    np.testing.assert_array_equal(lf.disparity[~hidden], plain.disparity[~hidden])
    # Colours change only at pixels where one of the 2x2 anti-aliasing samples (offsets
    # +-0.25, the renderer's default supersample=2) falls on a hidden object.
    spec = scenes[0]
    rows, cols = np.meshgrid(np.arange(SIZE[0]), np.arange(SIZE[1]), indexing="ij")
    for s, t in [*_corners(GRID), lf.center, (1, 3)]:
        touched = np.zeros(SIZE, dtype=bool)
        for du in (-0.25, 0.25):
            for dv in (-0.25, 0.25):
                labels, _ = sample_geometry(spec, s, t, rows + du, cols + dv)
                touched |= np.isin(labels, lf.meta["generator"]["hidden_labels"])
        assert touched.sum() >= hidden[s, t].sum()
        np.testing.assert_array_equal(lf.views[s, t][~touched], plain.views[s, t][~touched])
    # Where they show, they cover what the plain scene had there: only the background.
    assert set(np.unique(plain.labels[hidden])) == {1}


def test_they_hide_behind_a_closer_object_not_off_view(scenes):
    spec, lf, _ = scenes
    sc, tc = lf.center
    for s, t in _corners(GRID):
        for label in lf.meta["generator"]["hidden_labels"]:
            u, v = np.nonzero(lf.labels[s, t] == label)
            d = lf.disparity[s, t][u, v].astype(np.float64)
            # Where the center view would see these points: inside the view, on a closer object.
            cu, cv = u + d * (s - sc), v + d * (t - tc)
            assert np.all((cu >= 0) & (cu <= SIZE[0] - 1) & (cv >= 0) & (cv <= SIZE[1] - 1))
            labels, disparity = sample_geometry(spec, sc, tc, cu, cv)
            assert np.all(disparity > d + 1e-6)
            assert not np.isin(labels, [1, *lf.meta["generator"]["hidden_labels"]]).any()


def test_labels_and_disparity_are_exact(scenes):
    spec, lf, _ = scenes
    rows, cols = np.meshgrid(np.arange(SIZE[0]), np.arange(SIZE[1]), indexing="ij")
    for s, t in [*_corners(GRID), (2, 2), (4, 1)]:
        labels, disparity = sample_geometry(spec, s, t, rows, cols)
        np.testing.assert_array_equal(lf.labels[s, t], labels)
        np.testing.assert_array_equal(lf.disparity[s, t], disparity.astype(np.float32))


def test_photo_consistent_with_the_ground_truth_disparity(scenes):
    _, lf, _ = scenes
    for s, t in _extreme_views(lf.grid_shape):
        visible = _visible(lf, s, t)
        assert visible.mean() > 0.7
        right = _residual(lf, s, t, 1.0, visible)
        wrong = _residual(lf, s, t, -1.0, visible)
        assert wrong > 4 * right, (s, t, right, wrong)


def test_deterministic_per_seed(scenes):
    spec, _, _ = scenes
    again = random_scene(grid=GRID, size=SIZE, seed=0, num_objects=OBJECTS, hidden_objects=HIDDEN)
    other = random_scene(grid=GRID, size=SIZE, seed=2, num_objects=OBJECTS, hidden_objects=HIDDEN)
    assert again == spec
    assert other.objects[-1] != spec.objects[-1]


def test_impossible_requests_are_one_line_user_errors():
    with pytest.raises(LfsamError, match="outer views"):
        random_scene(grid=(1, 1), size=(32, 32), num_objects=3, hidden_objects=1)
    with pytest.raises(LfsamError, match=">= 0"):
        random_scene(grid=(3, 3), size=(32, 32), hidden_objects=-1)
    # No objects: nothing to hide behind.
    with pytest.raises(LfsamError, match="could hide only 0 of 1"):
        random_scene(grid=(3, 3), size=(32, 32), num_objects=0, hidden_objects=1)


def test_cli_hidden_objects(tmp_path, capsys):
    out = tmp_path / "hidden.npz"
    args = ["synth", str(out), "--grid", "5x5", "--size", "48x64", "--objects", "4"]
    assert main([*args, "--seed", "2", "--hidden-objects", "1", "--supersample", "1"]) == 0
    assert "4 objects + 1 hidden" in capsys.readouterr().out
    lf = read_lightfield(out)
    meta = lf.meta["generator"] if "generator" in lf.meta else json.loads(lf.meta)["generator"]
    assert meta["hidden_labels"] == [6]
    assert not (lf.center_labels == 6).any() and (lf.labels == 6).any()
    with pytest.raises(SystemExit):
        main([*args, "--hidden-objects", "-2"])
