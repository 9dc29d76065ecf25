"""Synthetic light-field videos (issue 25): moving objects with exact per-frame ground truth."""

from __future__ import annotations

import numpy as np
import pytest

from lfsam.cli.main import main
from lfsam.errors import LfsamError
from lfsam.video import read_video
from lfsam.video.io.synth import generate_video, video_specs

SETTINGS = {"grid": (3, 3), "size": (48, 64), "frames": 6, "seed": 0, "num_objects": 3}


@pytest.fixture(scope="module")
def frames():
    return list(generate_video(**SETTINGS))


def test_objects_move_in_the_plane_and_in_depth(frames):
    labels = np.stack([lf.labels for lf in frames])  # (F, S, T, U, V)
    disparity = np.stack([lf.disparity for lf in frames])
    assert set(np.unique(labels)) <= {1, 2, 3, 4}
    for label in (3, 4):  # the objects that stay
        where = labels[:, 1, 1] == label
        assert where.any(axis=(1, 2)).all()
        rows, cols = np.nonzero(where[0])
        rows5, cols5 = np.nonzero(where[-1])
        moved = np.hypot(rows5.mean() - rows.mean(), cols5.mean() - cols.mean())
        assert moved > 2.0
        depth = [disparity[f, 1, 1][where[f]].mean() for f in range(len(frames))]
        assert np.ptp(depth) > 0.1
    # the geometry is exact: the center view's label of a point is where the disparity says
    lf = frames[2]
    u, v = np.mgrid[0:48, 0:64]
    d = lf.disparity[1, 1]
    uu, vv = np.rint(u - d * (0 - 1)).astype(int), np.rint(v - d * (0 - 1)).astype(int)
    inside = (uu >= 0) & (uu < 48) & (vv >= 0) & (vv < 64)
    agree = lf.labels[0, 0][uu[inside], vv[inside]] == lf.labels[1, 1][inside]
    assert agree.mean() > 0.9  # (occlusions and rounding account for the rest)


def test_an_object_leaves_and_comes_back(frames):
    area = np.array([[(lf.labels[s, t] == 2).sum() for s in range(3) for t in range(3)]
                     for lf in frames])
    assert (area[0] > 30).all() and (area[-1] > 30).all()
    assert (area[2:4] == 0).all()  # out of every view in the middle
    visible = np.array([[(lf.labels[1, 1] == k).sum() for k in (3, 4)] for lf in frames])
    assert np.ptp(visible, axis=0).max() > 20  # occluded and uncovered over time


def test_deterministic_per_seed_and_cli(tmp_path, capsys):
    a, b = video_specs(**SETTINGS), video_specs(**SETTINGS)
    assert a == b and video_specs(**{**SETTINGS, "seed": 1}) != a
    args = ["synth", "--frames", "3", "--grid", "3x3", "--size", "24x32", "--objects", "2"]
    assert main([*args[:1], str(tmp_path / "v"), *args[1:]]) == 0
    assert main([*args[:1], str(tmp_path / "w"), *args[1:]]) == 0
    assert "3 frames of 3 x 3 views of 24 x 32" in capsys.readouterr().out
    with read_video(tmp_path / "v") as v, read_video(tmp_path / "w") as w:
        assert len(v) == 3 and v.has_labels and v.has_disparity
        for f in range(3):
            np.testing.assert_array_equal(v.frame(f).views, w.frame(f).views)
            np.testing.assert_array_equal(v.frame(f).labels, w.frame(f).labels)
    with pytest.raises(LfsamError, match="at least 1"):
        video_specs(frames=0)
    assert main(["synth", str(tmp_path / "x.npz"), "--frames", "2"]) == 2
    assert not (tmp_path / "x.npz").exists()
