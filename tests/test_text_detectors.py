"""Text detectors and their data (issue 26, docs/design.md section 9): phrase matching, the
oracle's answer, the tiny SAM 3, SAM 3's weights offline, categories on disk, `--text`
parsing."""

from __future__ import annotations

import argparse
import inspect
import json

import numpy as np
import pytest

from lfsam.cli.text import parse_text
from lfsam.errors import LfsamError
from lfsam.io import read_lightfield, write_lightfield
from lfsam.lightfield import LightField
from lfsam.prompts import ObjectPrompts, TextPrompt, prompts_from_json, prompts_to_json
from lfsam.segmenters.text import (
    DEFAULT_TEXT_THRESHOLD,
    TEXT_MODELS,
    Detections,
    load_text_detector,
    phrase_matches,
)
from lfsam.segmenters.text.weights import resolve_text_weights
from lfsam.synth import generate_scene


@pytest.fixture(scope="module")
def scene():
    return generate_scene(grid=(3, 3), size=(32, 48), seed=3, num_objects=5)


@pytest.mark.parametrize(
    "phrase, category, expected",
    [("disc", "brick disc", True), ("Discs", "brick disc", True), ("brick disc", "brick disc",
     True), ("gravel disc", "brick disc", False), ("dis", "brick disc", False),
     ("glass", "glass star", True), ("", "brick disc", False)],
)
def test_phrase_matches(phrase, category, expected):
    assert phrase_matches(phrase, category) is expected


def test_detections_drop_empty_masks_and_sort_by_score():
    masks = np.zeros((3, 4, 5), bool)
    masks[0, 0, 0] = masks[2, 1, 1] = True
    found = Detections.build("x", masks, [0.2, 0.9, 0.7], (4, 5))
    assert len(found) == 2 and found.scores.tolist() == pytest.approx([0.7, 0.2])
    assert found.masks[0, 1, 1] and found.masks[1, 0, 0]
    assert len(Detections.build("x", np.zeros((0, 4, 5)), [], (4, 5))) == 0


def test_oracle_answers_every_visible_object_of_the_category(scene):
    detector = load_text_detector("oracle", lightfield=scene)
    for view in [(1, 1), (0, 0), (2, 1)]:
        labels = scene.labels[view]
        for noun in ("disc", "tile", "star", "background"):
            found = detector.detect(scene.views[view], noun, view=view)
            expected = sorted(
                i for i, name in scene.categories.items()
                if name.endswith(noun) and np.any(labels == i)
            )
            got = sorted(int(np.bincount(labels[m]).argmax()) for m in found.masks)
            assert got == expected, (view, noun)
            for mask in found.masks:
                np.testing.assert_array_equal(mask, labels == labels[mask][0])
    assert len(detector.detect(scene.center_view, "cat", view=(1, 1))) == 0


def test_oracle_needs_categories(scene):
    plain = LightField(scene.views, labels=scene.labels)
    with pytest.raises(LfsamError, match="ground-truth categories"):
        load_text_detector("oracle", lightfield=plain)


def test_tiny_sam3_detects_deterministically(scene):
    a = load_text_detector("sam3-tiny-test", random_weights=True, device="cpu")
    b = load_text_detector("sam3-tiny-test", random_weights=True, device="cpu")
    assert sum(p.numel() for p in a.model.parameters()) == TEXT_MODELS["sam3-tiny-test"].params
    everything = a.detect(scene.center_view, "red cup", threshold=0.0)
    assert len(everything) >= 1 and everything.masks.shape[1:] == (32, 48)
    assert np.all(np.diff(everything.scores) <= 0)  # best first
    again = b.detect(scene.center_view, "red cup", threshold=0.0)
    np.testing.assert_array_equal(everything.masks, again.masks)
    assert len(a.detect(scene.center_view, "red cup", threshold=1.0)) == 0
    with pytest.raises(LfsamError, match=r"in \[0, 1\]"):
        a.detect(scene.center_view, "cup", threshold=2.0)


def test_default_threshold_is_sam3_processors():
    from transformers import Sam3Processor

    signature = inspect.signature(Sam3Processor.post_process_instance_segmentation)
    assert signature.parameters["threshold"].default == DEFAULT_TEXT_THRESHOLD


def test_sam3_weights_offline_and_bad_folders(tmp_path, monkeypatch):
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    monkeypatch.setenv("HF_HUB_CACHE", str(tmp_path / "cache"))
    with pytest.raises(LfsamError) as info:
        load_text_detector("sam3")
    message = str(info.value)
    assert "\n" not in message and "hf auth login" in message and "--text-checkpoint" in message
    with pytest.raises(LfsamError, match=r"is not a folder with config\.json"):
        resolve_text_weights("sam3", tmp_path)
    with pytest.raises(LfsamError, match="--random-weights"):
        resolve_text_weights("sam3-tiny-test")
    # a cached snapshot is found without the network
    snapshot = tmp_path / "cache" / "models--facebook--sam3" / "snapshots" / "abc"
    snapshot.mkdir(parents=True)
    (snapshot / "config.json").write_text("{}")
    (snapshot / "model.safetensors").write_bytes(b"")
    refs = tmp_path / "cache" / "models--facebook--sam3" / "refs"
    refs.mkdir()
    (refs / "main").write_text("abc")
    assert resolve_text_weights("sam3") == snapshot


@pytest.mark.parametrize("suffix", ["", ".npz"])
def test_categories_round_trip(scene, tmp_path, suffix):
    assert scene.categories and all(" " in name for name in scene.categories.values())
    path = tmp_path / f"scene{suffix}"
    write_lightfield(scene, path)
    assert read_lightfield(path).categories == scene.categories


def test_categories_are_checked(scene):
    with pytest.raises(LfsamError, match="not a label id"):
        LightField(scene.views, labels=scene.labels, categories={"zero": "disc"})
    with pytest.raises(LfsamError, match="non-empty name"):
        LightField(scene.views, labels=scene.labels, categories={2: " "})
    with pytest.raises(LfsamError, match="no labels"):
        LightField(scene.views, categories={2: "disc"})
    assert LightField(scene.views, labels=scene.labels, categories={"2": "a  b"}).categories == {
        2: "a b"
    }


def test_parse_text_and_prompt_files():
    assert parse_text("red cup") == TextPrompt("red cup")
    assert parse_text("disc@0,4") == TextPrompt("disc", (0, 4))
    assert parse_text("a@b@1,2") == TextPrompt("a@b", (1, 2))
    for bad in ("", "disc@x", "@1,2"):
        with pytest.raises(argparse.ArgumentTypeError):
            parse_text(bad)
    items = prompts_from_json([{"text": " red  cup ", "view": [1, 0]}, {"points": [[3, 4]]}])
    assert items[0] == TextPrompt("red cup", (1, 0)) and isinstance(items[1], ObjectPrompts)
    assert prompts_from_json(prompts_to_json(items)) == items
    with pytest.raises(LfsamError, match="text and view only"):
        prompts_from_json([{"text": "cup", "id": 3}])
    with pytest.raises(LfsamError, match="at least one word"):
        prompts_from_json([{"text": ""}])


def test_synth_scene_json_names_shapes(scene, tmp_path):
    write_lightfield(scene, tmp_path / "s")
    description = json.loads((tmp_path / "s" / "lfsam_scene.json").read_text())
    nouns = {name.split()[-1] for name in description["categories"].values()}
    assert nouns <= {"background", "disc", "tile", "star"}
