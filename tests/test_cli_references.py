"""``--references`` of `lfsam segment --auto` and `lfsam evaluate` (issue 16): checked, passed on.

The generation in views other than the center is the predictor's (``generate(references=...)``);
here a spy records what reaches it and lets the center-only generation run, so these tests check
the command-line plumbing and the one-line errors.
"""

from __future__ import annotations

import numpy as np
import pytest

from lfsam.api import RunOptions, SegmentOptions, segment
from lfsam.cli.main import main
from lfsam.errors import LfsamError
from lfsam.generator import LightFieldMaskGenerator
from lfsam.io import write_lightfield
from lfsam.result import load_result
from lfsam.synth import generate_scene

MESSAGE = "--references middle: use one of center, corners, ring, all"


@pytest.fixture(scope="module")
def scene():
    return generate_scene(grid=(3, 3), size=(24, 32), seed=1, num_objects=2, supersample=1)


@pytest.fixture
def scene_path(scene, tmp_path):
    return write_lightfield(scene, tmp_path / "scene.npz")


@pytest.fixture
def spy(monkeypatch):
    calls = []
    original = LightFieldMaskGenerator.generate

    def generate(self, references=None):
        calls.append(self.references if references is None else references)
        return original(self, references="center")

    monkeypatch.setattr(LightFieldMaskGenerator, "generate", generate)
    return calls


def oracle_args(path, out):
    return ["segment", str(path), "--auto", "--model", "oracle", "--disparity", "gt",
            "--quiet", "--out", str(out)]  # fmt: skip


def test_bad_mode_is_a_one_line_error(scene_path, tmp_path, capsys):
    assert main([*oracle_args(scene_path, tmp_path / "r.npz"), "--references", "middle"]) == 2
    assert capsys.readouterr().err == f"lfsam: error: {MESSAGE}\n"
    assert not (tmp_path / "r.npz").exists()
    argv = ["evaluate", str(tmp_path), "--out", str(tmp_path / "run"), "--references", "middle"]
    assert main(argv) == 2
    assert capsys.readouterr().err == f"lfsam: error: {MESSAGE}\n"


def test_references_need_auto_and_lfsam(scene, scene_path, tmp_path, capsys):
    argv = ["segment", str(scene_path), "--point", "10,10", "--model", "oracle", "--quiet",
            "--references", "corners", "--out", str(tmp_path / "r.npz")]  # fmt: skip
    assert main(argv) == 2
    assert "--references corners needs --auto" in capsys.readouterr().err
    with pytest.raises(LfsamError, match="needs --method lfsam"):
        segment(scene, model="oracle", options=SegmentOptions(
            run=RunOptions(method="video-baseline", references="ring")))


def test_segment_passes_the_mode_to_the_predictor(scene_path, tmp_path, spy):
    assert main([*oracle_args(scene_path, tmp_path / "c.npz"), "--references", "corners"]) == 0
    assert main(oracle_args(scene_path, tmp_path / "d.npz")) == 0
    assert spy == ["corners", "center"]
    corners, default = load_result(tmp_path / "c.npz"), load_result(tmp_path / "d.npz")
    assert corners.meta["references"] == "corners" and default.meta["references"] == "center"
    # The spy generated in the center both times: the same labels.
    np.testing.assert_array_equal(corners.labels, default.labels)


def test_evaluate_passes_the_mode_and_reports_recall(scene, tmp_path, spy, capsys):
    data = tmp_path / "data"
    data.mkdir()
    write_lightfield(scene, data / "s0.npz")
    out = tmp_path / "run"
    argv = ["evaluate", str(data), "--out", str(out), "--model", "oracle", "--disparity", "gt",
            "--references", "ring", "--device", "cpu"]  # fmt: skip
    assert main(argv) == 0
    assert spy == ["ring"]
    table = (out / "table.md").read_text()
    assert "| T↓ | Recall↑ | SIoU(c)↑ |" in table
    assert "references ring" in table
    assert main([*argv[:-4], "--references", "all", "--method", "video-baseline"]) == 2
    assert "--references all needs --method lfsam" in capsys.readouterr().err
