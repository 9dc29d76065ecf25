"""The `synth`, `info` and `convert` commands, and one-line errors for bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from lfsam.cli.main import main
from lfsam.io import read_lightfield

SMALL = ["--grid", "3x3", "--size", "24x32", "--objects", "2"]


def _files(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def test_synth_is_deterministic_per_seed(tmp_path, capsys):
    assert main(["synth", str(tmp_path / "a"), *SMALL, "--seed", "1"]) == 0
    assert main(["synth", str(tmp_path / "b"), *SMALL, "--seed", "1"]) == 0
    assert main(["synth", str(tmp_path / "c"), *SMALL, "--seed", "2"]) == 0
    a, b, c = _files(tmp_path / "a"), _files(tmp_path / "b"), _files(tmp_path / "c")
    assert a == b
    assert a.keys() == c.keys() and a["view_01_01.png"] != c["view_01_01.png"]
    assert "wrote" in capsys.readouterr().out


def test_synth_npz_is_deterministic(tmp_path):
    for name in ("a.npz", "b.npz"):
        assert (
            main(["synth", str(tmp_path / name), *SMALL, "--seed", "4", "--disparity-range=-1,1.5"])
            == 0
        )
    assert (tmp_path / "a.npz").read_bytes() == (tmp_path / "b.npz").read_bytes()
    lf = read_lightfield(tmp_path / "a.npz")
    assert lf.grid_shape == (3, 3) and lf.view_shape == (24, 32)
    assert lf.disparity.min() >= -1.0 and lf.disparity.max() <= 1.5


def test_info_text_and_json(tmp_path, capsys):
    main(["synth", str(tmp_path / "scene"), *SMALL, "--seed", "3"])
    capsys.readouterr()
    assert main(["info", str(tmp_path / "scene")]) == 0
    text = capsys.readouterr().out
    assert "3 x 3 grid, 9 of 9 views present, center view (1, 1)" in text
    assert "24 x 32 pixels" in text
    assert "all views, 3 labels" in text
    assert "format" in text and "lfsam" in text
    assert main(["info", str(tmp_path / "scene"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["grid"] == [3, 3] and summary["view_size"] == [24, 32]
    assert summary["format"] == "lfsam" and summary["num_labels"] == 3
    assert summary["disparity"] == "all views" and len(summary["disparity_range"]) == 2


def test_info_reports_urbanlf_orientation(tmp_path, capsys):
    lf = read_lightfield(_synth(tmp_path))
    folder = tmp_path / "urban"
    folder.mkdir()
    for s in range(3):
        for t in range(3):  # stored with both view axes flipped
            Image.fromarray(lf.views[2 - s, 2 - t]).save(folder / f"{s + 1}_{t + 1}.png")
            np.save(folder / f"{s + 1}_{t + 1}_disparity.npy", lf.disparity[2 - s, 2 - t])
            np.save(folder / f"{s + 1}_{t + 1}_label.npy", lf.labels[2 - s, 2 - t] - 1)
    capsys.readouterr()
    assert main(["info", str(folder)]) == 0
    text = capsys.readouterr().out
    assert "urbanlf" in text
    assert "view rows and columns flipped; disparity as stored" in text
    assert "photo-consistency residual" in text


def _synth(tmp_path):
    out = tmp_path / "scene"
    if not out.exists():
        main(["synth", str(out), *SMALL, "--seed", "5", "--size", "40x56"])
    return out


def test_convert_grid_folder_to_npz_and_scene(tmp_path, capsys):
    lf = read_lightfield(_synth(tmp_path))
    folder = tmp_path / "views"
    folder.mkdir()
    for s in range(3):
        for t in range(3):
            Image.fromarray(lf.views[s, t]).save(folder / f"cam_{s:02d}_{t:02d}.png")
    capsys.readouterr()
    assert main(["convert", str(folder), str(tmp_path / "out.npz")]) == 0
    assert "out.npz (.npz archive): 3x3 views of 40x56 from grid" in capsys.readouterr().out
    np.testing.assert_array_equal(read_lightfield(tmp_path / "out.npz").views, lf.views)
    assert main(["convert", str(tmp_path / "out.npz"), str(tmp_path / "copy")]) == 0
    copy = read_lightfield(tmp_path / "copy")
    assert copy.meta["format"] == "lfsam"
    np.testing.assert_array_equal(copy.views, lf.views)


def test_convert_keeps_ground_truth(tmp_path):
    scene = _synth(tmp_path)
    assert main(["convert", str(scene), str(tmp_path / "gt.npz"), "--format-in", "lfsam"]) == 0
    original, converted = read_lightfield(scene), read_lightfield(tmp_path / "gt.npz")
    np.testing.assert_array_equal(converted.disparity, original.disparity)
    np.testing.assert_array_equal(converted.labels, original.labels)


# --- one-line errors ---------------------------------------------------------------------------
def _grid(tmp_path, size=(12, 16)):
    folder = tmp_path / "grid"
    folder.mkdir()
    for s in range(2):
        for t in range(2):
            Image.new("RGB", size[::-1], (40 * s, 40 * t, 90)).save(folder / f"{s}_{t}.png")
    return folder


def _missing_path(tmp_path):
    return tmp_path / "does_not_exist"


def _empty_folder(tmp_path):
    (tmp_path / "empty").mkdir()
    return tmp_path / "empty"


def _different_sizes(tmp_path):
    folder = _grid(tmp_path)
    Image.new("RGB", (20, 12)).save(folder / "1_1.png")
    return folder


def _missing_view(tmp_path):
    folder = _grid(tmp_path)
    (folder / "1_1.png").unlink()  # the center view: a partial grid needs it
    return folder


def _unreadable_image(tmp_path):
    folder = _grid(tmp_path)
    (folder / "1_0.png").write_bytes(b"this is not a png")
    return folder


def _wrong_shape(tmp_path):
    np.save(tmp_path / "lf.npy", np.zeros((2, 2, 12, 16), dtype=np.uint8))
    return tmp_path / "lf.npy"


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (_missing_path, "no such file or folder"),
        (_empty_folder, "is empty"),
        (_different_sizes, "views differ in size: 1_1.png is 12x20"),
        (_missing_view, "the center view 1_1.png of the 2x2 grid"),
        (_unreadable_image, "cannot read image"),
        (_wrong_shape, "needs shape [S, T, U, V, 3]"),
    ],
)
@pytest.mark.parametrize("command", ["info", "convert"])
def test_bad_input_gives_one_line_error(tmp_path, capsys, make, message, command):
    path = make(tmp_path)
    argv = [command, str(path)] + ([str(tmp_path / "out.npz")] if command == "convert" else [])
    assert main(argv) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("lfsam: error: ") and message in lines[0]
    assert "Traceback" not in captured.err and captured.out == ""
    assert not (tmp_path / "out.npz").exists()


def test_bad_arguments_exit_with_usage(tmp_path, capsys):
    with pytest.raises(SystemExit) as info:
        main(["synth", str(tmp_path / "x"), "--grid", "3"])
    assert info.value.code == 2
    with pytest.raises(SystemExit):
        main(["synth", str(tmp_path / "x"), "--disparity-range=2,1"])
    assert "LO < HI" in capsys.readouterr().err
    assert main(["synth", str(tmp_path / "x"), *SMALL, "--format", "npz"]) == 2
    assert "end the name in .npz" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["info", "convert", "synth"])
def test_help_teaches_with_an_example(capsys, command):
    with pytest.raises(SystemExit) as info:
        main([command, "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert "examples:" in out and f"lfsam {command} " in out
