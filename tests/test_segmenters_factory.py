"""``load_segmenter``: every backend by name, and one-line errors for what cannot be built."""

from __future__ import annotations

import time

import numpy as np
import pytest
import torch

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.segmenters import Prompts, Segmenter, available_models, load_segmenter
from lfsam.segmenters.oracle import OracleSegmenter
from lfsam.segmenters.sam2.backend import Sam2Segmenter


def test_tiny_model_by_name_is_a_random_weight_sam2_segmenter():
    seg = load_segmenter("sam2-tiny-test", device="cpu", seed=5)
    assert isinstance(seg, Sam2Segmenter) and isinstance(seg, Segmenter)
    assert seg.describe()["random_weights"] is True and seg.describe()["seed"] == 5
    assert seg.device == torch.device("cpu")


def test_checkpoint_through_the_factory_gives_the_same_answers(tmp_path):
    original = load_segmenter("sam2-tiny-test", device="cpu", seed=11)
    path = tmp_path / "tiny.pt"
    torch.save({"model": original.model.state_dict()}, path)
    loaded = load_segmenter("sam2-tiny-test", checkpoint=path, device="cpu")
    assert loaded.describe()["random_weights"] is False
    view = np.random.default_rng(0).integers(0, 256, (1, 32, 48, 3), dtype=np.uint8)
    prompts = Prompts(points=[[[10.0, 12.0]], [[30.0, 20.0]]], point_labels=[[1], [1]])
    a = original.predict(original.encode(view)[0], prompts)
    b = loaded.predict(loaded.encode(view)[0], prompts)
    assert torch.equal(a.masks, b.masks)
    torch.testing.assert_close(a.iou_predictions, b.iou_predictions)


def test_oracle_by_name():
    g = np.zeros((8, 8), np.int32)
    g[2:5, 2:5] = 1
    lf = LightField(views=np.zeros((1, 1, 8, 8, 3), np.uint8), labels=g)
    seg = load_segmenter("oracle", lightfield=lf, oracle_options={"min_area": 2}, device="cpu")
    assert isinstance(seg, OracleSegmenter) and seg.min_area == 2
    with pytest.raises(LfsamError, match="do not apply to the oracle"):
        load_segmenter("oracle", lightfield=lf, random_weights=True)
    with pytest.raises(LfsamError, match="only to --model oracle"):
        load_segmenter("sam2-tiny-test", oracle_options={"min_area": 2})


def test_unknown_model_fails_before_building():
    with pytest.raises(LfsamError, match="unknown model 'sam2-giant'"):
        load_segmenter("sam2-giant")
    assert "oracle" in available_models() and "sam2.1-hiera-small" in available_models()


def test_offline_real_model_fails_fast(tmp_path, monkeypatch):
    monkeypatch.setenv("HF_HOME", str(tmp_path))
    monkeypatch.setenv("HF_HUB_CACHE", str(tmp_path / "hub"))
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    start = time.perf_counter()
    with pytest.raises(LfsamError) as info:
        load_segmenter("sam2.1-hiera-small", device="cpu")
    assert time.perf_counter() - start < 2.0
    message = str(info.value)
    assert "\n" not in message and "--checkpoint FILE" in message
    assert list(tmp_path.iterdir()) == []
