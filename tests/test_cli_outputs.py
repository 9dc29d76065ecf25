"""Nothing lost (issue 38): every command that writes checks, before it reads an input or loads
a model, that it can write each of its outputs (lfsam.fileutil.check_writable; docs/design.md
section 2, "Outputs and inputs on the command line").

As root a read-only folder is still writable, so the unwritable places are a path under
``/proc`` (no file can be created there) and a path below an existing regular file.
"""

from __future__ import annotations

import importlib
import time
from pathlib import Path

import pytest

from cli_files import make_inputs
from lfsam.cli.main import main
from lfsam.errors import LfsamError
from lfsam.fileutil import check_writable

MODEL = ["--model", "sam2.1-hiera-small"]  # a real model: loading it would download weights

# Each writing command with OUT standing for a place below the unwritable folder.
COMMANDS = {
    "segment": ["segment", "SCENE", "--auto", *MODEL, "--out", "OUT/r.npz"],
    "segment video": ["segment", "CLIP", "--auto", *MODEL, "--out", "OUT/tracked"],
    "evaluate": ["evaluate", "DATASET", *MODEL, "--out", "OUT/run"],
    "export": ["export", "RESULT", "--to", "png", "--out", "OUT/png"],
    "export video": ["export", "TRACKED", "--to", "npy", "--out", "OUT/npy"],
    "disparity --out": ["disparity", "SCENE", "--out", "OUT/d.npy"],
    "disparity --confidence": ["disparity", "SCENE", "--out", "TMP/d.npy",
                               "--confidence", "OUT/c.npy"],
    "disparity --preview": ["disparity", "SCENE", "--out", "TMP/d.npy", "--preview", "OUT/p.png"],
    "convert npz": ["convert", "SCENE", "OUT/c.npz"],
    "convert folder": ["convert", "SCENE", "OUT/c"],
    "show": ["show", "RESULT", "--lightfield", "SCENE", "--out", "OUT/grid.png"],
    "show all": ["show", "RESULT", "--lightfield", "SCENE", "--out", "OUT/figures/"],
    "show light field": ["show", "SCENE", "--out", "OUT/views.gif"],
    "show video": ["show", "TRACKED", "--out", "OUT/tracks.gif"],
    "synth npz": ["synth", "OUT/s.npz", "--grid", "3x3", "--size", "24x32"],
    "synth folder": ["synth", "OUT/s", "--grid", "3x3", "--size", "24x32"],
    "synth video": ["synth", "OUT/clip", "--frames", "2", "--grid", "3x3", "--size", "24x32"],
    "demo": ["demo", "--out", "OUT/demo", *MODEL],
}

# What reads an input or loads a model; none may run before the outputs are checked.
READERS = ("read_lightfield", "read_video", "load_result", "load_video_result", "run_demo",
           "generate_scene", "generate_video", "load_segmenter", "evaluate_dataset")


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    return make_inputs(tmp_path_factory.mktemp("inputs"))


@pytest.fixture
def nothing_read(monkeypatch):
    """Every reader and model loader the commands reach fails the test if called."""
    def forbidden(*args, **kwargs):
        raise AssertionError("an input was read or a model loaded before the outputs were checked")

    modules = ["lfsam.segmenters", "lfsam.segmenters.factory", "lfsam.api", "lfsam.demo",
               "lfsam.evaluate", "lfsam.video", "lfsam.video.io.detect", "lfsam.io",
               *(f"lfsam.cli.{name}" for name in ("segment", "segment_video", "evaluate",
                                                  "export", "disparity", "convert", "show",
                                                  "show_video", "synth", "demo", "metrics"))]
    loaded = [importlib.import_module(name) for name in modules]  # all first, then patch
    for module in loaded:
        for reader in READERS:
            if hasattr(module, reader):
                monkeypatch.setattr(module, reader, forbidden)


def _unwritable(where: str, tmp_path: Path) -> Path:
    if where == "proc":
        if not Path("/proc").is_dir():
            pytest.skip("no /proc on this system")
        return Path("/proc/lfsam-test")
    blocker = tmp_path / "afile"
    blocker.write_text("a regular file, not a folder\n")
    return blocker


@pytest.mark.parametrize("where", ["proc", "below a file"])
@pytest.mark.parametrize("name", list(COMMANDS))
def test_an_unwritable_output_stops_the_command_first(
    name, where, inputs, nothing_read, tmp_path, capsys
):
    base = _unwritable(where, tmp_path)
    values = {**{key: str(path) for key, path in inputs.items()}, "TMP": str(tmp_path)}
    argv = []
    for arg in COMMANDS[name]:
        head, _, tail = arg.partition("/")
        if head == "OUT":
            arg = f"{base}/{tail}"
        elif head in values:
            arg = values[head] + (f"/{tail}" if tail else "")
        argv.append(arg)
    before = sorted(p.name for p in tmp_path.iterdir())
    start = time.perf_counter()
    assert main(argv) == 2
    assert time.perf_counter() - start < 20
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("lfsam: error: "), err
    assert "Traceback" not in err
    written = next(a for a in argv if a.startswith(str(base))).rstrip("/")
    assert written in err
    reason = "No such file or directory" if where == "proc" else "is a file, not a folder"
    assert reason in err
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing left behind


def test_check_writable_accepts_writable_places_and_leaves_nothing(tmp_path):
    assert check_writable(tmp_path / "r.npz", folder=False, option="--out") == tmp_path / "r.npz"
    check_writable(tmp_path / "export", folder=True, option="--out")
    check_writable(tmp_path, folder=True, option="--out")  # an existing folder, replaced
    check_writable(tmp_path / "a" / "b" / "run", folder=True, option="--out", inside=True)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "make, kwargs, message",
    [
        (lambda t: t, {"folder": False}, "is a folder; give a file name for --out"),
        (lambda t: t / "f", {"folder": True}, "is a file, but a folder is written there"),
        (lambda t: t / "f", {"folder": True, "inside": True}, "is a file, but a folder"),
        (lambda t: t / "no" / "r.npz", {"folder": False}, "does not exist; create it"),
        (lambda t: t / "no" / "export", {"folder": True}, "(mkdir -p "),
        (lambda t: t / "f" / "deeper" / "run", {"folder": True, "inside": True},
         "is a file, not a folder"),
    ],
)
def test_check_writable_names_the_problem(tmp_path, make, kwargs, message):
    (tmp_path / "f").write_text("x")
    with pytest.raises(LfsamError, match="--out") as info:
        check_writable(make(tmp_path), option="--out", **kwargs)
    assert message in str(info.value) and "\n" not in str(info.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f"]


def test_outputs_that_can_be_written_still_are(inputs, tmp_path, capsys):
    """The check changes nothing where the output can be written (and creates nothing)."""
    out = tmp_path / "png"
    assert main(["export", str(inputs["RESULT"]), "--to", "png", "--out", str(out)]) == 0
    assert (out / "lfsam_export.json").is_file()
    assert main(["convert", str(inputs["SCENE"]), str(tmp_path / "c.npz")]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.npz", "png"]
