"""Light fields with missing views: HCI "star" subsets, grid folders with holes, round trips
through the package's formats, metrics that skip absent views (docs/design.md section 8)."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from PIL import Image

from lfsam.cli.main import main
from lfsam.errors import LfsamError
from lfsam.io import read_lightfield, write_lightfield
from lfsam.lightfield import LightField
from lfsam.metrics import evaluate_labels, evaluate_result
from lfsam.result import SegmentationResult
from lfsam.synth import generate_scene


def _star(side: int = 9) -> np.ndarray:
    """Center row, center column and both diagonals: 33 of 81 views for a 9x9 grid."""
    s, t = np.mgrid[:side, :side]
    c = side // 2
    return (s == c) | (t == c) | (s == t) | (s + t == side - 1)


def _view(s: int, t: int) -> np.ndarray:
    """A tiny image that says which view it is."""
    image = np.zeros((6, 10, 3), dtype=np.uint8)
    image[..., 0] = 20 * s + 1
    image[..., 1] = 20 * t + 1
    image[2:4, 3:7, 2] = 200
    return image


def test_hci_star_subset_reads_as_a_partial_9x9_grid(tmp_path, capsys):
    star = _star()
    assert star.sum() == 33
    folder = tmp_path / "antinous_star"
    folder.mkdir()
    for s, t in zip(*np.nonzero(star), strict=True):
        Image.fromarray(_view(s, t)).save(folder / f"input_Cam{9 * s + t:03d}.png")
    lf = read_lightfield(folder)
    assert lf.meta["format"] == "hci4d" and lf.grid_shape == (9, 9)
    np.testing.assert_array_equal(lf.present, star)
    for s in range(9):
        for t in range(9):
            expected = _view(s, t) if star[s, t] else np.zeros((6, 10, 3), np.uint8)
            np.testing.assert_array_equal(lf.views[s, t], expected)
    assert main(["info", str(folder)]) == 0
    assert "9 x 9 grid, 33 of 81 views present" in capsys.readouterr().out


def test_real_hci_star_subset_keeps_its_names(shared_data, tmp_path):
    source = shared_data / "hci_antinous"
    if not (source / "input_Cam040.png").is_file():
        pytest.skip("hci_antinous has no HCI 4D layout here")
    star = _star()
    folder = tmp_path / "star"
    folder.mkdir()
    for s, t in zip(*np.nonzero(star), strict=True):
        name = f"input_Cam{9 * s + t:03d}.png"
        shutil.copyfile(source / name, folder / name)
    shutil.copyfile(source / "gt_disp_lowres.pfm", folder / "gt_disp_lowres.pfm")
    lf = read_lightfield(folder)
    assert lf.grid_shape == (9, 9) and lf.num_present == 33
    np.testing.assert_array_equal(lf.present, star)
    with Image.open(source / "input_Cam072.png") as image:  # bottom-left: view (8, 0)
        np.testing.assert_array_equal(lf.views[8, 0], np.asarray(image.convert("RGB")))
    assert not lf.views[0, 1].any() and lf.center_disparity is not None


def test_grid_folder_with_holes(tmp_path):
    folder = tmp_path / "lf"
    folder.mkdir()
    present = np.ones((3, 5), dtype=bool)
    present[0, 1] = present[2, 4] = present[1, 0] = False
    for s, t in zip(*np.nonzero(present), strict=True):
        Image.fromarray(_view(s, t)).save(folder / f"lf_{s:02d}_{t:02d}.png")
    lf = read_lightfield(folder)
    np.testing.assert_array_equal(lf.present, present)
    assert not lf.views[0, 1].any()
    np.testing.assert_array_equal(lf.views[2, 3], _view(2, 3))
    (folder / "lf_01_02.png").unlink()
    with pytest.raises(LfsamError, match=r"center view lf_01_02\.png of the 3x5 grid"):
        read_lightfield(folder)


@pytest.mark.parametrize("name", ["scene", "scene.npz"])
def test_partial_round_trip_through_package_formats(tmp_path, name):
    present = _star(5)
    views = np.stack([np.stack([_view(s, t) for t in range(5)]) for s in range(5)])
    views[~present] = 0
    lf = LightField(views, present=present)
    out = write_lightfield(lf, tmp_path / name)
    if out.is_dir():
        assert len(list(out.glob("view_*.png"))) == present.sum()  # absent views: no file
    back = read_lightfield(out)
    np.testing.assert_array_equal(back.present, present)
    np.testing.assert_array_equal(back.views, views)


def test_metrics_skip_absent_views():
    scene = generate_scene(grid=(3, 3), size=(24, 32), seed=4, num_objects=2, supersample=1)
    present = np.ones((3, 3), dtype=bool)
    present[0, 0] = present[2, 1] = False
    truth = scene.labels.copy()
    zeroed = truth.copy()
    zeroed[~present] = 0
    garbage = truth.copy()
    garbage[~present] = 7
    full = evaluate_labels(truth, scene, device="cpu")
    assert full["coverage"] == 1.0
    # Without skipping, zeroed absent views would lower coverage to 7/9.
    skipped = evaluate_labels(zeroed, scene, device="cpu", present=present)
    assert skipped["coverage"] == 1.0
    other = evaluate_labels(garbage, scene, device="cpu", present=present)
    for key in ("siou", "lpp", "aa", "ue", "coverage"):
        assert skipped[key] == other[key]
    assert skipped["aa"] == 1.0 and skipped["ue"] == 0.0
    result = SegmentationResult(labels=garbage, present=present, timings={"total": 0.7})
    via_result = evaluate_result(result, scene, device="cpu")
    assert via_result["siou"] == skipped["siou"]
    assert via_result["ms_per_mask_view"] == pytest.approx(1000 * 0.7 / (3 * 7))
