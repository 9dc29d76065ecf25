"""The chunked result of a light-field video (issue 25): one file per frame, read lazily."""

from __future__ import annotations

import numpy as np
import pytest

import lfsam
from lfsam.errors import LfsamError
from lfsam.result import SegmentationResult
from lfsam.video.io.result import frame_name, load_video_result, video_result_writer


def _frames(count):
    for f in range(count):
        labels = np.zeros((3, 3, 6, 8), np.int32)
        labels[:, :, f: f + 2, 1:4] = 1 + f % 2
        yield SegmentationResult(labels=labels, meta={"frame": f})


def test_written_frame_by_frame_and_read_lazily(tmp_path):
    out = tmp_path / "out"
    with video_result_writer(out, meta={"input": "x"}) as writer:
        for result in _frames(4):
            writer.write(result)
            assert not out.exists()  # nothing at the target until the last frame is in
    video = lfsam.load_result(out)
    assert video.shape == (4, 3, 3, 6, 8) and video.labels.shape == video.shape
    assert video.object_ids == [1, 2] and video.meta == {"input": "x"}
    expected = list(_frames(4))
    for f in (3, 0, -1):
        np.testing.assert_array_equal(video.labels[f], expected[f].labels)
    assert video.frame(2).meta["frame"] == 2
    assert sorted(p.name for p in out.iterdir())[:2] == [frame_name(0), frame_name(1)]


def test_failure_leaves_nothing_and_errors(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(RuntimeError), video_result_writer(out) as writer:
        writer.write(next(_frames(1)))
        raise RuntimeError("interrupted")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(LfsamError, match=r"is a folder .* without \.npz"):
        video_result_writer(tmp_path / "r.npz").__enter__()
    (tmp_path / "file").write_text("x")
    with pytest.raises(LfsamError, match="not a video result"):
        video_result_writer(tmp_path / "file").__enter__()
    with pytest.raises(LfsamError, match="at least one frame"), video_result_writer(out):
        pass
    (tmp_path / "broken").mkdir()
    (tmp_path / "broken" / "lfsam_video_result.json").write_text("{")
    with pytest.raises(LfsamError, match="not a readable video result"):
        load_video_result(tmp_path / "broken")
    with video_result_writer(out) as writer:
        writer.write(next(_frames(1)))
    with pytest.raises(LfsamError, match="outside the result"):
        load_video_result(out).frame(1)


def test_objects_prompts_kept_in_the_manifest_and_old_folders_have_none(tmp_path):
    """Issue 38: ``meta["objects"]`` keeps each object's frame-tagged prompts (prompt-file
    format) and category; a folder written without them (before lfsam stored them) reads as
    None, one of the automatic mode as no prompted object."""
    import json

    from lfsam.prompts import BoxPrompt, ObjectPrompts, PointPrompt
    from lfsam.video.io.result import RESULT_MARKER

    objects = [
        ObjectPrompts(1, (PointPrompt(2, 3, True, (1, 1), 0), PointPrompt(4, 1, False, None, 2))),
        ObjectPrompts(2, (), BoxPrompt(1, 1, 5, 4, view=(0, 2), frame=2)),
    ]
    frames = list(_frames(3))
    frames[1].meta["categories"] = {"2": "disc"}
    with video_result_writer(tmp_path / "new", meta={"input": "x"}, objects=objects) as writer:
        for result in frames:
            writer.write(result)
    video = load_video_result(tmp_path / "new")
    assert video.stored_prompts() == objects and video.categories == {2: "disc"}
    assert video.meta["input"] == "x"
    manifest = json.loads((tmp_path / "new" / RESULT_MARKER).read_text())
    assert manifest["meta"]["objects"][0] == {  # the prompt-file format, frames on the points
        "id": 1, "points": [{"xy": [2.0, 3.0], "label": 1, "view": [1, 1], "frame": 0},
                            {"xy": [4.0, 1.0], "label": 0, "frame": 2}]}
    assert manifest["meta"]["objects"][1]["category"] == "disc"

    with video_result_writer(tmp_path / "auto", objects=[]) as writer:  # the automatic mode
        for result in _frames(3):
            writer.write(result)
    auto = load_video_result(tmp_path / "auto")
    assert auto.stored_prompts() == [] and auto.meta["objects"] == [
        {"id": 1, "mask": "automatic"}, {"id": 2, "mask": "automatic"}]

    with video_result_writer(tmp_path / "old") as writer:  # as written before issue 38
        for result in _frames(3):
            writer.write(result)
    old = load_video_result(tmp_path / "old")
    assert old.stored_prompts() is None and old.categories == {} and "objects" not in old.meta

    manifest["meta"]["objects"][0]["points"] = "nonsense"
    (tmp_path / "new" / RESULT_MARKER).write_text(json.dumps(manifest))
    with pytest.raises(LfsamError, match=r"objects stored in .* are damaged .*points"):
        load_video_result(tmp_path / "new").stored_prompts()
