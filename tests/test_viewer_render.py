"""The viewer's "Render" dock (docs/design.md section 13): the focus slider, "Focus on
selected", "See through selected", "Remove selected" and Save, each the same as
:mod:`lfsam.render` on the same inputs, computed off the GUI thread.

A synthetic scene of 5x5 views of 48x64 with its ground-truth labels shown as committed objects
and the ground-truth disparity (exact and instant). Needs a display: run under ``xvfb-run``.
"""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from PIL import Image
from qtpy.QtCore import QTimer

from lfsam.disparity import resolve_disparity
from lfsam.io import read_lightfield
from lfsam.render import object_focus, objects_in_front, refocus, remove_objects, see_through
from lfsam.render.output import read_flags
from lfsam.synth import generate_scene
from lfsam.viewer import controls as C
from lfsam.viewer import layers as L
from lfsam.viewer import render_jobs as J
from lfsam.viewer.render_dock import IMAGE_LAYER, REMOVED_LAYER, STEPS, RenderDock
from lfsam.viewer.widget import LightFieldWidget
from napari_events import register_plugin

TIMEOUT = 60_000

register_plugin()


@pytest.fixture(scope="module")
def scene():
    return generate_scene(grid=(5, 5), size=(48, 64), seed=3, num_objects=2)


@pytest.fixture(scope="module")
def truth(scene):
    """The center disparity, its range and the nearest object (the one in front)."""
    disparity, _ = resolve_disparity("gt", scene)
    center = scene.labels[scene.center]
    ids = [int(i) for i in np.unique(center) if i > 0]
    nearest = max(ids, key=lambda i: np.median(disparity[center == i]))
    return disparity, (float(disparity.min()), float(disparity.max())), nearest


def _docks(make_napari_viewer, scene, labels=True):
    """The lfsam dock on ``scene`` (oracle, ground-truth disparity) with its labels shown as
    committed objects and listed, and a RenderDock found in the viewer (as napari makes it)."""
    viewer = make_napari_viewer()
    widget = LightFieldWidget(viewer, lightfield=scene, model="oracle", disparity="gt",
                              autoload=False)
    viewer.window.add_dock_widget(widget, name="lfsam")
    if labels:
        widget.masks.show_labels(L.COMMITTED, scene.labels)
        ids = [int(i) for i in np.unique(scene.labels) if i > 0]
        widget.controls.show_objects(ids, current=0, auto=set())
    dock = RenderDock(viewer)
    viewer.window.add_dock_widget(dock, name="lfsam render", area="right")
    assert dock.widget is widget
    return viewer, widget, dock


def _select(widget, obj_id):
    """Select object ``obj_id`` in the lfsam dock's object list, as a click does."""
    rows = [widget.objects.item(i) for i in range(widget.objects.count())]
    widget.objects.setCurrentItem(next(row for row in rows if C.item_id(row) == obj_id))
    assert widget.controls.selected_id() == obj_id


def test_the_slider_refocuses_in_a_thread_of_its_own_once_it_stops(
        make_napari_viewer, qtbot, scene, truth, monkeypatch):
    viewer, _, dock = _docks(make_napari_viewer, scene)
    calls = []

    def slow_refocus(*args, **kwargs):  # lfsam.render.refocus, slowed, noting its thread
        calls.append(threading.current_thread())
        time.sleep(0.3)
        return refocus(*args, **kwargs)

    monkeypatch.setattr(J, "refocus", slow_refocus)
    ticks = []
    timer = QTimer()
    timer.timeout.connect(lambda: ticks.append(1))
    timer.start(5)
    for focus in (-1.0, -0.5, 0.1):  # moved thrice within the debounce: one rendering
        dock.set_focus(focus)
    qtbot.waitUntil(lambda: dock.running, timeout=TIMEOUT)
    assert not dock.through_button.isEnabled()
    qtbot.waitUntil(lambda: not dock.running, timeout=TIMEOUT)
    timer.stop()
    assert len(calls) == 1 and calls[0] is not threading.main_thread()
    assert len(ticks) >= 10  # the event loop ran while it computed
    out = dock.output
    assert out.kind == "refocus" and out.object_id is None
    assert dock.scene_range == pytest.approx(truth[1])
    step = (truth[1][1] - truth[1][0]) / STEPS
    assert abs(out.focus - 0.1) <= step and abs(dock.focus - out.focus) <= step
    expected = refocus(scene.views, out.focus, present=scene.present)
    np.testing.assert_array_equal(out.image, expected)
    np.testing.assert_array_equal(viewer.layers[IMAGE_LAYER].data, expected)
    assert f"refocused at {out.focus:+.3f} px" in dock.status.text()
    assert "disparity gt" in dock.status.text() and " s" in dock.status.text()
    assert viewer.layers.selection.active is not viewer.layers[IMAGE_LAYER]  # still the prompts'
    dock.set_focus(10.0)  # past the end: the slider stops at the scene's nearest disparity
    qtbot.waitUntil(lambda: dock.output is not out and not dock.running, timeout=TIMEOUT)
    assert dock.output.focus == pytest.approx(truth[1][1])
    assert len([layer for layer in viewer.layers if layer.name == IMAGE_LAYER]) == 1  # in place


def test_focus_on_and_see_through_the_selected_object(make_napari_viewer, qtbot, scene, truth):
    viewer, widget, dock = _docks(make_napari_viewer, scene)
    disparity, scene_range, obj = truth
    _select(widget, obj)
    dock.focus_on_selected(block=True)  # the slider moves to the object's median disparity
    out = dock.output
    mask = scene.labels[scene.center] == obj
    assert out.kind == "refocus" and out.object_id == obj
    assert out.focus == pytest.approx(object_focus(mask, disparity))
    assert abs(dock.focus - out.focus) <= (scene_range[1] - scene_range[0]) / STEPS
    np.testing.assert_array_equal(viewer.layers[IMAGE_LAYER].data,
                                  refocus(scene.views, out.focus, present=scene.present))
    assert f"object {obj}: in focus at its median disparity {out.focus:+.3f} px" in \
        dock.status.text()

    dock.see_through_selected(block=True)  # what lies behind it, its rays left out
    out = dock.output
    masks = scene.labels == obj
    front = objects_in_front(widget.masks.composite(), [obj], disparity, out.focus)
    image, coverage = see_through(scene.views, masks, disparity=disparity, occluders=front)
    assert out.kind == "see-through" and out.object_id == obj
    np.testing.assert_array_equal(viewer.layers[IMAGE_LAYER].data, image)
    np.testing.assert_array_equal(out.coverage, coverage)
    # behind the object: not the average of all rays (the object's colours left out)
    hidden = masks[scene.center] & (coverage > 0)
    plain = refocus(scene.views, out.focus, present=scene.present)
    assert hidden.sum() > 20
    assert np.abs(image - plain)[hidden].mean() > 10.0
    assert dock.slider_through.isChecked()
    assert f"object {obj}: seen through at {out.focus:+.3f} px" in dock.status.text()
    dock.set_focus(out.focus - 0.3)  # the slider sees through it at another focus
    qtbot.waitUntil(lambda: dock.output is not out and not dock.running, timeout=TIMEOUT)
    again = dock.output
    assert again.kind == "see-through" and again.object_id == obj
    front = objects_in_front(widget.masks.composite(), [obj], disparity, again.focus)
    np.testing.assert_array_equal(again.image, see_through(scene.views, masks, occluders=front,
                                                           focus=again.focus)[0])
    dock.slider_through.setChecked(False)  # unchecked: the slider refocuses
    dock.set_focus(again.focus + 0.3)
    qtbot.waitUntil(lambda: dock.output is not again and not dock.running, timeout=TIMEOUT)
    assert dock.output.kind == "refocus" and dock.output.object_id is None


def test_remove_shows_the_light_field_without_the_object_and_save_writes_it(
        make_napari_viewer, scene, truth, tmp_path):
    pytest.importorskip("cv2")
    viewer, widget, dock = _docks(make_napari_viewer, scene)
    disparity, _, obj = truth
    _select(widget, obj)
    dock.remove_selected(block=True)
    out = dock.output
    masks = scene.labels == obj
    views, unseen = remove_objects(scene.views, masks, disparity)
    layer = viewer.layers[REMOVED_LAYER]
    assert layer.data.shape == scene.views.shape and layer.rgb
    np.testing.assert_array_equal(layer.data, views)
    np.testing.assert_array_equal(out.unseen, unseen)
    changed = np.any(layer.data != scene.views, axis=-1)
    assert changed[masks].mean() > 0.5 and not changed[~masks & ~_grown(masks)].any()
    assert f"object {obj} removed" in dock.status.text()

    for target in (tmp_path / "without.npz", tmp_path / "without_scene"):
        dock.save(target, block=True)
        assert f"wrote {target}" in dock.status.text(), dock.status.text()
        back = read_lightfield(target)
        np.testing.assert_array_equal(back.views, views)
        np.testing.assert_array_equal(read_flags(target), unseen)
        assert back.meta["render"]["removed"] == [obj]

    dock.focus_on_selected(block=True)  # then an image: Save writes a PNG
    png = tmp_path / "focused.png"
    dock.save(png, block=True)
    written = np.asarray(Image.open(png).convert("RGB"))
    np.testing.assert_array_equal(written, np.round(dock.output.image).astype(np.uint8))
    assert not viewer.layers[REMOVED_LAYER].visible and viewer.layers[IMAGE_LAYER].visible


def _grown(masks):
    """``masks`` grown by two pixels in each view (removal also replaces anti-aliased edges)."""
    grown = masks.copy()
    for du in range(-2, 3):
        for dv in range(-2, 3):
            grown |= np.roll(masks, (du, dv), axis=(2, 3))
    return grown


def test_without_an_object_or_a_selection_the_status_says_so_and_nothing_is_written(
        make_napari_viewer, scene, tmp_path):
    _, widget, dock = _docks(make_napari_viewer, scene, labels=False)
    for action in (dock.focus_on_selected, dock.see_through_selected, dock.remove_selected):
        action(block=True)
        assert "no object yet" in dock.status.text() and dock.output is None
    widget.masks.show_labels(L.COMMITTED, scene.labels)
    dock.see_through_selected(block=True)
    assert "no object selected" in dock.status.text() and "objects with masks: 1, 2, 3" in \
        dock.status.text()
    assert dock.output is None and not dock.running
    target = tmp_path / "nothing.png"
    dock.save(target, block=True)
    assert "nothing to save yet" in dock.status.text() and not target.exists()
    dock.render_focus(block=True)  # a plain refocus needs no object
    assert dock.output is not None
    dock.save(tmp_path / "missing" / "refocused.png", block=True)  # a folder that is not there
    assert "missing" in dock.status.text() and not (tmp_path / "missing").exists()
    dock.save(tmp_path / "refocused.txt", block=True)  # not an image format
    assert ".png" in dock.status.text() and not list(tmp_path.iterdir())
    lonely = RenderDock(make_napari_viewer())  # no lfsam dock in its viewer
    assert "open the lfsam widget first" in lonely.status.text()
    lonely.render_focus(block=True)
    assert lonely.output is None and "open the lfsam widget first" in lonely.status.text()


def test_lfsam_view_and_the_plugin_menu_dock_it(make_napari_viewer, qtbot, scene, truth,
                                                tmp_path):
    """``lfsam view`` docks it as a tab beside the lfsam dock; the plugin's menu entry finds
    the lfsam dock of its viewer, and once shown the slider spans the scene's range."""
    from lfsam.cli.main import build_parser
    from lfsam.cli.view import open_viewer
    from lfsam.io import write_lightfield

    write_lightfield(scene, tmp_path / "scene")
    argv = ["view", str(tmp_path / "scene"), "--model", "oracle", "--disparity", "gt"]
    viewer, widget = open_viewer(build_parser().parse_args(argv), show=False)
    try:
        dock = viewer.window.dock_widgets["lfsam render"]
        assert isinstance(dock, RenderDock) and dock.widget is widget
        dock.render_focus(block=True)
        assert dock.output is not None and IMAGE_LAYER in viewer.layers
    finally:
        viewer.close()
    viewer = make_napari_viewer(show=True)
    widget = LightFieldWidget(viewer, lightfield=scene, model="oracle", disparity="gt",
                              autoload=False)
    viewer.window.add_dock_widget(widget, name="lfsam")
    _, plugin_dock = viewer.window.add_plugin_dock_widget(
        "lfsam", "Render (refocus, see through, remove)")
    assert isinstance(plugin_dock, RenderDock) and plugin_dock.widget is widget
    # shown: the slider's range is found in the work's thread
    qtbot.waitUntil(lambda: plugin_dock.scene_range is not None and not plugin_dock.running,
                    timeout=TIMEOUT)
    assert plugin_dock.scene_range == pytest.approx(truth[1]) and plugin_dock.output is None
    assert "focus slider over the scene" in plugin_dock.status.text()
