"""Every real light field in ../shared/data loads with the grid and view size of its README."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from lfsam.io import detect_format, read_lightfield

# folder: (format, grid, view size, disparity, file of view (0, 1), file of view (1, 0))
TABLE = {
    "hci_antinous": ("hci4d", (9, 9), (512, 512), "center", "input_Cam001.png", "input_Cam009.png"),
    "lytro_2067": ("grid", (9, 9), (383, 552), None, "2067_01_02.png", "2067_02_01.png"),
    "t_rex_5x5": ("grid", (5, 5), (525, 840), None, "t_rex_00_01.png", "t_rex_01_00.png"),
    "translucent_7x7": (
        "grid",
        (7, 7),
        (430, 619),
        None,
        "translucent_00_01.png",
        "translucent_01_00.png",
    ),
    "stanford_legoknights_3x3": ("grid", (3, 3), (1024, 1024), None, "09_09.png", "10_08.png"),
    "dolls_3x3": ("grid", (3, 3), (1024, 1024), None, "0102.png", "0201.png"),
}


@pytest.mark.shared_data
@pytest.mark.parametrize("name", list(TABLE))
def test_scene_loads_with_its_grid_and_size(shared_data, name):
    fmt, grid, size, disparity, right, down = TABLE[name]
    folder = shared_data / name
    assert detect_format(folder) == fmt
    lf = read_lightfield(folder)
    assert lf.meta["format"] == fmt and lf.meta["source"] == str(folder)
    assert lf.grid_shape == grid
    assert lf.view_shape == size
    assert lf.views.dtype == np.uint8
    assert lf.labels is None
    if disparity is None:
        assert lf.disparity is None
    else:
        assert lf.disparity.shape == size
        # README: values range from about -3.1 to 2.7.
        assert -3.3 < float(lf.disparity.min()) < -2.9 and 2.5 < float(lf.disparity.max()) < 2.9
    # View order: (0, 1) is one step right of the top-left view, (1, 0) one step down.
    np.testing.assert_array_equal(lf.views[0, 1], np.asarray(Image.open(folder / right)))
    np.testing.assert_array_equal(lf.views[1, 0], np.asarray(Image.open(folder / down)))
