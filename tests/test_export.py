"""`lfsam export`: label PNGs, binary masks, COCO and NumPy round trips (docs/design.md section 8).

Expected values come from the synthetic scene's exact labels, never from the exporter.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image
from pycocotools import mask as mask_utils
from pycocotools.coco import COCO

import lfsam.export.png as png_module
from lfsam.cli.main import main
from lfsam.errors import LfsamError
from lfsam.export import export_result
from lfsam.export.common import view_name
from lfsam.result import SegmentationResult, load_result, save_result
from lfsam.synth import generate_scene

GRID = (3, 5)


@pytest.fixture(scope="module")
def labels() -> np.ndarray:
    """Exact per-view labels with unlabeled pixels and an id above 255 (16-bit territory)."""
    scene = generate_scene(
        grid=GRID, size=(20, 28), seed=2, num_objects=3, label_background=False, supersample=1
    )
    truth = scene.labels.copy()
    truth[truth == 2] = 300
    assert (truth == 0).any() and len(np.unique(truth)) >= 4
    return truth


@pytest.fixture
def partial() -> np.ndarray:
    present = np.zeros(GRID, dtype=bool)
    present[1, :] = True
    present[:, 2] = True
    present[0, 0] = True
    return present


def _result(labels, present=None) -> SegmentationResult:
    labels = labels.copy()
    if present is not None:
        labels[~present] = 0
    return SegmentationResult(labels=labels, meta={"input": "synthetic"}, present=present)


def _ids(labels):
    ids = np.unique(labels)
    return ids[ids != 0]


def test_view_names_sort_in_row_major_order():
    for grid in [(3, 5), (9, 9), (11, 12), (5, 101)]:
        names = [view_name(s, t, grid) for s in range(grid[0]) for t in range(grid[1])]
        assert sorted(names) == names and len(set(names)) == len(names)


def test_png_round_trip_in_file_name_order(labels, tmp_path):
    out = export_result(_result(labels), tmp_path / "png", "png")
    files = sorted(out.glob("view_*.png"))
    assert len(files) == GRID[0] * GRID[1]
    images = []
    for path in files:
        with Image.open(path) as image:
            assert image.mode.startswith("I;16")
            images.append(np.asarray(image))
    back = np.stack(images).reshape(labels.shape)
    np.testing.assert_array_equal(back, labels)
    sidecar = json.loads((out / "lfsam_export.json").read_text())
    assert sidecar["grid"] == list(GRID) and sidecar["view_size"] == [20, 28]
    assert sidecar["object_ids"] == _ids(labels).tolist()
    assert sidecar["source"] == "synthetic" and sidecar["views_present"] == 15
    assert not list(tmp_path.glob(".*"))  # no temporary folder left


def test_png_of_a_partial_grid_skips_absent_views(labels, partial, tmp_path):
    out = export_result(_result(labels, partial), tmp_path / "png", "png")
    written = sorted(p.name for p in out.glob("view_*.png"))
    expected = [view_name(s, t, GRID) for s, t in zip(*np.nonzero(partial), strict=True)]
    assert written == expected
    sidecar = json.loads((out / "lfsam_export.json").read_text())
    assert sidecar["present"] == partial.tolist() and sidecar["views_present"] == partial.sum()
    for s, t in zip(*np.nonzero(partial), strict=True):
        with Image.open(out / view_name(s, t, GRID)) as image:
            np.testing.assert_array_equal(np.asarray(image), labels[s, t])


def test_coco_loads_and_rebuilds_the_partition(labels, tmp_path):
    out = export_result(_result(labels), tmp_path / "coco", "coco")
    coco = COCO(str(out / "annotations.json"))
    ids = _ids(labels)
    assert len(coco.getImgIds()) == GRID[0] * GRID[1]
    views_per_track: dict[int, int] = {}
    for image in coco.loadImgs(coco.getImgIds()):
        s, t = image["view_row"], image["view_col"]
        assert image["file_name"] == view_name(s, t, GRID)
        assert (image["height"], image["width"]) == labels.shape[2:]
        rebuilt = np.zeros(labels.shape[2:], dtype=np.int64)
        anns = coco.loadAnns(coco.getAnnIds(imgIds=image["id"]))
        assert sorted(a["track_id"] for a in anns) == _ids(labels[s, t]).tolist()
        for ann in anns:
            mask = coco.annToMask(ann).astype(bool)
            assert not (rebuilt[mask] != 0).any()  # a partition: no overlaps
            rebuilt[mask] = ann["track_id"]
            rows, cols = np.nonzero(labels[s, t] == ann["track_id"])
            assert ann["area"] == rows.size
            assert ann["bbox"] == [cols.min(), rows.min(), np.ptp(cols) + 1, np.ptp(rows) + 1]
            assert ann["iscrowd"] == 0 and ann["category_id"] == 1
            views_per_track[ann["track_id"]] = views_per_track.get(ann["track_id"], 0) + 1
        np.testing.assert_array_equal(rebuilt, labels[s, t])
    visible = {int(i): int((labels == i).any(axis=(2, 3)).sum()) for i in ids}
    assert views_per_track == visible  # one track id per object, one annotation per view seen
    ann = coco.loadAnns(coco.getAnnIds())[0]
    assert mask_utils.decode(ann["segmentation"]).shape == labels.shape[2:]


def test_coco_of_a_partial_grid_has_no_absent_images(labels, partial, tmp_path):
    out = export_result(_result(labels, partial), tmp_path / "coco", "coco")
    coco = COCO(str(out / "annotations.json"))
    positions = {(i["view_row"], i["view_col"]) for i in coco.loadImgs(coco.getImgIds())}
    assert positions == {(int(s), int(t)) for s, t in zip(*np.nonzero(partial), strict=True)}
    assert coco.dataset["info"]["present"] == partial.tolist()


def test_masks_round_trip(labels, partial, tmp_path):
    out = export_result(_result(labels, partial), tmp_path / "masks", "masks")
    ids = _ids(labels[partial])
    folders = sorted(p.name for p in out.iterdir() if p.is_dir())
    assert folders == [f"object_{i:04d}" for i in ids]
    for object_id in ids:
        files = sorted((out / f"object_{object_id:04d}").iterdir())
        assert len(files) == partial.sum()
        for path in files:
            s, t = (int(x) for x in path.stem.split("_")[1:])
            assert partial[s, t]
            with Image.open(path) as image:
                assert image.mode == "1"
                np.testing.assert_array_equal(np.asarray(image), labels[s, t] == object_id)


def test_npy_round_trip(labels, partial, tmp_path):
    expected = labels.copy()
    expected[~partial] = 0
    out = export_result(_result(labels, partial), tmp_path / "npy", "npy")
    np.testing.assert_array_equal(np.load(out / "labels.npy"), expected)
    ids = np.load(out / "ids.npy")
    np.testing.assert_array_equal(ids, _ids(expected))
    masks = np.load(out / "masks.npy", mmap_mode="r")
    assert masks.shape == (len(ids), *labels.shape) and masks.dtype == bool
    for k, object_id in enumerate(ids):
        np.testing.assert_array_equal(masks[k], expected == object_id)
    np.testing.assert_array_equal(np.load(out / "present.npy"), partial)


def test_cli_force_and_saved_present(labels, partial, tmp_path, capsys):
    path = save_result(_result(labels, partial), tmp_path / "r.npz")
    np.testing.assert_array_equal(load_result(path).present, partial)
    out = tmp_path / "out"
    assert main(["export", str(path), "--to", "png", "--out", str(out)]) == 0
    assert "3 x 5 views (8 present)" in capsys.readouterr().out
    (out / "mine.txt").write_text("keep me")
    assert main(["export", str(path), "--to", "npy", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "not empty; pass --force" in err and len(err.strip().splitlines()) == 1
    assert (out / "mine.txt").is_file() and not (out / "labels.npy").exists()
    assert main(["export", str(path), "--to", "npy", "--out", str(out), "--force"]) == 0
    assert not (out / "mine.txt").exists() and (out / "labels.npy").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "r.npz"]


def test_failure_leaves_nothing(labels, tmp_path, monkeypatch):
    result = _result(labels)
    old = tmp_path / "old"
    export_result(result, old, "npy")
    before = sorted(p.name for p in old.iterdir())

    def broken(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(png_module.Image.Image, "save", broken)
    with pytest.raises(OSError, match="disk full"):
        export_result(result, tmp_path / "new", "png")
    with pytest.raises(OSError, match="disk full"):
        export_result(result, old, "png", force=True)
    assert sorted(p.name for p in old.iterdir()) == before  # the old export is untouched
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old"]


def test_ids_beyond_16_bits_and_bad_targets(labels, tmp_path, capsys):
    big = labels.copy()
    big[big == 300] = 70000
    with pytest.raises(LfsamError, match=r"does not fit a 16-bit PNG.*--to npy"):
        export_result(_result(big), tmp_path / "png", "png")
    assert not list(tmp_path.iterdir())
    (tmp_path / "file").write_text("x")
    with pytest.raises(LfsamError, match="is a file"):
        export_result(_result(labels), tmp_path / "file", "png")
    with pytest.raises(LfsamError, match="does not exist"):
        export_result(_result(labels), tmp_path / "no" / "out", "png")


def test_cli_checks_the_light_field_shape(labels, tmp_path, capsys):
    from lfsam.io import write_lightfield

    scene = generate_scene(grid=(3, 3), size=(20, 28), seed=1, num_objects=1, supersample=1)
    write_lightfield(scene, tmp_path / "scene")
    path = save_result(_result(labels), tmp_path / "r.npz")
    out = tmp_path / "out"
    code = main(["export", str(path), "--to", "png", "--out", str(out), "--lightfield",
                 str(tmp_path / "scene")])
    err = capsys.readouterr().err
    assert code == 2 and "labels of shape (3, 5, 20, 28)" in err and "(3, 3, 20, 28)" in err
    assert not out.exists()
