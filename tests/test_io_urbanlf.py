"""UrbanLF scene folders: 1-based names, label offset, and orientation found from the data."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from lfsam.errors import LfsamError
from lfsam.io import detect_format, read_lightfield
from lfsam.lightfield import LightField
from lfsam.synth import generate_scene


@pytest.fixture(scope="module")
def truth() -> LightField:
    # 3 x 5 views: odd (a center view exists) and not square (a transpose changes the grid).
    return generate_scene(grid=(3, 5), size=(40, 56), seed=11, num_objects=4)


def _write_urbanlf(folder, views, disparity=None, labels=None):
    """Write UrbanLF-Syn files: {r}_{c}.png 1-based, per-view disparity and 0-based labels."""
    folder.mkdir()
    for s in range(views.shape[0]):
        for t in range(views.shape[1]):
            name = f"{s + 1}_{t + 1}"
            Image.fromarray(np.ascontiguousarray(views[s, t])).save(folder / f"{name}.png")
            if disparity is not None:
                np.save(folder / f"{name}_disparity.npy", np.ascontiguousarray(disparity[s, t]))
            if labels is not None:
                np.save(folder / f"{name}_label.npy", np.ascontiguousarray(labels[s, t]) - 1)
    return folder


# How a data set might store the truth, and what the reader must then report.
STORAGE = {
    "as stored": (lambda a: a, 1.0, "views as stored; disparity as stored"),
    "both axes flipped": (
        lambda a: a[::-1, ::-1],
        1.0,
        "view rows and columns flipped; disparity as stored",
    ),
    "negated": (lambda a: a, -1.0, "views as stored; disparity negated"),
    "rows flipped": (lambda a: a[::-1], 1.0, "view rows flipped; disparity as stored"),
    "transposed": (
        lambda a: np.swapaxes(a, 0, 1),
        1.0,
        "view rows and columns swapped; disparity as stored",
    ),
}


@pytest.mark.parametrize("storage", list(STORAGE))
def test_orientation_is_detected_and_undone(tmp_path, truth, storage):
    arrange, sign, expected = STORAGE[storage]
    folder = _write_urbanlf(
        tmp_path / "scene",
        arrange(truth.views),
        sign * arrange(truth.disparity),
        arrange(truth.labels),
    )
    assert detect_format(folder) == "urbanlf"
    lf = read_lightfield(folder)
    assert lf.meta["orientation"] == expected
    assert "photo-consistency residual" in lf.meta["orientation_check"]
    np.testing.assert_array_equal(lf.views, truth.views)
    np.testing.assert_array_equal(lf.disparity, truth.disparity)
    np.testing.assert_array_equal(lf.labels, truth.labels)  # file labels + 1


def test_label_offset(tmp_path, truth):
    lf = read_lightfield(_write_urbanlf(tmp_path / "s", truth.views, truth.disparity, truth.labels))
    assert lf.meta["label_offset"] == 1
    assert lf.labels.min() == 1  # a file label 0 is a class, not "no label"
    assert np.load(tmp_path / "s" / "2_3_label.npy").min() == 0


def test_urbanlf_real_center_labels_only(tmp_path, truth):
    folder = _write_urbanlf(tmp_path / "real", truth.views)
    np.save(folder / "label.npy", truth.center_labels - 1)
    lf = read_lightfield(folder)
    assert lf.meta["format"] == "urbanlf"
    assert lf.disparity is None and lf.labels.shape == (40, 56)
    np.testing.assert_array_equal(lf.labels, truth.center_labels)
    assert "not verified" in lf.meta["orientation"]


def test_ground_truth_of_wrong_size(tmp_path, truth):
    folder = _write_urbanlf(tmp_path / "s", truth.views, truth.disparity, truth.labels)
    np.save(folder / "2_2_disparity.npy", np.zeros((10, 10), np.float32))
    with pytest.raises(LfsamError, match=r"2_2_disparity\.npy has shape \(10, 10\)"):
        read_lightfield(folder)


def test_missing_view(tmp_path, truth):
    folder = _write_urbanlf(tmp_path / "s", truth.views, truth.disparity, truth.labels)
    (folder / "3_4.png").unlink()
    with pytest.raises(LfsamError, match=r"3_4\.png"):
        read_lightfield(folder)
