"""``lfsam render`` (issue 66): outputs other commands read, one-line errors, nothing written
on failure."""

from __future__ import annotations

import numpy as np
import pytest

from lfsam.cli.main import main
from lfsam.io import read_lightfield
from lfsam.render.output import read_flags


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    folder = tmp_path_factory.mktemp("render")
    lf_path, result = folder / "scene", folder / "result.npz"
    assert main(["synth", str(lf_path), "--grid", "3x3", "--size", "40x56", "--seed", "4",
                 "--objects", "2"]) == 0
    assert main(["segment", str(lf_path), "--auto", "--model", "oracle", "--disparity", "gt",
                 "--out", str(result)]) == 0
    return lf_path, result


def test_refocus_see_through_and_remove_write_their_outputs(scene, tmp_path):
    lf_path, result = scene
    base = ["render", str(lf_path), "--result", str(result), "--disparity", "gt"]
    assert main([*base, "--focus-on", "2", "--out", str(tmp_path / "f.png")]) == 0
    assert main([*base, "--see-through", "3", "--coverage", str(tmp_path / "c.png"),
                 "--aperture", "1", "--out", str(tmp_path / "s.png")]) == 0
    assert (tmp_path / "f.png").exists() and (tmp_path / "c.png").exists()
    for out in (tmp_path / "removed.npz", tmp_path / "removed"):
        assert main([*base, "--remove", "3", "--out", str(out)]) == 0
        removed = read_lightfield(out)
        assert removed.views.shape == read_lightfield(lf_path).views.shape
        assert read_flags(out).shape == removed.views.shape[:4]
    assert main(["info", str(tmp_path / "removed")]) == 0


def test_twin_without_an_object(tmp_path):
    out = tmp_path / "twin.npz"
    assert main(["synth", str(out), "--grid", "3x3", "--size", "40x56", "--seed", "4",
                 "--objects", "2", "--without", "3"]) == 0
    assert not (read_lightfield(out).labels == 3).any()


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--see-through", "9"], "no object 9 in"),
        (["--remove", "3", "--focus", "1"], "--remove takes none of"),
        (["--see-through", "3", "--remove", "2"], "give one of --see-through and --remove"),
    ],
)
def test_errors_are_one_line_and_write_nothing(scene, tmp_path, capsys, extra, message):
    lf_path, result = scene
    out = tmp_path / "out.png"
    code = main(["render", str(lf_path), "--result", str(result), "--disparity", "gt",
                 *extra, "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code != 0 and message in err and len(err.splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def test_a_result_of_another_light_field_is_refused(scene, tmp_path, capsys):
    _, result = scene
    other = tmp_path / "other.npz"
    assert main(["synth", str(other), "--grid", "3x3", "--size", "32x48", "--seed", "1",
                 "--objects", "1"]) == 0
    capsys.readouterr()
    code = main(["render", str(other), "--result", str(result), "--see-through", "2",
                 "--disparity", "gt", "--out", str(tmp_path / "x.png")])
    err = capsys.readouterr().err.strip()
    assert code != 0 and "give the light field the result was computed on" in err
    assert len(err.splitlines()) == 1 and not (tmp_path / "x.png").exists()


def test_a_focus_outside_the_range_is_clipped_with_a_warning(scene, tmp_path, capsys):
    lf_path, _ = scene
    assert main(["render", str(lf_path), "--focus", "40", "--disparity", "gt",
                 "--out", str(tmp_path / "f.png")]) == 0
    assert "outside the scene's disparity range" in capsys.readouterr().err
    assert np.asarray(read_lightfield(lf_path).views).any()


@pytest.mark.slow  # segmenting a video first: about 50 s on a shared 2-core CPU
def test_a_video_result_renders_every_frame(tmp_path):
    clip, result, out = tmp_path / "clip", tmp_path / "clip_result", tmp_path / "behind"
    assert main(["synth", str(clip), "--frames", "2", "--grid", "3x3", "--size", "40x56",
                 "--objects", "2"]) == 0
    assert main(["segment", str(clip), "--auto", "--model", "oracle", "--disparity", "gt",
                 "--out", str(result)]) == 0
    assert main(["render", str(clip), "--result", str(result), "--see-through", "2",
                 "--disparity", "gt", "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["frame_0000.png", "frame_0001.png"]
