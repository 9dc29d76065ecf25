"""Inputs given in the wrong role (issue 38): a light-field video, a light field, a result or a
video's result folder where another kind belongs is one line naming what was given and what
the command takes (lfsam.video.io.detect.input_kind, lfsam.cli.inputs; docs/design.md section 2,
"Outputs and inputs on the command line"). And `lfsam info` never prints null."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from cli_files import make_inputs
from lfsam.cli.main import main
from lfsam.io import write_lightfield
from lfsam.lightfield import LightField
from lfsam.video.io.detect import input_kind

ORACLE = ["--model", "oracle", "--disparity", "gt"]
VIDEO = "is a light-field video"
LIGHT_FIELD = "is a light field;"
RESULT = "is a segmentation result"
VIDEO_RESULT = "is a light-field video's result folder"

# argv (names of make_inputs, TMP for the test's folder), the input named, what it is said to
# be, and what the command is said to take ({NAME}: a path of make_inputs).
CASES = [
    (["metrics", "VIDEO_NPZ", "--gt", "SCENE"], "VIDEO_NPZ", VIDEO,
     "lfsam metrics takes a result .npz or a video result folder"),
    (["metrics", "CLIP", "--gt", "SCENE"], "CLIP", VIDEO, "lfsam metrics takes a result"),
    (["metrics", "SCENE", "--gt", "SCENE"], "SCENE", LIGHT_FIELD, "lfsam metrics takes a result"),
    (["metrics", "SCENE_NPZ", "--gt", "SCENE"], "SCENE_NPZ", LIGHT_FIELD,
     "lfsam segment {SCENE_NPZ} --auto --out RESULT.npz"),
    (["metrics", "RESULT", "--gt", "RESULT"], "RESULT", RESULT,
     "lfsam metrics --gt takes a light field"),
    (["metrics", "RESULT", "--gt", "VIDEO_NPZ"], "VIDEO_NPZ", VIDEO,
     "give the light field {RESULT} was computed on (recorded: {SCENE})"),
    (["metrics", "RESULT", "--gt", "TRACKED"], "TRACKED", VIDEO_RESULT,
     "lfsam metrics --gt takes a light field"),
    (["metrics", "TRACKED", "--gt", "SCENE"], "SCENE", LIGHT_FIELD,
     "lfsam metrics --gt takes a light-field video"),
    (["export", "VIDEO_NPZ", "--to", "png", "--out", "TMP/png"], "VIDEO_NPZ", VIDEO,
     "lfsam export takes a result .npz or a video result folder"),
    (["export", "SCENE", "--to", "png", "--out", "TMP/png"], "SCENE", LIGHT_FIELD,
     "lfsam export takes a result"),
    (["export", "RESULT", "--to", "png", "--out", "TMP/png", "--lightfield", "CLIP"], "CLIP",
     VIDEO, "lfsam export --lightfield takes a light field"),
    (["export", "TRACKED", "--to", "png", "--out", "TMP/png", "--lightfield", "SCENE"], "SCENE",
     LIGHT_FIELD, "give the light-field video {TRACKED} was computed on (recorded: {CLIP})"),
    (["show", "VIDEO_NPZ", "--out", "TMP/v.png"], "VIDEO_NPZ", VIDEO,
     "lfsam show takes a result .npz, a video result folder or a light field"),
    (["show", "RESULT", "--lightfield", "CLIP", "--out", "TMP/g.png"], "CLIP", VIDEO,
     "lfsam show --lightfield takes a light field"),
    (["show", "RESULT", "--lightfield", "RESULT", "--out", "TMP/g.png"], "RESULT", RESULT,
     "lfsam show --lightfield takes a light field"),
    (["show", "RESULT", "--lightfield", "SCENE", "--compare", "SCENE_NPZ", "--out", "TMP/g.png"],
     "SCENE_NPZ", LIGHT_FIELD, "lfsam show --compare takes a result .npz"),
    (["show", "TRACKED", "--lightfield", "SCENE", "--out", "TMP/a.gif"], "SCENE", LIGHT_FIELD,
     "lfsam show --lightfield takes a light-field video"),
    (["show", "SCENE", "--lightfield", "SCENE", "--out", "TMP/g.png"], "SCENE", LIGHT_FIELD,
     "--lightfield goes with a result"),
    (["info", "RESULT"], "RESULT", RESULT, "lfsam info takes a light field"),
    (["info", "TRACKED"], "TRACKED", VIDEO_RESULT, "or a light-field video"),
    (["segment", "RESULT", "--auto", *ORACLE, "--out", "TMP/r.npz"], "RESULT", RESULT,
     "lfsam segment takes a light field"),
    (["segment", "TRACKED", "--auto", *ORACLE, "--out", "TMP/t"], "TRACKED", VIDEO_RESULT,
     "it was computed on {CLIP}"),
    (["disparity", "RESULT", "--out", "TMP/d.npy"], "RESULT", RESULT,
     "lfsam disparity takes a light field"),
    (["disparity", "VIDEO_NPZ", "--out", "TMP/d.npy"], "VIDEO_NPZ", VIDEO,
     "lfsam disparity takes a light field"),
    (["convert", "CLIP", "TMP/c.npz"], "CLIP", VIDEO, "lfsam convert takes a light field"),
    (["convert", "TRACKED", "TMP/c.npz"], "TRACKED", VIDEO_RESULT, "lfsam convert takes"),
    (["evaluate", "SCENE", *ORACLE, "--out", "TMP/run"], "SCENE", LIGHT_FIELD,
     "lfsam evaluate takes a folder of scenes"),
    (["evaluate", "CLIP", *ORACLE, "--out", "TMP/run"], "CLIP", VIDEO,
     "put it in a folder of its own"),
    (["evaluate", "TRACKED", *ORACLE, "--out", "TMP/run"], "TRACKED", VIDEO_RESULT,
     "score it with lfsam metrics"),
]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    return make_inputs(tmp_path_factory.mktemp("inputs"))


def _fill(arg: str, names: dict[str, str]) -> str:
    """``NAME`` or ``NAME/rest`` with NAME's path; any other argument as it is."""
    head, sep, tail = arg.partition("/")
    return names[head] + sep + tail if head in names else arg


@pytest.mark.parametrize(("argv", "given", "what", "takes"), CASES,
                         ids=[" ".join(case[0][:4]) for case in CASES])
def test_an_input_in_the_wrong_role_is_named_in_one_line(
    argv, given, what, takes, inputs, tmp_path, capsys
):
    names = {**{key: str(path) for key, path in inputs.items()}, "TMP": str(tmp_path)}
    assert main([_fill(arg, names) for arg in argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("lfsam: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    assert f"{names[given]} {what}" in err
    assert takes.format(**names) in err
    assert list(tmp_path.iterdir()) == []  # nothing written


@pytest.mark.parametrize("command", ["objects", "poses"])
def test_a_missing_result_is_named_not_its_light_field(command, inputs, tmp_path, capsys):
    """A RESULT that does not exist is said to be missing in one line, not taken for a result
    whose --lightfield is of the wrong kind (here a video beside a missing result)."""
    missing = tmp_path / "nothere.npz"
    assert main([command, str(missing), "--lightfield", str(inputs["CLIP"]),
                 "--json", str(tmp_path / "out.json")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("lfsam: error: ") and err.count("\n") == 1, err
    assert "not found" in err and str(missing) in err
    assert "light-field video" not in err
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_inputs_in_their_roles_still_work(inputs, tmp_path, capsys):
    assert main(["metrics", str(inputs["RESULT"]), "--gt", str(inputs["SCENE"]),
                 "--device", "cpu"]) == 0
    assert json.loads(capsys.readouterr().out)["aa"] == pytest.approx(1.0)
    assert main(["metrics", str(inputs["TRACKED"]), "--gt", str(inputs["CLIP"]),
                 "--device", "cpu"]) == 0
    assert json.loads(capsys.readouterr().out)["summary"]["identity_switches"] == 0
    for name in ("SCENE", "SCENE_NPZ", "CLIP", "VIDEO_NPZ"):
        assert main(["info", str(inputs[name])]) == 0
    out = tmp_path / "png"
    assert main(["export", str(inputs["TRACKED"]), "--to", "png", "--out", str(out),
                 "--lightfield", str(inputs["CLIP"])]) == 0


def test_input_kind_tells_the_four_kinds_apart(inputs, tmp_path):
    expected = {"SCENE": "lightfield", "SCENE_NPZ": "lightfield", "RESULT": "result",
                "CLIP": "video", "VIDEO_NPZ": "video", "TRACKED": "video-result",
                "DATASET": "video"}  # a folder of scenes reads as frames (no video marker)
    assert {name: input_kind(path) for name, path in inputs.items()} == expected
    bare = tmp_path / "labels_only.npz"
    np.savez(bare, labels=np.zeros((1, 3, 1, 6), np.int32))  # any .npz with labels: a result
    damaged = tmp_path / "damaged.npz"
    damaged.write_bytes(b"PK\x03\x04 not really")
    notes = tmp_path / "notes.txt"
    notes.write_text("hello")
    unknown = tmp_path / "unknown.npz"
    np.savez(unknown, something=np.zeros(3))
    assert input_kind(bare) == "result"
    for path in (damaged, notes, unknown, tmp_path / "missing", tmp_path / "missing.npz"):
        assert input_kind(path) is None  # the reader says what is wrong with it


def test_info_prints_no_null(tmp_path, capsys):
    """Absent fields (categories of a light field without them) print no row; --json keeps
    JSON's null."""
    lf = LightField(np.zeros((3, 3, 8, 10, 3), np.uint8))
    path = write_lightfield(lf, tmp_path / "plain.npz")
    assert main(["info", str(path)]) == 0
    text = capsys.readouterr().out
    assert not re.search(r"\bnull\b", text) and "categories" not in text
    assert re.search(r"^disparity +none$", text, re.MULTILINE)
    assert main(["info", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["categories"] is None


def test_info_shows_categories_as_names(inputs, capsys):
    assert main(["info", str(inputs["SCENE"])]) == 0
    rows = dict(line.split(None, 1) for line in capsys.readouterr().out.splitlines()
                if line.startswith("categories"))
    assert rows and "null" not in rows["categories"] and '"' not in rows["categories"]


@pytest.mark.shared_data
def test_info_of_a_shared_light_field_prints_no_null(shared_data, capsys):
    folder = shared_data / "hci_antinous"
    if not folder.is_dir():
        pytest.skip("no hci_antinous in ../shared/data")
    assert main(["info", str(folder)]) == 0
    assert not re.search(r"\bnull\b", capsys.readouterr().out)
