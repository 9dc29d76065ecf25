"""The viewer's "Objects in 3D" dock (docs/design.md section 11): the lfsam dock's masks as
point clouds in an embedded vispy canvas, with the measures' table below.

A synthetic scene of 5x5 views of 48x64 (it carries its camera) with the oracle and the
ground-truth disparity, whose answers are exact. Needs a display: run under ``xvfb-run``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from qtpy.QtCore import QTimer

from lfsam.objects3d import objects_in_3d
from lfsam.result import SegmentationResult
from lfsam.synth import generate_scene
from lfsam.viewer import layers as L
from lfsam.viewer.objects3d_dock import ObjectsDock
from lfsam.viewer.widget import LightFieldWidget
from napari_events import register_plugin

TIMEOUT = 60_000

register_plugin()


def _scene():
    return generate_scene(grid=(5, 5), size=(48, 64), seed=0, num_objects=3)


@pytest.fixture(scope="module")
def scene():
    return _scene()


def _docks(make_napari_viewer, qtbot, lightfield, show=False, disparity="gt"):
    """The lfsam dock on ``lightfield`` (oracle) with its ground-truth labels shown as committed
    objects, and an ObjectsDock found in the viewer (no widget given, as napari makes it)."""
    viewer = make_napari_viewer(show=show)
    widget = LightFieldWidget(viewer, lightfield=lightfield, model="oracle", disparity=disparity,
                              autoload=False)
    viewer.window.add_dock_widget(widget, name="lfsam")
    widget.masks.show_labels(L.COMMITTED, lightfield.labels)
    dock = ObjectsDock(viewer)
    viewer.window.add_dock_widget(dock, name="lfsam 3D", area="right")
    assert dock.widget is widget
    return viewer, widget, dock


def test_show_in_3d_draws_every_objects_points_and_lists_them(make_napari_viewer, qtbot, scene):
    _, widget, dock = _docks(make_napari_viewer, qtbot, scene)
    labels = np.array(widget.layers[L.COMMITTED].data)
    np.testing.assert_array_equal(labels, scene.labels)
    dock.compute(block=True)
    assert dock.found is not None and dock.show_button.isEnabled()
    total = sum(len(c.xyz) for c in dock.found.clouds.values())
    assert total > 0 and dock.points_shown == total
    direct = objects_in_3d(SegmentationResult(labels=labels), scene, disparity="gt")
    assert sum(len(c.xyz) for c in direct.clouds.values()) == total
    for obj_id, cloud in direct.clouds.items():
        np.testing.assert_allclose(dock.found.clouds[obj_id].xyz, cloud.xyz)
    table = dock.table.toPlainText().splitlines()
    ids = [int(line.split()[0]) for line in table[1:]]
    assert ids == [m.object_id for m in direct.measures] == [1, 2, 3, 4]
    assert f"{len(direct.measures)} object(s), {total} points" in dock.status.text()
    dock.by_object.setChecked(True)  # each object its colour; the same points
    assert dock.points_shown == total


def test_without_camera_the_status_says_what_is_missing_and_a_camera_file_helps(
        make_napari_viewer, qtbot, tmp_path):
    lightfield = _scene()
    camera = lightfield.meta.pop("camera")
    _, _, dock = _docks(make_napari_viewer, qtbot, lightfield)
    dock.compute(block=True)
    text = dock.status.text()
    assert "focal_px" in text and "--camera" in text and "Camera…" in text
    assert dock.found is None and dock.points_shown == 0 and dock.show_button.isEnabled()
    path = tmp_path / "camera.json"
    path.write_text("{broken")
    dock.set_camera(path)  # a bad file: said, nothing changes
    assert dock.camera is None and "camera.json" in dock.status.text()
    path.write_text(json.dumps(camera))
    dock.set_camera(path)
    assert dock.camera is not None and "Show in 3D to use it" in dock.status.text()
    dock.compute(block=True)
    assert dock.found is not None and dock.points_shown > 0
    assert dock.found.camera.focal_px == camera["focal_px"]
    lonely = ObjectsDock(make_napari_viewer())  # no lfsam dock in its viewer
    assert "open the lfsam widget first" in lonely.status.text()
    lonely.compute(block=True)
    assert lonely.found is None and "open the lfsam widget first" in lonely.status.text()


def test_the_canvas_shows_the_points(make_napari_viewer, qtbot, scene):
    viewer, _, dock = _docks(make_napari_viewer, qtbot, scene, show=True)
    viewer.window._qt_window.show()
    qtbot.waitUntil(lambda: dock.canvas.native.isVisible(), timeout=TIMEOUT)
    before = dock.canvas.render()
    assert len(np.unique(before[..., :3].reshape(-1, 3), axis=0)) == 1  # nothing shown yet
    dock.compute(block=True)
    qtbot.wait(50)
    image = dock.canvas.render()
    assert image.ndim == 3 and image.shape[-1] == 4
    colours = np.unique(image[..., :3].reshape(-1, 3), axis=0)
    assert len(colours) > 10
    lit = (image[..., :3] > 0).any(-1)
    assert 0.05 < lit.mean() < 0.95  # the scene fills much of the view from the center camera


def test_the_gui_thread_runs_while_the_objects_are_computed(make_napari_viewer, qtbot, scene):
    _, widget, dock = _docks(make_napari_viewer, qtbot, scene, disparity="estimate")
    assert widget.session.disparity == "estimate"
    ticks = []
    timer = QTimer()
    timer.timeout.connect(lambda: ticks.append(1))
    timer.start(5)
    dock.compute()
    assert dock.running and not dock.show_button.isEnabled()
    assert "estimating the disparity" in dock.status.text()
    qtbot.waitUntil(lambda: not dock.running, timeout=TIMEOUT)
    timer.stop()
    assert dock.show_button.isEnabled() and dock.found is not None
    assert dock.found.disparity_source == "estimate" and dock.points_shown > 0
    assert len(ticks) >= 2  # the event loop ran meanwhile


def test_lfsam_view_and_the_plugin_menu_dock_it(make_napari_viewer, qtbot, scene, tmp_path):
    """``lfsam view`` docks it beside the lfsam dock (a scene folder keeps its camera); the
    plugin's "Objects in 3D" finds the lfsam dock of its viewer (``make_napari_viewer`` resets
    napari's command registry afterwards, where open_viewer registered the plugin's commands)."""
    from lfsam.cli.main import build_parser
    from lfsam.cli.view import open_viewer
    from lfsam.io import write_lightfield

    write_lightfield(scene, tmp_path / "scene")
    argv = ["view", str(tmp_path / "scene"), "--model", "oracle", "--disparity", "gt"]
    viewer, widget = open_viewer(build_parser().parse_args(argv), show=False)
    try:
        dock = viewer.window.dock_widgets["lfsam 3D"]
        assert isinstance(dock, ObjectsDock) and dock.widget is widget
        widget.masks.show_labels(L.COMMITTED, scene.labels)
        dock.compute(block=True)
        assert dock.found is not None and dock.points_shown > 0
    finally:
        viewer.close()
    viewer = make_napari_viewer()
    widget = LightFieldWidget(viewer, lightfield=scene, model="oracle", autoload=False)
    viewer.window.add_dock_widget(widget, name="lfsam")
    _, plugin_dock = viewer.window.add_plugin_dock_widget("lfsam", "Objects in 3D")
    assert isinstance(plugin_dock, ObjectsDock) and plugin_dock.widget is widget
