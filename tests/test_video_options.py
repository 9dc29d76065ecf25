"""Tracking options on a light-field video (issue 25, docs/design.md section 10): a negative
click at a later frame, ``--auto``, ``--refine-views sparse`` per frame, and a tiny
random-weights SAM 2 end to end."""

from __future__ import annotations

import numpy as np
import pytest

import lfsam
from lfsam.cli.main import main
from lfsam.video import read_video
from lfsam.video.io.synth import generate_video, write_video_frames

FRAMES, GRID, SIZE = 4, (3, 3), (40, 56)


def _touching_rectangles(path):
    """A hand-made video: red rectangle A (label 1) touching green rectangle B (label 2) on
    its right, both moving 2 px per frame, zero disparity (every view the same)."""
    rng = np.random.default_rng(0)
    views = np.zeros((FRAMES, *GRID, *SIZE, 3), np.uint8)
    labels = np.zeros((FRAMES, *GRID, *SIZE), np.int32)
    background = rng.integers(0, 60, (*SIZE, 3))
    for f in range(FRAMES):
        x = 8 + 2 * f
        lab = np.zeros(SIZE, np.int32)
        lab[10:30, x:x + 18] = 1
        lab[12:28, x + 18:x + 30] = 2
        image = background.copy()
        image[lab == 1] = (200, 40, 40)
        image[lab == 2] = (40, 200, 40)
        views[f] = image.astype(np.uint8)
        labels[f] = lab
    np.savez(path, views=views, labels=labels,
             disparity=np.zeros(labels.shape, np.float32))
    return labels


def test_a_negative_click_at_a_later_frame_corrects_that_frame_onwards(tmp_path):
    # The oracle merging the neighbour with the longest shared border (--oracle-merge 1) leaks
    # into B from a click on A; a negative click on B at frame 2 removes the leak from frame 2
    # on (it is on the carried mask there, and must not be dropped for it).
    truth = _touching_rectangles(tmp_path / "clip.npz")
    out = tmp_path / "out"
    assert main(["segment", str(tmp_path / "clip.npz"), "--point", "16,20", "--neg", "35,20#2",
                 "--model", "oracle", "--oracle-merge", "1", "--disparity", "gt", "--quiet",
                 "--out", str(out)]) == 0
    result = lfsam.load_result(out)
    for f in range(FRAMES):
        center, a, b = result.labels[f][1, 1] == 1, truth[f, 1, 1] == 1, truth[f, 1, 1] == 2
        if f < 2:  # the leak, before the correction
            np.testing.assert_array_equal(center, a | b)
        else:
            np.testing.assert_array_equal(result.labels[f] == 1, truth[f] == 1)


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    folder = tmp_path_factory.mktemp("video") / "clip"
    write_video_frames(generate_video(grid=(5, 5), size=(48, 64), frames=3, seed=0,
                                      num_objects=2), folder)
    return folder


def _best_match(pred, truth):
    """Predicted id -> the ground-truth label it overlaps most."""
    return {int(i): int(np.bincount(truth[pred == i]).argmax())
            for i in np.unique(pred) if i > 0}


def test_auto_finds_frame_0_objects_and_keeps_their_ids(synthetic, tmp_path):
    out = tmp_path / "auto"
    assert main(["segment", str(synthetic), "--auto", "--model", "oracle", "--disparity", "gt",
                 "--quiet", "--out", str(out)]) == 0
    result, video = lfsam.load_result(out), read_video(synthetic)
    first = _best_match(result.labels[0], video.frame(0).labels)
    assert len(first) >= 2 and len(set(first.values())) == len(first)
    assert result.object_ids == sorted(first)
    for f in range(1, len(video)):
        assert _best_match(result.labels[f], video.frame(f).labels) == first


def test_sparse_refinement_per_frame(synthetic, tmp_path):
    video = read_video(synthetic)
    x, y = np.nonzero(video.frame(0).labels[2, 2] == 3)[::-1]
    out = tmp_path / "sparse"
    assert main(["segment", str(synthetic), "--point", f"{x[len(x) // 2]},{y[len(y) // 2]}",
                 "--model", "oracle", "--disparity", "gt", "--refine-views", "sparse",
                 "--quiet", "--out", str(out)]) == 0
    result = lfsam.load_result(out)
    for f in range(len(result)):
        meta = result.frame(f).meta
        assert meta["config"]["refine_views"] == "sparse"
        assert meta["views_encoded"] == 9 < 25  # center, corners, edge midpoints of 5x5
        assert np.asarray(meta["refined_views"]).sum() == 9
        assert (result.labels[f] == 1).any(axis=(2, 3)).all()  # filled into every view


def test_tiny_random_sam2_tracks_end_to_end(tmp_path):
    folder = tmp_path / "clip"
    write_video_frames(generate_video(grid=(3, 3), size=(48, 64), frames=3, seed=1,
                                      num_objects=2), folder)
    out = tmp_path / "out"
    assert main(["segment", str(folder), "--point", "32,24", "--point", "10,10",
                 "--model", "sam2-tiny-test", "--random-weights", "--disparity", "gt",
                 "--quiet", "--out", str(out)]) == 0
    result = lfsam.load_result(out)
    assert result.shape == (3, 3, 3, 48, 64)
    assert sorted(p.name for p in out.glob("frame_*.npz")) == [
        f"frame_{f:04d}.npz" for f in range(3)]
    for labels in result.labels:
        assert labels.shape == (3, 3, 48, 64) and labels.dtype == np.int32
        assert set(np.unique(labels)) <= {0, 1, 2}
    assert (result.labels[0] > 0).any(axis=(2, 3)).all()  # frame 0 segmented in every view
    # the center view's embedding comes from the video memory's encoder pass (issue 35)
    assert result.frame(0).meta["views_encoded"] == 8
    assert result.meta["model"] == "sam2-tiny-test"
