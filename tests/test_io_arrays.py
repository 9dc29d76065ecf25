"""Array files: .npz (the exchange format), .npy, HDF5 and MATLAB v5 / v7.3."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
import scipy.io

from lfsam.errors import LfsamError
from lfsam.io import read_lightfield, write_lightfield
from lfsam.lightfield import LightField
from lfsam.synth import generate_scene


@pytest.fixture(scope="module")
def scene() -> LightField:
    return generate_scene(grid=(3, 3), size=(32, 48), seed=2, num_objects=2)


def test_npz_roundtrip_with_ground_truth_and_meta(tmp_path, scene):
    path = write_lightfield(scene, tmp_path / "lf.npz")
    with np.load(path) as archive:  # a plain NumPy archive, no pickles
        assert sorted(archive.files) == ["categories", "disparity", "labels", "meta", "views"]
        assert archive["views"].dtype == np.uint8 and archive["views"].shape == (3, 3, 32, 48, 3)
    back = read_lightfield(path)
    assert back.meta["format"] == "npz" and back.meta["source"] == str(path)
    np.testing.assert_array_equal(back.views, scene.views)
    np.testing.assert_array_equal(back.disparity, scene.disparity)
    np.testing.assert_array_equal(back.labels, scene.labels)
    assert back.categories == scene.categories  # a JSON string, label id -> name (issue 26)
    assert back.meta["generator"]["seed"] == 2


def test_npz_bytes_are_reproducible(tmp_path, scene):
    first = write_lightfield(scene, tmp_path / "a.npz").read_bytes()
    second = write_lightfield(scene, tmp_path / "b.npz").read_bytes()
    assert first == second


def test_foreign_npz_with_other_key(tmp_path, scene):
    np.savez(tmp_path / "x.npz", LF=scene.views, disp=scene.center_disparity)
    back = read_lightfield(tmp_path / "x.npz")
    np.testing.assert_array_equal(back.views, scene.views)
    np.testing.assert_array_equal(back.disparity, scene.center_disparity)


def test_npz_with_pickled_extras_reads_without_unpickling(tmp_path, scene):
    np.savez(tmp_path / "p.npz", views=scene.views, info=np.array([{"a": 1}], dtype=object))
    np.testing.assert_array_equal(read_lightfield(tmp_path / "p.npz").views, scene.views)


def test_npy(tmp_path, scene):
    np.save(tmp_path / "lf.npy", scene.views)
    back = read_lightfield(tmp_path / "lf.npy")
    assert back.meta["format"] == "npy"
    np.testing.assert_array_equal(back.views, scene.views)


def test_float_views_are_scaled_to_uint8(tmp_path, scene):
    np.save(tmp_path / "f.npy", scene.views.astype(np.float32) / 255.0)
    np.testing.assert_array_equal(read_lightfield(tmp_path / "f.npy").views, scene.views)


def test_h5_finds_the_5d_dataset(tmp_path, scene):
    with h5py.File(tmp_path / "lf.h5", "w") as handle:
        handle["meta/notes"] = np.arange(3)
        handle["group/LF"] = scene.views
    back = read_lightfield(tmp_path / "lf.h5")
    assert back.meta["format"] == "h5"
    np.testing.assert_array_equal(back.views, scene.views)


def test_mat_v5(tmp_path, scene):
    scipy.io.savemat(tmp_path / "lf.mat", {"LF": scene.views, "other": np.zeros(3)})
    back = read_lightfield(tmp_path / "lf.mat")
    assert back.meta["format"] == "mat"
    np.testing.assert_array_equal(back.views, scene.views)


def test_mat_v5_weight_channel_is_dropped(tmp_path, scene):
    rgbw = np.concatenate([scene.views, np.full((*scene.views.shape[:4], 1), 255, np.uint8)], -1)
    scipy.io.savemat(tmp_path / "w.mat", {"LF": rgbw})
    np.testing.assert_array_equal(read_lightfield(tmp_path / "w.mat").views, scene.views)


def test_mat_v73_is_hdf5_with_reversed_axes(tmp_path, scene):
    # MATLAB v7.3 stores column-major: a MATLAB [S, T, U, V, 3] array appears reversed in HDF5.
    path = tmp_path / "lf73.mat"
    with h5py.File(path, "w", userblock_size=512) as handle:
        handle["LF"] = scene.views.transpose()
    with open(path, "r+b") as handle:
        handle.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64".ljust(116, b" "))
        handle.write(b"\0" * 8 + b"\x00\x02" + b"IM")
    back = read_lightfield(path)
    assert back.meta["format"] == "mat"
    np.testing.assert_array_equal(back.views, scene.views)


@pytest.mark.parametrize(
    ("shape", "hint"),
    [
        ((3, 3, 32, 48), "4-D array"),
        ((32, 48, 3), "one image"),
        ((3, 3, 3, 32, 48), "channels-first"),
        ((3, 3, 32, 48, 2), "2 channels"),
    ],
)
def test_wrong_shapes_say_what_is_needed(tmp_path, shape, hint):
    np.save(tmp_path / "bad.npy", np.zeros(shape, dtype=np.uint8))
    with pytest.raises(LfsamError, match=r"\[S, T, U, V, 3\]") as info:
        read_lightfield(tmp_path / "bad.npy")
    assert hint in str(info.value)
    assert "\n" not in str(info.value)


def test_unreadable_array_files(tmp_path):
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(LfsamError, match="cannot read"):
        read_lightfield(tmp_path / "junk.npz")
    (tmp_path / "junk.h5").write_bytes(b"not hdf5")
    with pytest.raises(LfsamError, match="cannot read"):
        read_lightfield(tmp_path / "junk.h5")
    np.savez(tmp_path / "none.npz", a=np.zeros((2, 2)))
    with pytest.raises(LfsamError, match="no light-field array"):
        read_lightfield(tmp_path / "none.npz")
