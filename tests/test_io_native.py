"""The package's scene folder: exact round trip, atomic writes, replacement rules."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

import lfsam.io.native as native
from lfsam.errors import LfsamError
from lfsam.io import read_lightfield, write_lightfield
from lfsam.lightfield import LightField
from lfsam.synth import generate_scene


@pytest.fixture(scope="module")
def scene() -> LightField:
    return generate_scene(grid=(3, 5), size=(32, 48), seed=4, num_objects=3)


def test_roundtrip_is_exact(tmp_path, scene):
    out = write_lightfield(scene, tmp_path / "scene")
    assert out == tmp_path / "scene"
    back = read_lightfield(out)
    assert back.meta["format"] == "lfsam"
    assert back.meta["source"] == str(out)
    assert back.meta["converted_from"] == f"synth: {scene.meta['source']}"
    np.testing.assert_array_equal(back.views, scene.views)
    np.testing.assert_array_equal(back.disparity, scene.disparity)
    np.testing.assert_array_equal(back.labels, scene.labels)
    assert back.disparity.dtype == np.float32 and back.labels.dtype == np.int32
    assert back.meta["generator"]["seed"] == 4


def test_layout_is_viewable_and_described(tmp_path, scene):
    folder = write_lightfield(scene, tmp_path / "scene")
    names = sorted(p.name for p in folder.iterdir())
    views = [n for n in names if n.startswith("view_")]
    assert len(views) == 15 and "view_02_04.png" in views and "view_00_00.png" in views
    # Any viewer sees view (s, t) in view_SS_TT.png.
    np.testing.assert_array_equal(
        np.asarray(Image.open(folder / "view_01_03.png")), scene.views[1, 3]
    )
    description = json.loads((folder / "lfsam_scene.json").read_text())
    assert description["format"] == "lfsam-scene" and description["version"] == 1
    assert description["grid"] == [3, 5] and description["view_size"] == [32, 48]
    assert description["disparity"] == "all views" and description["labels"] == "all views"
    assert np.load(folder / "disparity.npy").shape == (3, 5, 32, 48)


def test_center_only_ground_truth_and_none(tmp_path, scene):
    center = LightField(scene.views, disparity=scene.center_disparity, labels=scene.center_labels)
    back = read_lightfield(write_lightfield(center, tmp_path / "c"))
    np.testing.assert_array_equal(back.disparity, scene.center_disparity)
    np.testing.assert_array_equal(back.labels, scene.center_labels)
    bare = read_lightfield(write_lightfield(LightField(scene.views), tmp_path / "bare"))
    assert bare.disparity is None and bare.labels is None
    assert not (tmp_path / "bare" / "labels.npy").exists()


def test_more_than_100_views_per_axis_widen_the_names(tmp_path):
    views = np.zeros((1, 101, 8, 8, 3), dtype=np.uint8)
    views[0, 100] = 7
    folder = write_lightfield(LightField(views), tmp_path / "wide")
    assert (folder / "view_000_100.png").is_file()
    np.testing.assert_array_equal(read_lightfield(folder).views, views)


def test_failed_write_leaves_nothing(tmp_path, scene, monkeypatch):
    def broken(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(native.np, "save", broken)
    with pytest.raises(OSError, match="disk full"):
        write_lightfield(scene, tmp_path / "scene")
    assert list(tmp_path.iterdir()) == []


def test_replaces_own_scene_but_refuses_other_folders(tmp_path, scene):
    target = write_lightfield(scene, tmp_path / "scene")
    smaller = LightField(scene.views[:1, :2])
    write_lightfield(smaller, target)
    assert read_lightfield(target).grid_shape == (1, 2)
    assert not (target / "view_02_04.png").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene"]  # no leftovers
    other = tmp_path / "photos"
    other.mkdir()
    (other / "keep.txt").write_text("mine")
    with pytest.raises(LfsamError, match="not an lfsam scene"):
        write_lightfield(scene, other)
    assert (other / "keep.txt").read_text() == "mine"
    with pytest.raises(LfsamError, match="does not exist"):
        write_lightfield(scene, tmp_path / "no" / "such" / "scene")


def test_damaged_scene_errors(tmp_path, scene):
    folder = write_lightfield(scene, tmp_path / "scene")
    (folder / "view_01_01.png").unlink()
    with pytest.raises(LfsamError, match=r"lacks view view_01_01\.png"):
        read_lightfield(folder)
    (folder / "lfsam_scene.json").write_text("{not json")
    with pytest.raises(LfsamError, match="cannot read"):
        read_lightfield(folder)
    (folder / "lfsam_scene.json").write_text(
        json.dumps({"format": "lfsam-scene", "version": 99, "grid": [3, 5]})
    )
    with pytest.raises(LfsamError, match="newer lfsam"):
        read_lightfield(folder)
