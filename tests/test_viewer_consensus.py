"""The viewer's "Consensus" switch (issue 36, docs/design.md section 3.9): the dock's checkbox,
``LightFieldWidget(consensus=...)`` and ``lfsam view --consensus``; toggling it refines the
objects again in the worker, and every pipeline the viewer builds (a light field's predictor, a
video's track, a live stream's tracker) carries it.

A tiny scene (3x3 views of 32x40) with the oracle, ground-truth disparity and jittered
boundaries (``boundary_jitter=1``: each view's answer is a little wrong in its own way, so the
vote changes something). Needs a display: run under ``xvfb-run``.
"""

from __future__ import annotations

import numpy as np
import pytest
from napari.utils._proxies import ReadOnlyWrapper
from napari.utils.interactions import mouse_press_callbacks, mouse_release_callbacks
from scipy import ndimage

import lfsam
from lfsam.api import ModelOptions, RunOptions, SegmentOptions
from lfsam.pipeline import PipelineConfig
from lfsam.synth import generate_scene
from lfsam.viewer import layers as L
from lfsam.viewer.widget import LightFieldWidget
from napari_events import MouseEvent, register_plugin

TIMEOUT = 60_000
JITTER = {"boundary_jitter": 1}
CLICKS = ((2, (0, 2)), (5, (1, 1)))  # (ground-truth label, view clicked)

register_plugin()


@pytest.fixture(scope="module")
def scene():
    return generate_scene(grid=(3, 3), size=(32, 40), seed=1)


def _interior(labels: np.ndarray, label: int) -> tuple[int, int]:
    dist = ndimage.distance_transform_edt(labels == label)
    return tuple(int(i) for i in np.unravel_index(dist.argmax(), dist.shape))


def _click(viewer, layer, view, pixel):
    viewer.dims.current_step = (*view, *viewer.dims.current_step[2:])
    for kind, dispatch in (("mouse_press", mouse_press_callbacks),
                           ("mouse_release", mouse_release_callbacks)):
        event = MouseEvent(kind, (*view, *pixel), [])
        dispatch(layer, ReadOnlyWrapper(event, exceptions=("handled",)))


def _idle(qtbot, widget):
    qtbot.waitUntil(lambda: not widget.busy and not widget._segment_pending, timeout=TIMEOUT)


def _open(make_napari_viewer, qtbot, scene, **kwargs):
    viewer = make_napari_viewer()
    widget = LightFieldWidget(viewer, lightfield=scene, model="oracle", disparity="gt",
                              segmenter_options={"oracle_options": dict(JITTER)}, **kwargs)
    viewer.window.add_dock_widget(widget)
    qtbot.waitUntil(lambda: widget.session.loaded and not widget.busy, timeout=TIMEOUT)
    return viewer, widget


def _segment(scene, prompts, consensus: bool) -> np.ndarray:
    """What ``lfsam.segment`` gives these prompts with the same oracle."""
    options = SegmentOptions(pipeline=PipelineConfig(consensus=consensus),
                             model=ModelOptions(name="oracle", oracle=dict(JITTER)),
                             run=RunOptions(progress=False))
    return lfsam.segment(scene, prompts, disparity="gt", options=options).labels


@pytest.mark.parametrize("on", [False, True])
def test_the_checkbox_shows_the_constructor_setting(make_napari_viewer, qtbot, scene, on):
    _, widget = _open(make_napari_viewer, qtbot, scene, consensus=on)
    box = widget.controls.consensus_box
    assert box.isChecked() is on and widget.controls.consensus is on
    assert "outvoted" in box.toolTip()
    assert widget.session.consensus is on and widget.session.predictor.config.consensus is on
    assert widget.follow._tracker(auto=False).options.pipeline.consensus is on  # a live stream


def test_toggling_refines_the_objects_as_lfsam_segment_does(make_napari_viewer, qtbot, scene):
    viewer, widget = _open(make_napari_viewer, qtbot, scene)
    statuses: list[str] = []
    widget.status_changed.connect(statuses.append)
    for label, view in CLICKS:
        _click(viewer, widget.layers[L.POINTS], view, _interior(scene.labels[view], label))
        _idle(qtbot, widget)
        widget.commit()
        _idle(qtbot, widget)
    session = widget.session
    prompts = [session.predictor.objects[i] for i in session.object_ids]
    assert len(prompts) == len(CLICKS) and session.committed == set(session.object_ids)
    plain = _segment(scene, prompts, consensus=False)
    voted = _segment(scene, prompts, consensus=True)
    assert (plain != voted).any()  # the vote changes the jittered answers
    committed = widget.layers[L.COMMITTED]
    np.testing.assert_array_equal(committed.data, plain)

    widget.controls.consensus_box.click()  # the user's toggle
    assert widget.controls.consensus and session.consensus
    _idle(qtbot, widget)
    assert session.predictor.config.consensus
    assert any("refining with consensus" in line for line in statuses)
    np.testing.assert_array_equal(committed.data, voted)
    assert widget.session.to_result().meta["consensus_replaced"] >= 0  # the vote ran

    widget.controls.consensus_box.click()  # and off again: the plain answers come back
    _idle(qtbot, widget)
    assert not session.consensus and not session.predictor.config.consensus
    assert any("refining without consensus" in line for line in statuses)
    np.testing.assert_array_equal(committed.data, plain)


def test_toggling_without_objects_predicts_nothing(make_napari_viewer, qtbot, scene):
    _, widget = _open(make_napari_viewer, qtbot, scene)
    calls = []
    widget._predict_all = calls.append
    widget.set_consensus(True)  # programmatic: the box follows
    _idle(qtbot, widget)
    assert widget.controls.consensus_box.isChecked() and widget.session.consensus
    assert widget.session.predictor.config.consensus and calls == []


def test_lfsam_view_consensus(make_napari_viewer, qtbot, scene, tmp_path):
    """``lfsam view --consensus`` checks the box (``make_napari_viewer`` resets napari's
    command registry afterwards, where open_viewer registered the plugin's commands)."""
    from lfsam.cli.main import build_parser
    from lfsam.cli.view import open_viewer
    from lfsam.io import write_lightfield

    write_lightfield(scene, tmp_path / "scene")
    argv = ["view", str(tmp_path / "scene"), "--model", "oracle", "--disparity", "gt"]
    assert build_parser().parse_args(argv).consensus is False
    viewer, widget = open_viewer(build_parser().parse_args([*argv, "--consensus"]), show=False)
    try:
        qtbot.waitUntil(lambda: widget.session.loaded and not widget.busy, timeout=TIMEOUT)
        assert widget.controls.consensus_box.isChecked()
        assert widget.session.predictor.config.consensus
    finally:
        viewer.close()


def test_a_video_track_carries_the_consensus(make_napari_viewer, qtbot, monkeypatch, tmp_path):
    """Each frame's predictor and the track's pipeline (``track_video``'s options)."""
    from lfsam.video import read_video
    from lfsam.video.io.synth import generate_video, write_video_frames
    from lfsam.video.tracking import track as track_module

    write_video_frames(generate_video(grid=(3, 3), size=(32, 40), frames=2, seed=0,
                                      num_objects=2), tmp_path / "clip")
    video = read_video(tmp_path / "clip")
    seen = []

    def spy(*args, options=None, **kwargs):
        seen.append(options.pipeline)
        return real(*args, options=options, **kwargs)

    real = track_module.track_video
    monkeypatch.setattr(track_module, "track_video", spy)
    viewer = make_napari_viewer()
    widget = LightFieldWidget(viewer, video=video, model="oracle", disparity="gt", consensus=True)
    viewer.window.add_dock_widget(widget)
    qtbot.waitUntil(lambda: widget.session.loaded and not widget.busy, timeout=TIMEOUT)
    assert widget.session.predictor.config.consensus
    frame = video.frame(0)
    label = int(np.bincount(frame.labels[frame.center].ravel())[1:].argmax()) + 1
    pixel = _interior(frame.labels[frame.center], label)
    viewer.dims.current_step = (0, *frame.center, *viewer.dims.current_step[3:])
    for kind, dispatch in (("mouse_press", mouse_press_callbacks),
                           ("mouse_release", mouse_release_callbacks)):
        event = MouseEvent(kind, (0, *frame.center, *pixel), dims_displayed=[3, 4])
        dispatch(widget.layers[L.POINTS], ReadOnlyWrapper(event, exceptions=("handled",)))
    _idle(qtbot, widget)
    widget.track()
    qtbot.waitUntil(lambda: widget.session.tracked is not None and not widget.busy,
                    timeout=TIMEOUT)
    assert [config.consensus for config in seen] == [True]
