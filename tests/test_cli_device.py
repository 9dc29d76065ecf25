"""`--device`: one option, one vocabulary, for every command that computes on a device."""

from __future__ import annotations

import argparse
import importlib
import json

import numpy as np
import pytest

from lfsam.cli.main import SUBCOMMANDS, build_parser, main
from lfsam.devices import DEVICE_HELP
from lfsam.io import write_lightfield
from lfsam.synth import generate_scene

DEVICE_COMMANDS = {
    "disparity": ["disparity", "SCENE", "--out", "OUT/d.npy"],
    "segment": ["segment", "SCENE", "--auto", "--model", "oracle", "--disparity", "gt",
                "--out", "OUT/r.npz", "--quiet"],
    "metrics": ["metrics", "RESULT", "--gt", "SCENE"],
    "export": ["export", "RESULT", "--to", "ply", "--lightfield", "SCENE", "--out", "OUT/ply"],
    "objects": ["objects", "RESULT", "--lightfield", "SCENE"],
    "poses": ["poses", "RESULT", "--lightfield", "SCENE", "--views", "center"],
    "evaluate": ["evaluate", "DATASET", "--model", "oracle", "--disparity", "gt",
                 "--out", "OUT/ev"],
    "demo": ["demo", "--out", "OUT/demo", "--quiet"],
    "view": ["view", "SCENE", "--model", "oracle", "--disparity", "gt"],
    "render": ["render", "SCENE", "--result", "RESULT", "--focus", "0", "--out", "OUT/r.png"],
}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    root = tmp_path_factory.mktemp("device")
    dataset = root / "dataset"
    scene = dataset / "scene"
    dataset.mkdir()
    lightfield = generate_scene(grid=(3, 3), size=(32, 40), seed=4, num_objects=2)
    write_lightfield(lightfield, scene)
    result = root / "result.npz"
    assert main(["segment", str(scene), "--auto", "--model", "oracle", "--disparity", "gt",
                 "--out", str(result), "--quiet", "--device", "cpu"]) == 0
    return {"SCENE": str(scene), "DATASET": str(dataset), "RESULT": str(result), "root": root}


def _argv(command, files, out):
    names = {**files, "OUT": str(out)}
    return [
        "/".join(names.get(part, part) for part in word.split("/"))
        for word in DEVICE_COMMANDS[command]
    ]


def _sub_parsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def test_the_commands_with_device_share_one_option():
    parsers = _sub_parsers()
    with_device = set()
    for name, sub in parsers.items():
        options = {opt: a for a in sub._actions for opt in a.option_strings}
        if "--device" in options:
            with_device.add(name)
            action = options["--device"]
            assert action.default == "auto" and action.help == DEVICE_HELP, name
            assert action.choices is None and action.type is None, name
    assert with_device == set(DEVICE_COMMANDS)
    assert set(DEVICE_COMMANDS) <= set(SUBCOMMANDS)


def test_evaluate_view_and_demo_share_the_model_options_of_segment():
    parsers = _sub_parsers()

    def model_options(name):
        return {
            opt: (a.default, a.choices, a.help)
            for a in parsers[name]._actions
            for opt in a.option_strings
            if opt in ("--model", "--checkpoint", "--random-weights", "--device", "--amg")
        }

    assert model_options("evaluate") == model_options("segment")
    assert model_options("view") == model_options("segment")
    assert len(model_options("evaluate")) == 5
    demo, segment = model_options("demo"), model_options("segment")
    assert demo.keys() == segment.keys()
    assert demo["--model"][1] == segment["--model"][1]  # the same names are accepted
    assert demo["--device"] == segment["--device"]


@pytest.mark.parametrize("command", sorted(DEVICE_COMMANDS))
@pytest.mark.parametrize("spec", ["gpu", "cuda0"])
def test_unknown_device_is_one_line_exit_2_before_reading_input(command, spec, tmp_path, capsys):
    argv = [word.replace("SCENE", "missing").replace("RESULT", "missing.npz")
            .replace("DATASET", "missing").replace("OUT", str(tmp_path))
            for word in DEVICE_COMMANDS[command]]
    assert main([*argv, "--device", spec]) == 2
    err = capsys.readouterr().err
    assert err.splitlines() == [
        f"lfsam: error: --device {spec}: unknown device; use {DEVICE_HELP}"
    ]
    assert "Traceback" not in err and not any(tmp_path.iterdir())


@pytest.mark.parametrize("command", sorted(DEVICE_COMMANDS))
@pytest.mark.parametrize("spec", ["auto", "cpu", "CPU"])
def test_every_command_accepts_auto_and_cpu(command, spec, files, tmp_path, monkeypatch):
    module = importlib.import_module(f"lfsam.cli.{command}")
    seen = []
    monkeypatch.setattr(module, "run", lambda args: seen.append(args.device) or 0)
    assert main([*_argv(command, files, tmp_path), "--device", spec]) == 0
    assert seen == [spec]


def test_disparity_runs_with_device_auto(files, tmp_path, capsys):
    out = tmp_path / "d.npy"
    assert main(["disparity", files["SCENE"], "--out", str(out), "--device", "auto",
                 "--range=-2,2", "--no-edge-refinement"]) == 0
    disparity = np.load(out)
    assert disparity.shape == (32, 40) and np.isfinite(disparity).all()
    assert json.loads(capsys.readouterr().out)["out"] == str(out)


@pytest.mark.parametrize("spec", ["auto", "cpu"])
def test_metrics_and_evaluate_run_on_the_device_given(spec, files, tmp_path, capsys):
    assert main(["metrics", files["RESULT"], "--gt", files["SCENE"], "--device", spec]) == 0
    metrics = json.loads(capsys.readouterr().out)
    out = tmp_path / "ev"
    code = main(["evaluate", files["DATASET"], "--model", "oracle", "--disparity", "gt",
                 "--out", str(out), "--device", spec])
    assert code == 0
    scored = json.loads((out / "scene.metrics.json").read_text())
    assert scored["error"] is None
    assert scored["siou"] == pytest.approx(metrics["siou"])  # same oracle, same scene
