"""Format detection, explicit formats and the errors for paths that hold no light field."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from lfsam.errors import LfsamError
from lfsam.io import FORMATS, detect_format, read_lightfield, write_lightfield
from lfsam.lightfield import LightField


@pytest.fixture
def tiny() -> LightField:
    rng = np.random.default_rng(0)
    return LightField(rng.integers(0, 256, size=(2, 3, 8, 10, 3), dtype=np.uint8))


def test_format_names():
    assert set(FORMATS) == {
        "lfsam",
        "npz",
        "npy",
        "h5",
        "mat",
        "urbanlf",
        "hci4d",
        "hci-old",
        "grid",
    }


def test_detects_native_scene_and_its_marker(tmp_path, tiny):
    folder = write_lightfield(tiny, tmp_path / "scene")
    assert detect_format(folder) == "lfsam"
    assert detect_format(folder / "lfsam_scene.json") == "lfsam"
    np.testing.assert_array_equal(read_lightfield(folder / "lfsam_scene.json").views, tiny.views)


def test_explicit_format_overrides_detection(tmp_path, tiny):
    folder = write_lightfield(tiny, tmp_path / "scene")
    # The scene folder also reads as a generic grid of view_RR_CC.png images.
    lf = read_lightfield(folder, format="grid")
    assert lf.meta["format"] == "grid"
    np.testing.assert_array_equal(lf.views, tiny.views)
    assert read_lightfield(folder, format="native").meta["format"] == "lfsam"  # alias


def _missing(root):
    return root / "nothing"


def _empty(root):
    (root / "empty").mkdir()
    return root / "empty"


def _documents(root):
    (root / "docs").mkdir()
    (root / "docs" / "a.txt").write_text("x")
    return root / "docs"


def _text_file(root):
    (root / "a.txt").write_text("x")
    return root / "a.txt"


def _one_image(root):
    Image.new("RGB", (4, 4)).save(root / "one.png")
    return root / "one.png"


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (_missing, "no such file or folder"),
        (_empty, "is empty"),
        (_documents, "no light field found"),
        (_text_file, "cannot tell the light-field"),
        (_one_image, "single image"),
    ],
)
def test_paths_without_a_light_field(tmp_path, make, message):
    path = make(tmp_path)
    with pytest.raises(LfsamError, match=message) as info:
        read_lightfield(path)
    assert "\n" not in str(info.value)


def test_format_and_path_kind_must_agree(tmp_path, tiny):
    folder = write_lightfield(tiny, tmp_path / "scene")
    with pytest.raises(LfsamError, match="reads a file"):
        read_lightfield(folder, format="npz")
    archive = write_lightfield(tiny, tmp_path / "lf.npz")
    with pytest.raises(LfsamError, match="reads a folder"):
        read_lightfield(archive, format="grid")
    with pytest.raises(LfsamError, match="unknown light-field format 'png'"):
        read_lightfield(archive, format="png")


def test_write_format_must_fit_the_name(tmp_path, tiny):
    with pytest.raises(LfsamError, match=r"end the name in \.npz"):
        write_lightfield(tiny, tmp_path / "scene", format="npz")
    with pytest.raises(LfsamError, match=r"without the \.npz suffix"):
        write_lightfield(tiny, tmp_path / "x.npz", format="lfsam")
    with pytest.raises(LfsamError, match="cannot write format 'h5'"):
        write_lightfield(tiny, tmp_path / "x.h5", format="h5")
