"""``lfsam view``'s window on opening (issue 46): on a 1600 x 1000 screen the image canvas is
at least half the window's width, the window takes the screen, and the lfsam dock is in front
of the "lfsam 3D" tab. The viewer runs in a child process under an Xvfb screen of that size
(``xvfb-run``), opened as ``lfsam view`` opens it; the child also saves a screenshot."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap

import pytest

from lfsam.io import write_lightfield
from lfsam.synth import generate_scene

CHILD = """
import json, sys, time
from qtpy.QtWidgets import QApplication, QDockWidget
from lfsam.cli.main import build_parser
from lfsam.cli.view import open_viewer
from lfsam.viewer.layout import canvas_share

viewer, widget = open_viewer(build_parser().parse_args(["view", *sys.argv[2:]]), show=True)
end = time.time() + 3
while time.time() < end:
    QApplication.processEvents()
    time.sleep(0.02)
window = viewer.window._qt_window
shot = window.grab()
shot.save(sys.argv[1])
docks = {d.windowTitle(): {"width": d.width(), "seen": not d.widget().visibleRegion().isEmpty()}
         for d in window.findChildren(QDockWidget) if d.isVisible() and d.widget() is not None}
screen = QApplication.primaryScreen().availableGeometry()
print(json.dumps({"share": canvas_share(viewer), "window": [window.width(), window.height()],
                  "screen": [screen.width(), screen.height()], "docks": docks,
                  "shot": [shot.width(), shot.height()],
                  "canvas": viewer.window._qt_viewer.canvas.native.width()}))
viewer.close()
"""


@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="needs xvfb-run (make test has it)")
def test_the_canvas_is_the_largest_part_of_the_window_on_opening(tmp_path):
    scene = tmp_path / "scene"
    write_lightfield(generate_scene(grid=(3, 3), size=(240, 320), seed=0, num_objects=3), scene)
    shot = tmp_path / "viewer.png"
    proc = subprocess.run(
        ["xvfb-run", "-a", "--server-args", "-screen 0 1600x1000x24", sys.executable, "-c",
         textwrap.dedent(CHILD), str(shot), str(scene), "--model", "oracle", "--disparity",
         "gt"],
        capture_output=True, text=True, timeout=240,
        env={**os.environ, "OMP_NUM_THREADS": "1"})
    assert proc.returncode == 0, proc.stderr[-3000:]
    found = json.loads(proc.stdout.strip().splitlines()[-1])
    assert found["window"] == found["screen"] == [1600, 1000]  # sized to the screen
    assert found["share"] >= 0.5, found  # the canvas: at least half the window's width
    docks = found["docks"]
    assert docks["lfsam"]["seen"] and not docks["lfsam 3D"]["seen"], docks  # lfsam in front
    assert found["canvas"] > max(d["width"] for d in docks.values())  # the largest part
    assert found["shot"] == found["window"] and shot.stat().st_size > 10_000
