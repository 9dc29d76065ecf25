"""`lfsam demo`: the bundled scene segmented, scored and drawn, offline (a smaller scene here)."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

import lfsam.synth
from lfsam.cli.main import main
from lfsam.demo import choose_segmenter
from lfsam.result import load_result


@pytest.fixture
def small_demo_scene(monkeypatch):
    scene = lfsam.synth.generate_scene(grid=(3, 3), size=(48, 64), seed=0, num_objects=3)
    monkeypatch.setattr(lfsam.synth, "demo_scene", lambda: scene)
    return scene


def test_demo_writes_everything_and_reports_the_segmenter(
    small_demo_scene, tmp_path, capsys, monkeypatch
):
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    monkeypatch.setenv("HF_HUB_CACHE", str(tmp_path / "empty_cache"))
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "Segmenter: oracle" in printed and "cannot be reached" in printed
    assert "| lfsam (oracle, estimated disparity) |" in printed
    for name in ("result.npz", "metrics.md", "grid.png", "epi.png", "views.gif"):
        assert (out / name).is_file(), name
    result = load_result(out / "result.npz")
    assert result.labels.shape == small_demo_scene.labels.shape
    with Image.open(out / "views.gif") as gif:
        assert gif.n_frames == 9
    assert np.asarray(Image.open(out / "grid.png")).ndim == 3


def test_choose_segmenter_honours_a_request():
    assert choose_segmenter("oracle")[0] == "oracle"
