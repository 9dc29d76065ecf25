"""Text prompts end to end (issue 26, docs/design.md section 9): `lfsam segment --text`.

With the oracle (ground-truth categories, ground-truth disparity) every answer is exact, so the
light-field logic of the text path is checked against ground truth in every view: each phrase
finds exactly the objects of its category visible in the view it runs in, and each is carried
into every other view. The tiny SAM 3 (random weights) runs the real detector's code path.
"""

from __future__ import annotations

import json
import time

import numpy as np
import pytest

from lfsam.cli.main import main
from lfsam.io import read_lightfield, write_lightfield
from lfsam.result import load_result
from lfsam.segmenters.text import phrase_matches
from lfsam.synth import generate_scene

ORACLE = ["--model", "oracle", "--disparity", "gt", "--quiet"]


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    """5x5 views of 64x96 with nine objects; seed 3 has two discs, four stars, two tiles."""
    path = tmp_path_factory.mktemp("text") / "scene"
    write_lightfield(generate_scene(grid=(5, 5), size=(64, 96), seed=3, num_objects=8), path)
    return path


@pytest.fixture(scope="module")
def scene(scene_dir):
    return read_lightfield(scene_dir)


def _labels_of(scene, phrase: str, view) -> set[int]:
    """Ground-truth labels of ``phrase``'s category visible in ``view``."""
    visible = set(np.unique(scene.labels[view]).tolist())
    return {i for i, name in scene.categories.items() if phrase_matches(phrase, name)} & visible


def _matched(result, scene) -> dict[int, int]:
    """Each result object -> the ground-truth label it covers most in its reference view."""
    out = {}
    for entry in result.meta["objects"]:
        view = tuple(entry["reference_view"])
        gt = scene.labels[view][result.labels[view] == entry["id"]]
        out[entry["id"]] = int(np.bincount(gt).argmax())
    return out


def _check_every_view(result, scene, matched: dict[int, int]) -> None:
    """Each object is its ground-truth object in every view (oracle + gt disparity: exact up to
    what its reference view cannot see, e.g. a part disoccluded in the opposite corner)."""
    for obj_id, label in matched.items():
        n = result.meta["object_ids"].index(obj_id)
        masks = result.masks.mask(n)
        for s in range(5):
            for t in range(5):
                truth = scene.labels[s, t] == label
                inter = np.count_nonzero(masks[s, t] & truth)
                union = np.count_nonzero(masks[s, t] | truth)
                assert union == 0 or inter / union > 0.9, (obj_id, label, (s, t))


def test_scene_has_discs_and_other_objects(scene):
    discs = _labels_of(scene, "disc", scene.center)
    assert len(discs) == 2
    assert len(set(np.unique(scene.labels[scene.center]).tolist()) - {0} - discs) >= 5


def test_text_disc_segments_every_disc_and_nothing_else(scene_dir, scene, tmp_path):
    out = tmp_path / "discs.npz"
    assert main(["segment", str(scene_dir), "--text", "disc", *ORACLE, "--out", str(out)]) == 0
    result = load_result(out)
    matched = _matched(result, scene)
    assert sorted(matched.values()) == sorted(_labels_of(scene, "disc", scene.center))
    _check_every_view(result, scene, matched)
    # no other object anywhere: every labelled pixel of every view is a disc's
    for s in range(5):
        for t in range(5):
            gt = scene.labels[s, t][result.labels[s, t] > 0]
            assert set(np.unique(gt).tolist()) <= set(matched.values())
    assert set(result.meta["categories"].values()) == {"disc"}
    assert all(e["mask"] == "text" and e["category"] == "disc" for e in result.meta["objects"])
    np.testing.assert_array_equal(result.scores, 1.0)  # the oracle's score is kept
    assert result.meta["text"] == [
        {"phrase": "disc", "view": [2, 2], "found": 2, "ids": [1, 2], "dropped": 0}
    ]
    # COCO: the category is the phrase
    coco_dir = tmp_path / "coco"
    assert main(["export", str(out), "--to", "coco", "--out", str(coco_dir)]) == 0
    coco = json.loads((coco_dir / "annotations.json").read_text())
    assert coco["categories"] == [{"id": 1, "name": "disc", "supercategory": "object"}]
    assert {a["category_id"] for a in coco["annotations"]} == {1}
    assert {a["track_id"] for a in coco["annotations"]} == {1, 2}


def test_phrase_in_an_outer_view(scene_dir, scene, tmp_path):
    out = tmp_path / "outer.npz"
    assert main(["segment", str(scene_dir), "--text", "star@0,0", *ORACLE, "--out", str(out)]) == 0
    result = load_result(out)
    assert all(e["reference_view"] == [0, 0] for e in result.meta["objects"])
    matched = _matched(result, scene)
    assert sorted(matched.values()) == sorted(_labels_of(scene, "star", (0, 0)))
    _check_every_view(result, scene, matched)


def test_several_phrases_mixed_with_clicks(scene_dir, scene, tmp_path):
    tile = min(_labels_of(scene, "tile", scene.center))
    rows, cols = np.nonzero(scene.labels[scene.center] == tile)
    pick = len(rows) // 2
    out = tmp_path / "mixed.npz"
    code = main(["segment", str(scene_dir), "--text", "disc", "--point",
                 f"{cols[pick]},{rows[pick]}", "--text", "stars", *ORACLE, "--out", str(out)])
    assert code == 0
    result = load_result(out)
    objects = {e["id"]: e for e in result.meta["objects"]}
    assert "points" in objects[1] and "category" not in objects[1]  # the click: id 1
    matched = _matched(result, scene)
    assert matched[1] == tile
    by_phrase = {p: {matched[i] for i, e in objects.items() if e.get("category") == p}
                 for p in ("disc", "stars")}
    assert by_phrase["disc"] == _labels_of(scene, "disc", scene.center)
    assert by_phrase["stars"] == _labels_of(scene, "star", scene.center)
    _check_every_view(result, scene, matched)
    coco = tmp_path / "coco"
    assert main(["export", str(out), "--to", "coco", "--out", str(coco)]) == 0
    names = [c["name"] for c in json.loads((coco / "annotations.json").read_text())["categories"]]
    assert names == ["disc", "stars", "object"]


def test_prompt_file_with_text(scene_dir, scene, tmp_path):
    prompts = tmp_path / "p.json"
    prompts.write_text(json.dumps([{"text": "tile", "view": [4, 4]}]))
    out = tmp_path / "file.npz"
    assert main(["segment", str(scene_dir), "--prompts", str(prompts), *ORACLE,
                 "--out", str(out)]) == 0
    result = load_result(out)
    assert set(_matched(result, scene).values()) == _labels_of(scene, "tile", (4, 4))


def test_no_instance_found_is_a_clear_empty_success(scene_dir, tmp_path, capsys):
    out = tmp_path / "none.npz"
    code = main(["segment", str(scene_dir), "--text", "cat", "--model", "oracle",
                 "--disparity", "gt", "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 0
    summary = json.loads(captured.out)
    assert summary["masks"] == 0 and summary["text"][0]["found"] == 0
    assert "no instance of 'cat' found in view 2,2" in captured.err
    result = load_result(out)
    assert result.num_masks == 0 and not result.labels.any()


def test_references_find_text_once(scene_dir, scene, tmp_path):
    out = tmp_path / "refs.npz"
    assert main(["segment", str(scene_dir), "--text", "star", "--references", "corners",
                 *ORACLE, "--out", str(out)]) == 0
    result = load_result(out)
    matched = _matched(result, scene)
    views = [(2, 2), (0, 0), (0, 4), (4, 0), (4, 4)]
    expected = set().union(*(_labels_of(scene, "star", v) for v in views))
    assert sorted(matched.values()) == sorted(expected)  # each star once
    assert sum(f["dropped"] for f in result.meta["text"]) > 0


def test_offline_without_weights_stops_at_once(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    monkeypatch.setenv("HF_HUB_CACHE", str(tmp_path / "empty-cache"))
    start = time.perf_counter()
    # the light field is not even read: the path does not exist
    code = main(["segment", str(tmp_path / "missing"), "--text", "disc",
                 "--out", str(tmp_path / "r.npz")])
    assert time.perf_counter() - start < 5
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("lfsam: error:"), err
    for part in ("request access", "https://huggingface.co/facebook/sam3", "hf auth login",
                 "--text-checkpoint DIR"):
        assert part in err[0]
    assert not (tmp_path / "r.npz").exists()


def test_tiny_sam3_runs_end_to_end(tmp_path):
    path = tmp_path / "small"
    write_lightfield(generate_scene(grid=(3, 3), size=(32, 48), seed=1, num_objects=2), path)
    out = tmp_path / "tiny.npz"
    code = main(["segment", str(path), "--text", "disc", "--model", "sam2-tiny-test",
                 "--text-model", "sam3-tiny-test", "--random-weights", "--text-threshold", "0",
                 "--disparity", "gt", "--device", "cpu", "--quiet", "--out", str(out)])
    assert code == 0
    result = load_result(out)
    found = result.meta["text"][0]["found"]
    assert found >= 1 and result.num_masks == found
    assert result.meta["text_model"]["name"] == "sam3-tiny-test"
    assert result.meta["text_model"]["random_weights"] is True
    assert set(result.meta["categories"].values()) == {"disc"}
    assert np.all((result.scores >= 0) & (result.scores <= 1))
