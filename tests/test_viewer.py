"""The napari viewer (issue 15): click to segment a light field, correct, save, reopen.

Driven the way a user drives it: clicks go through the points layer's mouse callbacks, keys
through the canvas's key handler, and the worker is awaited with ``qtbot.waitUntil``. The oracle
with ground-truth disparity answers exactly, so masks are checked against ground truth in every
view. Needs a display: ``make test`` runs pytest under ``xvfb-run``.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import pytest
from napari.utils._proxies import ReadOnlyWrapper  # the dev extra installs napari: no skip
from napari.utils.interactions import mouse_press_callbacks, mouse_release_callbacks
from scipy import ndimage

from lfsam.errors import LfsamError
from lfsam.synth import generate_scene
from lfsam.viewer import layers as L
from lfsam.viewer.widget import LightFieldWidget
from napari_events import MouseEvent, register_plugin

VIEW = (0, 2)  # a corner view: prompts work in any view, not just the center
OBJ, NEIGHBOUR = 3, 2  # in VIEW of the scene below, object 3 touches only object 2
TIMEOUT = 60_000


register_plugin()


@pytest.fixture(scope="module")
def scene():
    """3x3 views of 48x64, three objects, unlabelled background (exact ground truth)."""
    return generate_scene(grid=(3, 3), size=(48, 64), seed=0, num_objects=3, label_background=False)


def _interior(labels: np.ndarray, label: int) -> tuple[int, int]:
    """The pixel (row, column) of ``label`` farthest from its border."""
    dist = ndimage.distance_transform_edt(labels == label)
    return tuple(int(i) for i in np.unravel_index(dist.argmax(), dist.shape))


def _click(viewer, layer, view, pixel, modifiers=()):
    """Press and release the mouse on ``pixel`` (row, column) of ``view``, in the layer's mode."""
    viewer.dims.current_step = (*view, *viewer.dims.current_step[2:])
    position = (*view, *pixel)
    for kind, dispatch in (("mouse_press", mouse_press_callbacks),
                           ("mouse_release", mouse_release_callbacks)):
        event = MouseEvent(kind, position, list(modifiers))
        dispatch(layer, ReadOnlyWrapper(event, exceptions=("handled",)))


def _open(make_napari_viewer, qtbot, scene, **kwargs):
    viewer = make_napari_viewer()
    widget = LightFieldWidget(viewer, lightfield=scene, model="oracle", disparity="gt", **kwargs)
    viewer.window.add_dock_widget(widget)
    qtbot.waitUntil(lambda: widget.session.loaded and not widget.busy, timeout=TIMEOUT)
    return viewer, widget


def _predictor_answer(scene, prompts) -> np.ndarray:
    """The mask a predictor of its own gives these prompts (oracle, ground-truth disparity)."""
    from lfsam.predictor import LightFieldPredictor
    from lfsam.segmenters import load_segmenter

    predictor = LightFieldPredictor(load_segmenter("oracle", lightfield=scene))
    predictor.set_lightfield(scene, disparity="gt")
    predictor.set_object(prompts)
    return predictor.predict().masks[prompts.obj_id]


def _idle(qtbot, widget):
    qtbot.waitUntil(lambda: not widget.busy and not widget._segment_pending, timeout=TIMEOUT)


def test_scene_assumption(scene):
    g = scene.labels[VIEW]
    ring = ndimage.binary_dilation(g == OBJ) & (g != OBJ)
    assert set(np.unique(g[ring])) - {0} == {NEIGHBOUR}


def test_click_commit_segment_everything_reopen_labels(make_napari_viewer, qtbot, scene):
    viewer, widget = _open(make_napari_viewer, qtbot, scene)
    shown = []
    original = widget._show_current

    def spy(obj_id, **kwargs):
        original(obj_id, **kwargs)
        shown.append(widget.layers[L.CURRENT].data.reshape(9, -1).any(1).reshape(3, 3).copy())

    widget._show_current = spy
    _click(viewer, widget.layers[L.POINTS], VIEW, _interior(scene.labels[VIEW], OBJ))
    _idle(qtbot, widget)
    obj_id = widget.session.current_id
    current = widget.layers[L.CURRENT].data
    for s in range(3):
        for t in range(3):
            np.testing.assert_array_equal(current[s, t] == obj_id, scene.labels[s, t] == OBJ)
    # the clicked view's mask was shown first, alone; then every view
    assert shown[0].sum() == 1 and shown[0][VIEW]
    assert shown[-1].all()
    assert widget.stages == ["reference", "coarse", "final"]
    # commit (C key): the object moves to the committed layer, the next click is a new object
    viewer.window._qt_viewer.canvas._key_map_handler.press_key("C")
    _idle(qtbot, widget)
    np.testing.assert_array_equal(widget.layers[L.COMMITTED].data == obj_id, scene.labels == OBJ)
    assert not widget.layers[L.CURRENT].data.any() and len(widget.layers[L.POINTS].data) == 0
    assert widget.session.current_id != obj_id
    assert widget.objects.count() == 1 and str(obj_id) in widget.objects.item(0).text()
    # a box drawn in the box layer segments the next object, as the predictor does by itself
    rows, cols = np.nonzero(scene.labels[VIEW] == OBJ)
    (r0, c0), (r1, c1) = (rows.min(), cols.min()), (rows.max(), cols.max())
    box = np.array([[*VIEW, r0, c0], [*VIEW, r0, c1], [*VIEW, r1, c1], [*VIEW, r1, c0]], float)
    widget.layers[L.BOXES].add_rectangles(box)
    _idle(qtbot, widget)
    box_id = widget.session.current_id
    expected = _predictor_answer(scene, widget.session.current_prompts())
    np.testing.assert_array_equal(widget.layers[L.CURRENT].data == box_id, expected)
    np.testing.assert_array_equal(expected[VIEW], scene.labels[VIEW] == OBJ)
    # segment everything: the automatic mode finds every object of the center view
    for obj_id in list(widget.session.object_ids):
        widget.remove_object(obj_id)
    widget.segment_everything()
    _idle(qtbot, widget)
    auto = widget.layers[L.AUTO].data
    # every ground-truth object of the center view is found, exactly, in every view
    center = scene.labels[scene.center]
    assert len(widget.session.auto) == len(np.unique(center[center > 0]))
    for label in np.unique(center[center > 0]):
        (found,) = np.unique(auto[scene.center][center == label])
        assert found in widget.session.auto
        np.testing.assert_array_equal(auto == found, scene.labels == label)
    # an automatic object opens for correction: its mask becomes the current object; a click
    # gives it prompts, and undoing the click gives its automatic mask back
    (auto_id,) = np.unique(auto[VIEW][scene.labels[VIEW] == OBJ])
    widget.edit_object(int(auto_id))
    _idle(qtbot, widget)
    np.testing.assert_array_equal(widget.layers[L.CURRENT].data == auto_id, scene.labels == OBJ)
    assert not (widget.layers[L.AUTO].data == auto_id).any()
    _click(viewer, widget.layers[L.POINTS], VIEW, _interior(scene.labels[VIEW], OBJ))
    _idle(qtbot, widget)
    assert widget.session.predictor.objects[auto_id].points
    widget.undo()
    _idle(qtbot, widget)
    assert auto_id not in widget.session.predictor.objects  # a mask-given object again
    assert auto_id in widget.session.object_ids
    np.testing.assert_array_equal(widget.layers[L.CURRENT].data == auto_id, scene.labels == OBJ)
    # a labels layer (here the ground truth) reopens as editable objects (label = object id)
    for obj_id in list(widget.session.object_ids):
        widget.remove_object(obj_id)
    _idle(qtbot, widget)
    assert not widget.session.object_ids and not widget.layers[L.AUTO].data.any()
    widget.open_labels(scene.labels)
    _idle(qtbot, widget)
    ids = [int(i) for i in np.unique(scene.labels) if i]
    assert widget.session.object_ids == ids and widget.session.committed == set(ids)
    np.testing.assert_array_equal(widget.layers[L.COMMITTED].data, scene.labels)


def test_segment_everything_from_the_corners_finds_hidden_objects(make_napari_viewer, qtbot):
    """"Everything from: corners" finds the objects the center view cannot see (issue 16)."""
    from lfsam.metrics import evaluate_result

    hidden_scene = generate_scene(grid=(5, 5), size=(96, 128), seed=0, hidden_objects=2)
    recall = {}
    _viewer, widget = _open(make_napari_viewer, qtbot, hidden_scene)
    for references in ("center", "corners"):
        for obj_id in list(widget.session.object_ids):
            widget.remove_object(obj_id)
        _idle(qtbot, widget)
        widget.references_box.setCurrentText(references)
        widget.segment_everything()
        _idle(qtbot, widget)
        result = widget.session.to_result()
        np.testing.assert_array_equal(widget.layers[L.AUTO].data, result.labels)
        recall[references] = evaluate_result(result, hidden_scene, device="cpu")["recall"]
    assert recall["center"] < 1.0 and recall["corners"] == 1.0


def test_negative_click_fixes_a_merge_and_undo_redo(make_napari_viewer, qtbot, scene, tmp_path):
    viewer, widget = _open(
        make_napari_viewer, qtbot, scene, segmenter_options={"oracle_options": {"merge_prob": 1.0}}
    )
    points = widget.layers[L.POINTS]
    g = scene.labels
    _click(viewer, points, VIEW, _interior(g[VIEW], OBJ))
    _idle(qtbot, widget)
    obj_id = widget.session.current_id
    merged = widget.layers[L.CURRENT].data[VIEW] == obj_id
    np.testing.assert_array_equal(merged, (g[VIEW] == OBJ) | (g[VIEW] == NEIGHBOUR))
    # Ctrl-click adds a negative point on the wrongly merged neighbour
    _click(viewer, points, VIEW, _interior(g[VIEW], NEIGHBOUR), modifiers=["Control"])
    assert points.features["positive"].tolist() == [True, False]
    _idle(qtbot, widget)
    np.testing.assert_array_equal(widget.layers[L.CURRENT].data == obj_id, g == OBJ)
    # undo (Ctrl-Z) brings the merge back, redo (Ctrl-Shift-Z) the fix
    keys = viewer.window._qt_viewer.canvas._key_map_handler
    keys.press_key("Control-Z")
    _idle(qtbot, widget)
    assert len(points.data) == 1
    np.testing.assert_array_equal(widget.layers[L.CURRENT].data[VIEW] == obj_id, merged)
    keys.press_key("Control-Shift-Z")
    _idle(qtbot, widget)
    assert len(points.data) == 2
    np.testing.assert_array_equal(widget.layers[L.CURRENT].data == obj_id, g == OBJ)
    # Shift-C clears; clicks made while the worker runs are queued, not lost
    keys.press_key("Shift-C")
    _idle(qtbot, widget)
    assert len(points.data) == 0 and not widget.layers[L.CURRENT].data.any()
    _click(viewer, points, VIEW, _interior(g[VIEW], OBJ))
    assert widget.busy  # the first click's prediction runs in the worker thread
    keys.press_key("T")  # T: plain clicks are negative now
    _click(viewer, points, VIEW, _interior(g[VIEW], NEIGHBOUR))
    _idle(qtbot, widget)
    assert points.features["positive"].tolist() == [True, False]
    np.testing.assert_array_equal(widget.layers[L.CURRENT].data == obj_id, g == OBJ)
    # save, then reopen the result for editing through `lfsam view --result`
    out = tmp_path / "result.npz"
    widget.save(out)
    from lfsam.cli.view import open_viewer
    from lfsam.result import load_result

    result = load_result(out)
    np.testing.assert_array_equal(result.labels == obj_id, g == OBJ)
    prompts = result.meta["objects"][0]
    assert prompts["id"] == obj_id and len(prompts["points"]) == 2
    from lfsam.viewer.widget import _export_module

    if _export_module() is not None:  # the CLI's export code, where this version has it
        folder = widget.export(tmp_path / "export", "png")
        assert (folder / "view_00_02.png").is_file()
    else:
        assert not widget.export_button.isEnabled()
    scene_dir = tmp_path / "scene"
    from lfsam.io import write_lightfield

    write_lightfield(scene, scene_dir)
    args = argparse.Namespace(
        path=str(scene_dir), result=str(out), model="oracle", disparity="gt", cache=None,
        input_format=None,
    )
    viewer2, widget2 = open_viewer(args, show=False)
    try:
        _idle(qtbot, widget2)
        qtbot.waitUntil(lambda: widget2.layers[L.COMMITTED].data.any(), timeout=TIMEOUT)
        np.testing.assert_array_equal(widget2.layers[L.COMMITTED].data, result.labels)
        widget2.edit_object(obj_id)
        _idle(qtbot, widget2)
        assert len(widget2.layers[L.POINTS].data) == 2
        np.testing.assert_array_equal(widget2.layers[L.CURRENT].data == obj_id, g == OBJ)
        assert not widget2.layers[L.COMMITTED].data.any()
    finally:
        viewer2.close()


def test_jobs_yield_typed_events_and_user_errors_become_failed():
    """The worker's jobs turn the session's stages into typed events; an LfsamError in a job is
    a Failed event, not a raise (lfsam.viewer.worker)."""
    from lfsam.viewer import worker as W

    class Session:
        def segment_current(self):
            yield "reference", ((1, 2), np.eye(3, dtype=np.uint8), np.float32(0.5))
            yield "coarse", "coarse prediction"
            yield "final", "final prediction"

    events = list(W.segment_job(Session(), 7))
    assert [type(e) for e in events] == [W.ReferenceMask, W.CoarseMasks, W.FinalMasks]
    assert [e.stage for e in events] == ["reference", "coarse", "final"]
    reference = events[0]
    assert reference.obj_id == 7 and reference.view == (1, 2) and reference.score == 0.5
    assert reference.mask.dtype == bool and events[2].prediction == "final prediction"

    def failing():
        yield W.AllMasks("first")
        raise LfsamError("no weights offline")

    first, failed = W.guarded(failing)()
    assert first.prediction == "first" and failed == W.Failed("no weights offline")
    with pytest.raises(AttributeError):
        events[0].obj_id = 1  # events are frozen


def test_stale_and_failed_events(make_napari_viewer, qtbot, scene, monkeypatch):
    """The widget shows a reference mask only for the current object; a Failed event is a
    notification and drops what was queued behind it."""
    from lfsam.viewer import worker as W

    shown = []
    monkeypatch.setattr("lfsam.viewer.widget._notify_error", shown.append)
    _viewer, widget = _open(make_napari_viewer, qtbot, scene)
    current = widget.session.current_id
    mask = scene.labels[VIEW] == OBJ
    widget._on_event(W.ReferenceMask(current + 1, VIEW, mask, 0.9))  # an object left meanwhile
    assert not widget.layers[L.CURRENT].data.any() and widget.stages == []
    widget._on_event(W.ReferenceMask(current, VIEW, mask, 0.9))
    np.testing.assert_array_equal(widget.layers[L.CURRENT].data[VIEW] == current, mask)
    assert widget.layers[L.CURRENT].data.sum() == current * mask.sum()
    assert widget.stages == ["reference"] and "score 0.90" in widget.status.text()
    ran = []
    widget.work.actions.append(lambda: ran.append(True))
    widget.work.segment_pending = True
    widget.work._on_yielded(W.Failed("the model is gone"))
    assert shown == ["the model is gone"] and widget.status.text() == "the model is gone"
    assert widget.work.idle and not ran


def test_errors_are_notifications(make_napari_viewer, qtbot, monkeypatch):
    shown = []
    monkeypatch.setattr("lfsam.viewer.widget._notify_error", shown.append)
    unlabelled = generate_scene(grid=(3, 3), size=(24, 32), seed=1, num_objects=1)
    unlabelled.labels = None
    viewer = make_napari_viewer()
    widget = LightFieldWidget(viewer, lightfield=unlabelled, model="oracle", disparity="gt")
    qtbot.waitUntil(lambda: not widget.busy, timeout=TIMEOUT)
    assert len(shown) == 1 and "ground-truth labels" in shown[0] and "\n" not in shown[0]
    assert not widget.session.loaded


def test_reader_writer_layers_and_epis(make_napari_viewer, qtbot, scene, tmp_path, monkeypatch):
    import npe2

    from lfsam.io import write_lightfield
    from lfsam.result import load_result
    from lfsam.viewer.plugin_io import get_reader

    viewer = make_napari_viewer()
    assert "lfsam" in npe2.PluginManager.instance()._manifests
    path = tmp_path / "scene.npz"
    write_lightfield(scene, path)
    layers = viewer.open(str(path), plugin="lfsam")
    image = layers[0]
    assert image.rgb and image.data.shape == (3, 3, 48, 64, 3)
    np.testing.assert_array_equal(image.data, scene.views)
    lightfield = image.metadata["lfsam_lightfield"]
    assert image.data is lightfield.views  # the layer shows the views themselves, no copy
    assert layers[1].data.shape == (3, 3, 48, 64) and not layers[1].visible  # ground truth
    # writer: a labels layer as a result, and the reader opens results
    out = tmp_path / "labels.npz"
    layers[1].save(str(out), plugin="lfsam")
    np.testing.assert_array_equal(load_result(out).labels, scene.labels)
    (reread,) = viewer.open(str(out), plugin="lfsam")
    np.testing.assert_array_equal(reread.data, scene.labels)
    assert reread.metadata["lfsam_result"].labels.shape == (3, 3, 48, 64)
    # an unreadable file: a notification with lfsam's one-line message, no layer, no raise
    shown = []
    monkeypatch.setattr("napari.utils.notifications.show_error", shown.append)
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    reader = get_reader(str(bad))
    assert reader(str(bad)) == [] and len(shown) == 1 and "\n" not in shown[0]
    assert get_reader(str(tmp_path / "missing.npz")) is None
    # the dock widget (as from the Plugins menu) adopts the light field already open
    widget = LightFieldWidget(viewer, autoload=False)
    assert widget.image_layer is image and widget.session.lightfield is lightfield
    assert viewer.dims.ndim == 4 and viewer.dims.displayed == (2, 3)
    assert viewer.dims.current_step[:2] == scene.center
    for name in (L.CURRENT, L.COMMITTED, L.AUTO):
        assert viewer.layers[name].data.shape == (3, 3, 48, 64)
    assert viewer.layers[L.POINTS].ndim == viewer.layers[L.BOXES].ndim == 4
    # a deleted fixed layer comes back, in its place
    index = viewer.layers.index(L.COMMITTED)
    viewer.layers.remove(L.COMMITTED)
    qtbot.waitUntil(lambda: L.COMMITTED in viewer.layers, timeout=5000)
    assert viewer.layers.index(L.COMMITTED) == index
    # EPIs: a reorder of the same data's axes
    viewer.dims.current_step = (1, 1, 20, 30)
    widget.show_display("epi-row")
    assert viewer.dims.displayed == (1, 3)  # (t, v) through pixel row u=20 of view row s=1
    np.testing.assert_array_equal(image._slice.image.raw, scene.views[1, :, 20, :])
    widget.show_display("epi-column")
    assert viewer.dims.displayed == (2, 0)  # (u, s) through pixel column v=30 of view column 1
    np.testing.assert_array_equal(image._slice.image.raw, scene.views[:, 1, :, 30].swapaxes(0, 1))
    widget.show_display("views")
    assert viewer.dims.displayed == (2, 3)


def test_view_help_and_the_message_without_the_extra(capsys, monkeypatch):
    from lfsam.cli.main import main

    with pytest.raises(SystemExit) as exit_info:
        main(["view", "--help"])
    assert exit_info.value.code == 0
    assert "lfsam view scene" in capsys.readouterr().out
    monkeypatch.setitem(sys.modules, "napari", None)  # as if napari were not installed
    assert main(["view", "scene"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "pip install 'lfsam[viewer]'" in err
    from lfsam.viewer import require_napari

    with pytest.raises(LfsamError, match=r"lfsam\[viewer\]"):
        require_napari()


# --- the transformers backend in the dock (EdgeTAM; docs/design.md section 3.8) --------------
EDGETAM = "edgetam-tiny-test"


@pytest.fixture(scope="module")
def edgetam_folder(tmp_path_factory):
    """A tiny EdgeTAM in transformers format (``save_pretrained``), as a real checkpoint is:
    the image and prompt positional embeddings equal."""
    import torch
    from transformers import EdgeTamModel

    from lfsam.segmenters.transformers.build import tiny_edgetam_config

    torch.manual_seed(0)
    model = EdgeTamModel(tiny_edgetam_config())
    with torch.no_grad():
        shared = model.shared_image_embedding.positional_embedding
        model.prompt_encoder.shared_embedding.positional_embedding.copy_(shared)
    folder = tmp_path_factory.mktemp("edgetam-hf") / "edgetam-tiny-hf"
    model.save_pretrained(folder)
    return folder


def _choose_weights(widget, text):
    """Choose ``text`` in the weights box as a user does: the current item changes, then the
    box emits ``activated`` with its index."""
    box = widget.weights_box
    index = box.findText(text)
    assert index >= 0, text
    box.setCurrentIndex(index)
    box.activated.emit(index)


def _click_center_segments(qtbot, viewer, widget, scene):
    """A click on an object of the center view gives the current object a mask there."""
    center = scene.center
    _click(viewer, widget.layers[L.POINTS], center, _interior(scene.labels[center], OBJ))
    _idle(qtbot, widget)
    obj_id = widget.session.current_id
    assert widget.stages == ["reference", "coarse", "final"]
    assert (widget.layers[L.CURRENT].data[center] == obj_id).any()
    assert widget.objects.count() == 1 and str(obj_id) in widget.objects.item(0).text()


def test_edgetam_model_segments_a_click(make_napari_viewer, qtbot, scene, monkeypatch):
    """The model box on the tiny EdgeTAM (random weights): a click segments an object."""
    from lfsam.segmenters.transformers.backend import TransformersSegmenter

    shown = []
    monkeypatch.setattr("lfsam.viewer.widget._notify_error", shown.append)
    viewer = make_napari_viewer()
    widget = LightFieldWidget(viewer, lightfield=scene, model=EDGETAM, disparity="gt",
                              segmenter_options={"random_weights": True, "device": "cpu"})
    viewer.window.add_dock_widget(widget)
    qtbot.waitUntil(lambda: widget.session.loaded and not widget.busy, timeout=TIMEOUT)
    assert widget.model_box.currentText() == EDGETAM and widget.weights_box.isEnabled()
    segmenter = widget.session.predictor.segmenter
    assert isinstance(segmenter, TransformersSegmenter)
    assert segmenter.info["name"] == EDGETAM and segmenter.info["random_weights"]
    _click_center_segments(qtbot, viewer, widget, scene)
    assert shown == []


def test_weights_folder_item_loads_a_transformers_folder(
    make_napari_viewer, qtbot, scene, edgetam_folder, monkeypatch
):
    """"folder…" in the weights box asks for a folder; with the model "transformers" the
    session's segmenter is then the transformers backend on that folder, and clicks segment."""
    from lfsam.segmenters.registry import TRANSFORMERS_FOLDER
    from lfsam.segmenters.transformers.backend import TransformersSegmenter
    from lfsam.viewer import controls as C

    asked = []

    def ask_open_folder(parent, title):
        asked.append(title)
        return str(edgetam_folder)

    monkeypatch.setattr("lfsam.viewer.controls.ask_open_folder", ask_open_folder)

    def ask_open_file(*args):
        raise AssertionError("folder… asked for a file")

    monkeypatch.setattr("lfsam.viewer.controls.ask_open_file", ask_open_file)
    shown = []
    monkeypatch.setattr("lfsam.viewer.widget._notify_error", shown.append)
    viewer, widget = _open(make_napari_viewer, qtbot, scene, segmenter_options={"device": "cpu"})
    assert not widget.weights_box.isEnabled()  # the oracle has no weights
    widget.model_box.setCurrentText(TRANSFORMERS_FOLDER)
    _idle(qtbot, widget)
    assert widget.weights_box.isEnabled() and widget.session.model == TRANSFORMERS_FOLDER
    shown.clear()  # the model without a folder yet may say so; choosing one must not fail
    box = widget.weights_box
    assert box.findText(C.FOLDER_ITEM) == box.count() - 1
    _choose_weights(widget, C.FOLDER_ITEM)
    _idle(qtbot, widget)
    assert len(asked) == 1
    assert box.currentText() == str(edgetam_folder)
    assert [box.itemText(i) for i in range(box.count())][-2:] == [C.FILE_ITEM, C.FOLDER_ITEM]
    segmenter = widget.session.predictor.segmenter
    assert isinstance(segmenter, TransformersSegmenter)
    assert segmenter.info["checkpoint"] == str(edgetam_folder)
    assert segmenter.info["model_type"] == "edgetam" and not segmenter.info["random_weights"]
    assert widget.session.model == TRANSFORMERS_FOLDER
    _click_center_segments(qtbot, viewer, widget, scene)
    # a cancelled dialog keeps the folder in use
    monkeypatch.setattr("lfsam.viewer.controls.ask_open_folder", lambda parent, title: None)
    _choose_weights(widget, C.FOLDER_ITEM)
    _idle(qtbot, widget)
    assert box.currentText() == str(edgetam_folder)
    assert widget.session.predictor.segmenter is segmenter  # nothing reloaded
    assert shown == []


def test_view_with_a_checkpoint_folder_shows_transformers(
    make_napari_viewer, qtbot, scene, edgetam_folder, tmp_path
):
    """`lfsam view SCENE --checkpoint FOLDER` (no --model): the model box shows
    "transformers", the weights box the folder, and the folder's model is loaded.
    (``make_napari_viewer`` resets napari's command registry afterwards, where open_viewer
    registered the plugin's commands.)"""
    from lfsam.cli.main import build_parser
    from lfsam.cli.view import open_viewer
    from lfsam.io import write_lightfield
    from lfsam.segmenters.registry import TRANSFORMERS_FOLDER
    from lfsam.segmenters.transformers.backend import TransformersSegmenter

    scene_dir = tmp_path / "scene"
    write_lightfield(scene, scene_dir)
    args = build_parser().parse_args(["view", str(scene_dir), "--checkpoint", str(edgetam_folder),
                                      "--disparity", "gt", "--device", "cpu"])
    viewer, widget = open_viewer(args, show=False)
    try:
        assert widget.model_box.currentText() == TRANSFORMERS_FOLDER
        assert widget.weights_box.currentText() == str(edgetam_folder)
        assert widget.weights_box.isEnabled()
        qtbot.waitUntil(lambda: widget.session.loaded and not widget.busy, timeout=TIMEOUT)
        segmenter = widget.session.predictor.segmenter
        assert isinstance(segmenter, TransformersSegmenter)
        assert segmenter.info["checkpoint"] == str(edgetam_folder)
        assert widget.model_box.currentText() == TRANSFORMERS_FOLDER
        assert widget.weights_box.currentText() == str(edgetam_folder)
    finally:
        viewer.close()
