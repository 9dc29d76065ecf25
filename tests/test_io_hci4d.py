"""HCI 4D benchmark folders: input_CamNNN.png row-major, PFM ground truth, parameters.cfg."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from lfsam.errors import LfsamError
from lfsam.io import detect_format, read_lightfield
from lfsam.lightfield import LightField
from lfsam.synth import generate_scene

CFG = """\
[intrinsics]
focal_length_mm = 100
image_resolution_x_px = {cols}
image_resolution_y_px = {rows}

[extrinsics]
num_cams_x = {t}
num_cams_y = {s}
baseline_mm = 160.0

[meta]
disp_min = -2.0
disp_max = 2.0
"""


@pytest.fixture(scope="module")
def truth() -> LightField:
    return generate_scene(grid=(3, 3), size=(36, 52), seed=8, num_objects=3)


def _pfm_by_hand(path, image):
    """A little-endian PFM written independently of lfsam: rows bottom-to-top."""
    rows, cols = image.shape
    with open(path, "wb") as handle:
        handle.write(f"Pf\n{cols} {rows}\n-1\n".encode())
        handle.write(np.ascontiguousarray(image[::-1], dtype="<f4").tobytes())


def _write_hci(folder, lf, per_view=False, cfg=True):
    folder.mkdir()
    s_count, t_count = lf.grid_shape
    for s in range(s_count):
        for t in range(t_count):
            index = s * t_count + t
            Image.fromarray(lf.views[s, t]).save(folder / f"input_Cam{index:03d}.png")
            if per_view:
                _pfm_by_hand(folder / f"gt_disp_lowres_Cam{index:03d}.pfm", lf.disparity[s, t])
    _pfm_by_hand(folder / "gt_disp_lowres.pfm", lf.center_disparity)
    if cfg:
        rows, cols = lf.view_shape
        (folder / "parameters.cfg").write_text(
            CFG.format(rows=rows, cols=cols, s=s_count, t=t_count)
        )
    return folder


def test_reads_views_and_center_disparity(tmp_path, truth):
    folder = _write_hci(tmp_path / "scene", truth)
    assert detect_format(folder) == "hci4d"
    lf = read_lightfield(folder)
    np.testing.assert_array_equal(lf.views, truth.views)
    # Exact equality also proves the PFM rows were flipped (the map is not symmetric).
    assert not np.array_equal(truth.center_disparity, truth.center_disparity[::-1])
    np.testing.assert_array_equal(lf.disparity, truth.center_disparity)
    assert lf.labels is None
    assert lf.meta["parameters"]["extrinsics"]["baseline_mm"] == 160.0
    assert "package convention" in lf.meta["orientation"]


def test_per_view_disparity(tmp_path, truth):
    lf = read_lightfield(_write_hci(tmp_path / "scene", truth, per_view=True))
    np.testing.assert_array_equal(lf.disparity, truth.disparity)


def test_non_square_grid_from_parameters(tmp_path):
    wide = generate_scene(grid=(3, 5), size=(16, 24), seed=3, num_objects=1)
    lf = read_lightfield(_write_hci(tmp_path / "wide", wide))
    assert lf.grid_shape == (3, 5)
    np.testing.assert_array_equal(lf.views, wide.views)


def test_without_parameters_the_grid_is_square(tmp_path, truth):
    lf = read_lightfield(_write_hci(tmp_path / "scene", truth, cfg=False))
    assert lf.grid_shape == (3, 3) and "parameters" not in lf.meta


def test_missing_camera(tmp_path, truth):
    folder = _write_hci(tmp_path / "scene", truth)
    (folder / "input_Cam004.png").unlink()  # the center of the 3x3 grid: partial grids need it
    with pytest.raises(LfsamError, match=r"center view \(number 004.*is missing"):
        read_lightfield(folder)


def test_ground_truth_of_another_resolution(tmp_path, truth):
    folder = _write_hci(tmp_path / "scene", truth)
    _pfm_by_hand(folder / "gt_disp_lowres.pfm", np.zeros((72, 104), np.float32))
    with pytest.raises(LfsamError, match="72x104 but the views are 36x52"):
        read_lightfield(folder)
