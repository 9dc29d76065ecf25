"""Folders of views named by grid position: RR_CC with prefixes, RRCC, linear numbers."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from lfsam.errors import LfsamError
from lfsam.io import detect_format, read_lightfield
from lfsam.io.grid_folder import scan_grid_folder
from lfsam.lightfield import LightField
from lfsam.synth import generate_scene


@pytest.fixture(scope="module")
def scene() -> LightField:
    # 3 x 4: not square, so a transposed or mis-ordered read cannot pass.
    return generate_scene(grid=(3, 4), size=(24, 40), seed=5, num_objects=2)


def _write(folder, views, name):
    folder.mkdir(exist_ok=True)
    for s in range(views.shape[0]):
        for t in range(views.shape[1]):
            Image.fromarray(views[s, t]).save(folder / name(s, t))
    return folder


@pytest.mark.parametrize(
    ("name", "naming", "rows", "cols"),
    [
        (lambda s, t: f"2067_{s + 1:02d}_{t + 1:02d}.png", "'2067' + ROW_COL", "01..03", "01..04"),
        (lambda s, t: f"t_rex_{s:02d}_{t:02d}.png", "'t_rex' + ROW_COL", "00..02", "00..03"),
        (lambda s, t: f"{s + 9:02d}_{t + 8:02d}.png", "ROW_COL", "09..11", "08..11"),
        (lambda s, t: f"{s + 1}-{t + 1}.jpg", "ROW_COL", "1..3", "1..4"),
        (lambda s, t: f"{s + 1:02d}{t + 1:02d}.png", "RRCC", "01..03", "01..04"),
        (lambda s, t: f"cam{s + 1:03d}{t + 1:03d}.png", "'cam' + RRCC", "001..003", "001..004"),
    ],
)
def test_grid_namings(tmp_path, scene, name, naming, rows, cols):
    lossy = name(0, 0).endswith(".jpg")
    folder = _write(tmp_path / "lf", scene.views, name)
    assert detect_format(folder) == "grid"
    lf = read_lightfield(folder)
    assert lf.grid_shape == (3, 4) and lf.view_shape == (24, 40)
    if lossy:
        assert np.abs(lf.views.astype(int) - scene.views).mean() < 8
    else:
        np.testing.assert_array_equal(lf.views, scene.views)
    assert lf.meta["naming"] == naming
    assert (lf.meta["view_rows"], lf.meta["view_cols"]) == (rows, cols)
    assert "not verified" in lf.meta["orientation"]


def test_linear_numbering_is_row_major(tmp_path):
    views = generate_scene(grid=(3, 3), size=(16, 24), seed=1, num_objects=1).views
    folder = _write(tmp_path / "lin", views, lambda s, t: f"img_{s * 3 + t + 1:03d}.png")
    lf = read_lightfield(folder)
    np.testing.assert_array_equal(lf.views, views)
    assert lf.meta["naming"] == "'img_' + row-major number"


def test_other_files_are_ignored(tmp_path, scene):
    folder = _write(tmp_path / "lf", scene.views, lambda s, t: f"{s:02d}_{t:02d}.png")
    Image.fromarray(scene.views[0, 0]).save(folder / "thumbnail.png")
    (folder / "notes.txt").write_text("hello")
    lf = read_lightfield(folder)
    np.testing.assert_array_equal(lf.views, scene.views)
    assert lf.meta["ignored_files"] == ["thumbnail.png"]


def test_missing_view_is_named(tmp_path, scene):
    folder = _write(tmp_path / "lf", scene.views, lambda s, t: f"t_rex_{s:02d}_{t:02d}.png")
    (folder / "t_rex_01_02.png").unlink()
    with pytest.raises(LfsamError, match=r"t_rex_01_02\.png") as info:
        read_lightfield(folder)
    assert "3x4 grid" in str(info.value)


def test_views_of_different_sizes(tmp_path, scene):
    folder = _write(tmp_path / "lf", scene.views, lambda s, t: f"{s:02d}_{t:02d}.png")
    Image.fromarray(scene.views[1, 1, :20]).save(folder / "01_01.png")
    with pytest.raises(LfsamError, match=r"views differ in size: 01_01\.png is 20x40"):
        read_lightfield(folder)


def test_unreadable_image(tmp_path, scene):
    folder = _write(tmp_path / "lf", scene.views, lambda s, t: f"{s:02d}_{t:02d}.png")
    (folder / "02_03.png").write_bytes(b"\x89PNG\r\n\x1a\n truncated")
    with pytest.raises(LfsamError, match=r"cannot read image .*02_03\.png"):
        read_lightfield(folder)


def test_duplicate_positions(tmp_path, scene):
    folder = _write(tmp_path / "lf", scene.views[:2, :2], lambda s, t: f"{s}_{t}.png")
    Image.fromarray(scene.views[0, 0]).save(folder / "00_01.png")
    with pytest.raises(LfsamError, match="two files for view"):
        read_lightfield(folder)


def test_grayscale_and_rgba_views_become_rgb(tmp_path, scene):
    folder = tmp_path / "modes"
    folder.mkdir()
    gray = scene.views[..., 1]
    for t in range(2):
        Image.fromarray(gray[0, t]).save(folder / f"0_{t}.png")
    lf = read_lightfield(folder)
    np.testing.assert_array_equal(lf.views[0, 1], np.repeat(gray[0, 1][..., None], 3, -1))
    rgba = np.concatenate([scene.views[0, 0], np.full((24, 40, 1), 9, np.uint8)], -1)
    Image.fromarray(rgba).save(folder / "0_0.png")
    np.testing.assert_array_equal(read_lightfield(folder).views[0, 0], scene.views[0, 0])


def test_scan_reports_layout(tmp_path, scene):
    folder = _write(tmp_path / "lf", scene.views, lambda s, t: f"x_{s + 2}_{t + 5}.png")
    layout = scan_grid_folder(folder)
    assert layout.grid_shape == (3, 4)
    assert layout.rows == [2, 3, 4] and layout.cols == [5, 6, 7, 8]
    assert layout.paths[2][3].name == "x_4_8.png"
    assert layout.prefix == "x" and layout.scheme == "pair"
