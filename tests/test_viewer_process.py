"""The viewer in a fresh process with a real SAM 2 architecture (issue 22).

A SAM 2 model imports ``torchvision.ops`` -> ``torch._dynamo`` -> ``triton``, whose
``libtriton`` carries its own LLVM; loaded after Mesa's software OpenGL (this virtual X display)
it crashed the process (``lfsam.viewer.native_libraries``). The in-process viewer tests cannot
show that: their pytest process has imported torch and triton long before any window exists. So
each test here starts a new Python process that opens a window first and loads the tiny SAM 2
model afterwards, as a user's session does, and checks that it lives, segments and exits 0.
Needs a display: ``make test`` runs pytest under ``xvfb-run``.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from lfsam.io import write_lightfield
from lfsam.synth import generate_scene
from napari_events import WAIT_PRELUDE

TIMEOUT_S = 240

#: What every child runs first: wait for a condition while Qt processes events (draws included).
PRELUDE = WAIT_PRELUDE + """

def click_and_wait(widget, view):
    from lfsam.viewer import layers as L
    lf = widget.session.lightfield
    u, v = lf.view_shape[0] // 2, lf.view_shape[1] // 2
    widget.layers[L.POINTS].add([[*view, u, v]])  # as a click in "add" mode does
    wait(lambda: widget.stages == ["reference", "coarse", "final"] and not widget.busy
         and not widget._segment_pending, "the click's three stages")
    return widget._prediction
"""


@pytest.fixture(scope="module")
def scene_path(tmp_path_factory) -> Path:
    """A 3x3 synthetic light field of 48x64 written as an lfsam scene folder."""
    path = tmp_path_factory.mktemp("viewer_process") / "scene"
    scene = generate_scene(grid=(3, 3), size=(48, 64), seed=0, num_objects=3)
    write_lightfield(scene, path)
    return path


def _run_child(script: str) -> dict:
    """Run ``script`` (after PRELUDE) in a fresh interpreter; its last stdout line is JSON."""
    env = {**os.environ, "PYTHONFAULTHANDLER": "1"}
    proc = subprocess.run(
        [sys.executable, "-c", PRELUDE + textwrap.dedent(script)],
        capture_output=True, text=True, timeout=TIMEOUT_S, env=env,
    )
    assert proc.returncode == 0, (
        f"child exited with {proc.returncode} (-11/139 = the segfault)\n"
        f"stdout:\n{proc.stdout[-3000:]}\nstderr:\n{proc.stderr[-6000:]}"
    )
    assert "deprecated" not in proc.stderr.lower(), proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_lfsam_view_loads_sam2_in_the_worker_and_segments_a_click(scene_path):
    """``lfsam view`` as the CLI opens it: window drawn, tiny SAM 2 loaded in the worker thread,
    one click in an outer view segmented through all three stages, clean exit."""
    out = _run_child(f"""
        from lfsam.cli.main import build_parser
        from lfsam.cli.view import open_viewer

        args = build_parser().parse_args(
            ["view", {str(scene_path)!r}, "--model", "sam2-tiny-test", "--random-weights",
             "--device", "cpu", "--disparity", "gt"])
        viewer, widget = open_viewer(args, show=True)
        wait(lambda: widget.session.loaded and not widget.busy, "the model")
        prediction = click_and_wait(widget, (0, 2))
        result = {{"model": widget.session.model, "views": list(prediction.labels.shape[:2])}}
        viewer.close()
        print(json.dumps(result))
    """)
    assert out["model"] == "sam2-tiny-test"
    assert out["views"] == [3, 3]


def test_file_open_then_plugin_widget_loads_sam2_after_the_window_is_drawn(scene_path):
    """napari started on its own: File > Open through lfsam's reader, Plugins > lfsam's dock,
    then a SAM 2 model chosen and loaded: torch and triton come in only after OpenGL is up."""
    out = _run_child(f"""
        import napari, npe2
        from importlib.resources import files

        manager = npe2.PluginManager.instance()
        manager.discover()
        if "lfsam" not in manager._manifests:
            manager.register(npe2.PluginManifest.from_file(files("lfsam.viewer") / "napari.yaml"))
        viewer = napari.Viewer(show=True)
        for _ in range(50):
            QApplication.processEvents()
        assert "triton" not in sys.modules and "torch" not in sys.modules
        viewer.open({str(scene_path)!r}, plugin="lfsam")
        _dock, widget = viewer.window.add_plugin_dock_widget("lfsam", "Segment light field")
        wait(lambda: not widget.busy, "the default model's attempt")  # offline: no weights
        widget.model_box.setCurrentText("sam2-tiny-test")
        widget.set_weights(random_weights=True)
        prediction = click_and_wait(widget, (2, 0))
        result = {{"model": widget.session.model, "views": list(prediction.labels.shape[:2]),
                   "triton": "triton" in sys.modules}}
        viewer.close()
        print(json.dumps(result))
    """)
    assert out["model"] == "sam2-tiny-test"
    assert out["views"] == [3, 3]


def test_lfsam_view_cli_stays_up_until_closed(scene_path):
    """The real command: it stays up with the model loaded (echoing the dock's status on
    stderr), shows no deprecation notice, and Ctrl-C closes it with exit status 0."""
    lfsam = Path(sys.executable).with_name("lfsam")
    proc = subprocess.Popen(
        [str(lfsam), "view", str(scene_path), "--model", "sam2-tiny-test", "--random-weights",
         "--device", "cpu", "--disparity", "gt"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "PYTHONFAULTHANDLER": "1"},
    )
    try:
        lines = []
        end = time.monotonic() + TIMEOUT_S
        while time.monotonic() < end:
            line = proc.stderr.readline()
            if not line:
                break  # the process ended
            lines.append(line)
            if "loaded" in line:
                break
        assert any("model sam2-tiny-test loaded on cpu" in line for line in lines), lines
        time.sleep(3)  # it keeps drawing with the model loaded
        assert proc.poll() is None, "".join(lines) + proc.stderr.read()
        proc.send_signal(signal.SIGINT)
        _out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    stderr = "".join(lines) + err
    assert proc.returncode == 0, stderr
    assert "deprecated" not in stderr.lower(), stderr
