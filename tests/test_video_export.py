"""Exporting a light-field video's result (issue 25, docs/design.md section 10): label PNGs
per frame and view, and COCO with frame_index, view_row, view_col and track_id."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image
from pycocotools import mask as mask_utils
from pycocotools.coco import COCO

from lfsam.cli.main import main
from lfsam.errors import LfsamError
from lfsam.export import export_video
from lfsam.result import SegmentationResult
from lfsam.video.io.result import video_result_writer

F, S, T, U, V = 3, 2, 2, 4, 5


@pytest.fixture(scope="module")
def video_result(tmp_path_factory):
    rng = np.random.default_rng(0)
    labels = np.zeros((F, S, T, U, V), np.int32)
    labels[..., :2, :] = 3  # object 3 everywhere
    labels[0, ..., 3, 1:3] = 7  # object 7 in frames 0 and 2 (away in frame 1)
    labels[2, ..., 2:, 3:] = 7
    labels[2, 1, 1, 0, 0] = 0
    labels += rng.integers(0, 2, labels.shape).astype(np.int32) * (labels == 0) * 12
    folder = tmp_path_factory.mktemp("video") / "result"
    with video_result_writer(folder, meta={"input": "clip"}) as writer:
        for f in range(F):
            writer.write(SegmentationResult(labels=labels[f], meta={"input": "clip"}))
    return folder, labels


def test_png_frame_folders(video_result, tmp_path):
    folder, labels = video_result
    out = tmp_path / "png"
    assert main(["export", str(folder), "--to", "png", "--out", str(out)]) == 0
    names = sorted(str(p.relative_to(out)) for p in out.rglob("*.png"))
    assert names == [f"frame_{f:04d}/view_{s:02d}_{t:02d}.png"
                     for f in range(F) for s in range(S) for t in range(T)]
    for f in range(F):
        for s in range(S):
            for t in range(T):
                image = np.asarray(Image.open(out / f"frame_{f:04d}/view_{s:02d}_{t:02d}.png"))
                np.testing.assert_array_equal(image, labels[f, s, t])
    sidecar = json.loads((out / "lfsam_export.json").read_text())
    assert sidecar["frames"] == F and sidecar["object_ids"] == [3, 7, 12]
    assert sidecar["grid"] == [S, T] and sidecar["view_size"] == [U, V]


def test_coco_with_frames_views_and_tracks(video_result, tmp_path, capsys):
    folder, labels = video_result
    out = tmp_path / "coco"
    assert main(["export", str(folder), "--to", "coco", "--out", str(out)]) == 0
    assert "3 frames of 2 x 2 views" in capsys.readouterr().out
    coco = COCO(str(out / "annotations.json"))
    images = coco.dataset["images"]
    assert len(images) == F * S * T == len({i["id"] for i in images})
    assert [(i["frame_index"], i["view_row"], i["view_col"]) for i in images] == [
        (f, s, t) for f in range(F) for s in range(S) for t in range(T)]
    assert {i["file_name"] for i in images} == {
        f"frame_{f:04d}/view_{s:02d}_{t:02d}.png"
        for f in range(F) for s in range(S) for t in range(T)}
    assert len(coco.dataset["videos"]) == S * T  # one video per view, frames in time order
    for image in images:
        f, s, t = image["frame_index"], image["view_row"], image["view_col"]
        assert image["video_id"] == s * T + t + 1
        found = {a["track_id"]: a for a in coco.imgToAnns[image["id"]]}
        assert sorted(found) == sorted(set(np.unique(labels[f, s, t])) - {0})
        for track, ann in found.items():
            np.testing.assert_array_equal(mask_utils.decode(ann["segmentation"]).astype(bool),
                                          labels[f, s, t] == track)
            assert ann["area"] == (labels[f, s, t] == track).sum()
    tracks = {a["track_id"] for a in coco.dataset["annotations"]}
    assert tracks == {3, 7, 12}
    frames_of_7 = {coco.imgs[a["image_id"]]["frame_index"]
                   for a in coco.dataset["annotations"] if a["track_id"] == 7}
    assert frames_of_7 == {0, 2}


def test_nothing_written_on_failure(tmp_path):
    def frames():
        yield SegmentationResult(labels=np.zeros((S, T, U, V), np.int32))
        yield SegmentationResult(labels=np.zeros((S, T, U, V + 1), np.int32))

    with pytest.raises(LfsamError, match="frame 1 has labels"):
        export_video(frames(), tmp_path / "out", "coco")
    assert list(tmp_path.iterdir()) == []  # no partial output
