"""Old HCI archive: lf.h5 with LF, GT_DEPTH and dH/focalLength/shift; labels.h5."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from lfsam.errors import LfsamError
from lfsam.io import detect_format, read_lightfield
from lfsam.io.hci_old import depth_to_disparity
from lfsam.lightfield import LightField
from lfsam.synth import generate_scene

DH, FOCAL, SHIFT = 0.05, 600.0, 3.0


@pytest.fixture(scope="module")
def truth() -> LightField:
    return generate_scene(grid=(5, 5), size=(40, 56), seed=21, num_objects=3)


def _write_old_hci(folder, views, disparity, labels=None, attrs_on="file"):
    """Store depth the archive's way: disparity = dH * f / depth - shift."""
    folder.mkdir()
    depth = DH * FOCAL / (disparity.astype(np.float64) + SHIFT)
    with h5py.File(folder / "lf.h5", "w") as handle:
        handle["LF"] = views
        handle["GT_DEPTH"] = depth.astype(np.float32)
        owner = handle if attrs_on == "file" else handle["LF"]
        owner.attrs["dH"] = DH
        owner.attrs["focalLength"] = FOCAL
        owner.attrs["shift"] = SHIFT
    if labels is not None:
        with h5py.File(folder / "labels.h5", "w") as handle:
            handle["GT_LABELS"] = labels - 1
    return folder


def test_depth_to_disparity_formula():
    depth = np.array([[10.0, 20.0], [0.0, -1.0]])
    out = depth_to_disparity(depth, dh=2.0, focal_length=5.0, shift=0.5)
    np.testing.assert_allclose(out[0], [2.0 * 5.0 / 10.0 - 0.5, 2.0 * 5.0 / 20.0 - 0.5])
    assert np.isnan(out[1]).all()
    assert out.dtype == np.float32


def test_reads_views_disparity_and_labels(tmp_path, truth):
    folder = _write_old_hci(tmp_path / "buddha", truth.views, truth.disparity, truth.labels)
    assert detect_format(folder) == "hci-old"
    assert detect_format(folder / "lf.h5") == "hci-old"
    lf = read_lightfield(folder)
    np.testing.assert_array_equal(lf.views, truth.views)
    np.testing.assert_allclose(lf.disparity, truth.disparity, atol=2e-5)
    np.testing.assert_array_equal(lf.labels, truth.labels)
    assert lf.meta["label_offset"] == 1
    assert lf.meta["orientation"] == "views as stored; disparity as stored"
    assert lf.meta["depth_to_disparity"] == "0.05 * 600 / depth - 3"


def test_flipped_grid_is_detected(tmp_path, truth):
    folder = _write_old_hci(
        tmp_path / "s", truth.views[::-1], truth.disparity[::-1], attrs_on="dataset"
    )
    lf = read_lightfield(folder / "lf.h5")
    assert lf.meta["orientation"] == "view rows flipped; disparity as stored"
    np.testing.assert_array_equal(lf.views, truth.views)
    np.testing.assert_allclose(lf.disparity, truth.disparity, atol=2e-5)


def test_center_only_depth(tmp_path, truth):
    folder = _write_old_hci(tmp_path / "s", truth.views, truth.center_disparity)
    lf = read_lightfield(folder)
    assert lf.disparity.shape == (40, 56)
    np.testing.assert_allclose(lf.disparity, truth.center_disparity, atol=2e-5)


def test_missing_attribute(tmp_path, truth):
    folder = _write_old_hci(tmp_path / "s", truth.views, truth.disparity)
    with h5py.File(folder / "lf.h5", "a") as handle:
        del handle.attrs["shift"]
    with pytest.raises(LfsamError, match="lacks the attribute 'shift'"):
        read_lightfield(folder)


def test_plain_h5_is_not_old_hci(tmp_path, truth):
    with h5py.File(tmp_path / "plain.h5", "w") as handle:
        handle["LF"] = truth.views
    assert detect_format(tmp_path / "plain.h5") == "h5"
