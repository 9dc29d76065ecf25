"""The napari viewer on a light-field video (issue 25): a frame slider, prompts on any frame,
tracking in the worker with each frame shown as it finishes.

Driven as a user drives it (clicks through the points layer's mouse callbacks, the worker
awaited with ``qtbot.waitUntil``), on a tiny synthetic video (3 frames of 3x3 views of 32x48)
with the oracle and ground-truth disparity, whose answers are exact. Needs a display: run under
``xvfb-run``.
"""

from __future__ import annotations

import numpy as np
import pytest
from napari.utils._proxies import ReadOnlyWrapper
from napari.utils.interactions import mouse_press_callbacks, mouse_release_callbacks
from scipy import ndimage

import lfsam
from lfsam.errors import LfsamError
from lfsam.video import read_video
from lfsam.video.io.synth import generate_video, write_video_frames
from lfsam.viewer import layers as L
from lfsam.viewer.plugin_io import get_reader, read_path
from lfsam.viewer.video import FrameStore, VideoFrames
from lfsam.viewer.widget import LightFieldWidget
from napari_events import WAIT_PRELUDE, MouseEvent, register_plugin

TIMEOUT = 60_000
CENTER = (1, 1)
FIRST, LATER = 2, 3  # ground-truth labels: clicked at frame 0, and only at frame 1


register_plugin()


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    """A 3-frame video of 3x3 views of 32x48 written as a folder of frames."""
    path = tmp_path_factory.mktemp("viewer_video") / "clip"
    write_video_frames(generate_video(grid=(3, 3), size=(32, 48), frames=3, seed=0,
                                      num_objects=2), path)
    return path


def _interior(labels: np.ndarray, label: int) -> tuple[int, int]:
    dist = ndimage.distance_transform_edt(labels == label)
    return tuple(int(i) for i in np.unravel_index(dist.argmax(), dist.shape))


def _click(viewer, layer, frame, view, pixel):
    """Move the sliders to ``frame`` and ``view``, then press and release on ``pixel``."""
    viewer.dims.current_step = (frame, *view, *viewer.dims.current_step[3:])
    position = (frame, *view, *pixel)
    for kind, dispatch in (("mouse_press", mouse_press_callbacks),
                           ("mouse_release", mouse_release_callbacks)):
        event = MouseEvent(kind, position, dims_displayed=[3, 4])
        dispatch(layer, ReadOnlyWrapper(event, exceptions=("handled",)))


def _idle(qtbot, widget):
    qtbot.waitUntil(lambda: not widget.busy and not widget._segment_pending, timeout=TIMEOUT)


def _open(make_napari_viewer, qtbot, clip, **kwargs):
    viewer = make_napari_viewer()
    viewer.open(str(clip), plugin="lfsam")  # File > Open through the reader
    options = {"model": "oracle", "disparity": "gt", **kwargs}
    widget = LightFieldWidget(viewer, **options)
    viewer.window.add_dock_widget(widget)
    qtbot.waitUntil(lambda: widget.session.loaded and not widget.busy, timeout=TIMEOUT)
    return viewer, widget


def test_reader_gives_one_lazy_layer_with_a_frame_axis(clip):
    assert get_reader(str(clip)) is not None
    (data, kwargs, kind), = read_path(clip)
    assert kind == "image" and isinstance(data, VideoFrames)
    assert data.shape == (3, 3, 3, 32, 48, 3) and data.ndim == 6 and data.dtype == np.uint8
    assert kwargs["axis_labels"][0] == "frame" and data.reads == 0
    np.testing.assert_array_equal(data[2, 1], read_video(clip).frame(2).views[1])
    assert data.reads == 1
    data[2:3, 1, 1]  # napari slices with a one-frame slice: the cached frame, no new read
    assert data.reads == 1


def test_frame_slider_reads_one_frame_at_a_time(make_napari_viewer, qtbot, clip):
    viewer, widget = _open(make_napari_viewer, qtbot, clip)
    frames = widget.image_layer.data
    assert isinstance(frames, VideoFrames) and widget.is_video
    assert viewer.dims.axis_labels[:3] == ("frame", "s", "t")
    assert tuple(viewer.dims.current_step[:3]) == (0, *CENTER)
    # napari's first slice is the middle frame, then the widget shows frame 0: two reads
    assert frames.reads <= 2 and 2 not in frames._cache
    before = frames.reads
    viewer.dims.current_step = (2, *viewer.dims.current_step[1:])
    qtbot.waitUntil(lambda: 2 in frames._cache, timeout=TIMEOUT)
    assert frames.reads == before + 1  # one frame per slider step
    viewer.dims.current_step = (2, 0, 2, *viewer.dims.current_step[3:])  # another view
    qtbot.wait(50)
    assert frames.reads == before + 1  # the same frame: cached
    store = widget.layers[L.COMMITTED].data
    assert isinstance(store, FrameStore) and store.shape == (3, 3, 3, 32, 48)
    assert store.written() == []  # nothing allocated for frames nothing was written to


def test_click_on_a_later_frame_is_tagged_and_segments_that_frame(
        make_napari_viewer, qtbot, clip):
    viewer, widget = _open(make_napari_viewer, qtbot, clip)
    truth = read_video(clip).frame(2).labels
    _click(viewer, widget.layers[L.POINTS], 2, CENTER, _interior(truth[CENTER], LATER))
    _idle(qtbot, widget)
    obj_id = widget.session.current_id
    (point,) = widget.session.current_prompts().points
    assert point.frame == 2 and point.view == CENTER and point.positive
    assert widget.session.frame == 2
    current = widget.layers[L.CURRENT].data
    # exactly what a predictor of its own gives that click on frame 2's light field
    from lfsam.predictor import LightFieldPredictor
    from lfsam.segmenters import load_segmenter
    from lfsam.video.tracking.prompts import prompts_at

    frame = read_video(clip).frame(2)
    predictor = LightFieldPredictor(load_segmenter("oracle", lightfield=frame))
    predictor.set_lightfield(frame, disparity="gt")
    predictor.set_object(prompts_at(widget.session.current_prompts(), 2))
    np.testing.assert_array_equal(current[2] == obj_id, predictor.predict().masks[obj_id])
    np.testing.assert_array_equal(current[2][CENTER] == obj_id, truth[CENTER] == LATER)
    assert not current[0].any() and not current[1].any()
    assert widget.stages == ["reference", "coarse", "final"]
    # S on a frame where the object has no click: nothing to segment there, said so
    viewer.dims.current_step = (0, *viewer.dims.current_step[1:])
    widget.segment()
    _idle(qtbot, widget)
    assert "no positive click or box on frame 0" in widget.status.text()
    assert widget.session.frame == 2 and not widget.layers[L.CURRENT].data[0].any()
    with pytest.raises(LfsamError, match="press Track"):  # nothing tracked yet
        widget.save(clip.parent / "not_yet")
    # what a single light field does not offer is refused in one line saying what to do
    widget.segment_everything()
    _idle(qtbot, widget)
    assert "not videos" in widget.status.text() and "lfsam segment VIDEO --auto" in (
        widget.status.text())


def test_track_shows_every_frame_as_track_video_gives_it(
        make_napari_viewer, qtbot, clip, tmp_path):
    from lfsam.api import RunOptions, SegmentOptions
    from lfsam.video.tracking.track import track_video

    viewer, widget = _open(make_napari_viewer, qtbot, clip)
    video = read_video(clip)
    points = widget.layers[L.POINTS]
    _click(viewer, points, 0, CENTER, _interior(video.frame(0).labels[CENTER], FIRST))
    _idle(qtbot, widget)
    viewer.window._qt_viewer.canvas._key_map_handler.press_key("C")  # commit
    _idle(qtbot, widget)
    _click(viewer, points, 1, CENTER, _interior(video.frame(1).labels[CENTER], LATER))
    _idle(qtbot, widget)
    later_id = widget.session.current_id
    statuses = []
    widget.status_changed.connect(statuses.append)
    shown = []
    original = widget.masks.show_frame
    widget.masks.show_frame = lambda i, labels: (shown.append(i), original(i, labels))
    viewer.window._qt_viewer.canvas._key_map_handler.press_key("Control-T")  # track
    _idle(qtbot, widget)
    assert shown == [0, 1, 2]
    assert "tracking frame 3 of 3: 2 object(s)" in " ".join(statuses)
    prompts = [widget.session.video_objects[i] for i in sorted(widget.session.video_objects)]
    assert [p.frame for p in prompts[1].points] == [1]
    direct = track_video(video, prompts, tmp_path / "direct", model="oracle", disparity="gt",
                         options=SegmentOptions(run=RunOptions(progress=False)))
    layer = widget.layers[L.COMMITTED].data
    for f in range(3):
        np.testing.assert_array_equal(layer[f], direct.labels[f])
    assert not (direct.labels[0] == later_id).any()  # started at frame 1: absent before
    assert (direct.labels[1] == later_id).any() and (direct.labels[2] == later_id).any()
    # Save writes the video result folder
    out = widget.save(tmp_path / "saved")
    saved = lfsam.load_result(out)
    assert saved.shape == (3, 3, 3, 32, 48)
    for f in range(3):
        np.testing.assert_array_equal(saved.labels[f], direct.labels[f])
    (data, _kwargs, kind), = read_path(out)  # File > Open of the folder: lazy labels
    assert kind == "labels" and isinstance(data, FrameStore) and data.shape == saved.shape
    np.testing.assert_array_equal(data[2], direct.labels[2])
    exported = widget.export(tmp_path / "png", "png")  # lfsam export's video layout
    assert sorted(p.name for p in exported.glob("frame_*")) == [
        "frame_0000", "frame_0001", "frame_0002"]


def test_lfsam_view_video_tracks_with_sam2_in_a_fresh_process(clip, tmp_path):
    """``lfsam view VIDEO`` as the CLI opens it, in a new process (window first, then the tiny
    SAM 2 in the worker; see tests/test_viewer_process.py): a click on frame 1, Track, Save."""
    import json
    import os
    import subprocess
    import sys
    import textwrap

    out = tmp_path / "saved"
    script = WAIT_PRELUDE + textwrap.dedent(f"""
        from lfsam.cli.main import build_parser
        from lfsam.cli.view import open_viewer
        from lfsam.viewer import layers as L

        args = build_parser().parse_args(
            ["view", {str(clip)!r}, "--model", "sam2-tiny-test", "--random-weights",
             "--device", "cpu", "--disparity", "gt"])
        viewer, widget = open_viewer(args, show=True)
        wait(lambda: widget.session.loaded and not widget.busy, "the model")
        widget.layers[L.POINTS].add([[1, 1, 1, 16, 24]])  # a click on frame 1
        wait(lambda: not widget.busy and not widget._segment_pending, "the click")
        widget.track()
        wait(lambda: widget.session.tracked is not None and not widget.busy, "the track")
        saved = widget.save({str(out)!r})
        tracked = widget.session.tracked
        shown = all((widget.layers[L.COMMITTED].data[f] == tracked.labels[f]).all()
                    for f in range(len(tracked)))
        result = {{"frames": len(tracked), "tracking": tracked.meta["tracking"],
                   "shown": bool(shown), "point_frame":
                   widget.session.video_objects[1].points[0].frame,
                   "axes": list(viewer.dims.axis_labels[:3]), "saved": str(saved)}}
        viewer.close()
        print(json.dumps(result))
    """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=240, env={**os.environ, "PYTHONFAULTHANDLER": "1"})
    assert proc.returncode == 0, proc.stderr[-4000:]
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    assert result == {"frames": 3, "tracking": "sam2-memory", "shown": True, "point_frame": 1,
                      "axes": ["frame", "s", "t"], "saved": str(out)}
    assert lfsam.load_result(out).shape == (3, 3, 3, 32, 48)


def test_frame_store_holds_written_frames_spills_and_reads_results(tmp_path):
    from lfsam.result import SegmentationResult
    from lfsam.video.io.result import load_video_result, video_result_writer

    store = FrameStore((5, 1, 2, 3, 4), budget_mb=0)  # keeps 2 frames, spills the others
    assert store[3].shape == (1, 2, 3, 4) and not store[3].any() and store.written() == []
    for f in range(4):
        store.put(f, np.full((1, 2, 3, 4), f + 1))
    assert len(store._live) == 2 and store.written() == [0, 1, 2, 3]
    assert [int(store[f].max()) for f in range(5)] == [1, 2, 3, 4, 0]  # spilled ones read back
    store[4, 0, 1] = 7  # an index on (F, S, T, U, V)
    store[(np.array([0, 0, 2]), np.zeros(3, int), np.zeros(3, int), np.array([0, 1, 2]),
           np.zeros(3, int))] = 9  # napari's painting index
    assert int(store[4][0, 1].min()) == 7 and int(store[0][0, 0, 1, 0]) == 9
    assert int(store[2][0, 0, 2, 0]) == 9 and int(store[1].max()) == 2
    with video_result_writer(tmp_path / "r") as writer:
        for f in range(5):
            writer.write(SegmentationResult(labels=np.full((1, 2, 3, 4), 10 + f, np.int32)))
    store.attach_result(load_video_result(tmp_path / "r"))
    assert store.written() == [] and [int(store[f].max()) for f in range(5)] == [10, 11, 12, 13, 14]
    assert store[1:3].shape == (2, 1, 2, 3, 4)


def test_lfsam_view_video_with_its_result_folder(make_napari_viewer, qtbot, clip, tmp_path):
    """``lfsam view VIDEO --result FOLDER`` shows the tracked labels (a folder that keeps no
    prompts, as written before issue 38: shown only); a result of another shape, or a single
    result file, is refused in one line."""
    import argparse

    from lfsam.cli.main import build_parser
    from lfsam.cli.view import open_viewer
    from lfsam.result import SegmentationResult
    from lfsam.video.io.result import video_result_writer

    with video_result_writer(tmp_path / "r") as writer:
        for f in range(3):
            writer.write(SegmentationResult(labels=np.full((3, 3, 32, 48), f + 1, np.int32)))
    args = build_parser().parse_args(["view", str(clip), "--model", "oracle", "--disparity",
                                      "gt", "--result", str(tmp_path / "r")])
    viewer, widget = open_viewer(args, show=False)
    try:
        qtbot.waitUntil(lambda: widget.session.loaded and not widget.busy, timeout=TIMEOUT)
        assert widget.session.tracked is not None
        assert [int(widget.layers[L.COMMITTED].data[f].max()) for f in range(3)] == [1, 2, 3]
        assert "showing" in widget.status.text() and "not stored" in widget.status.text()
        assert widget.session.object_ids == [] and widget.session.current_id == 4
    finally:
        viewer.close()
    bad = argparse.Namespace(**{**vars(args), "result": str(tmp_path / "x.npz")})
    with pytest.raises(LfsamError, match="result folder"):
        open_viewer(bad, show=False)


def test_stop_tracking_after_the_frame_being_tracked_keeps_nothing(
        make_napari_viewer, qtbot, clip, tmp_path):
    viewer, widget = _open(make_napari_viewer, qtbot, clip)
    video = read_video(clip)
    _click(viewer, widget.layers[L.POINTS], 0, CENTER,
           _interior(video.frame(0).labels[CENTER], FIRST))
    _idle(qtbot, widget)  # the model is loaded: Track starts at once
    stop = widget.controls.stop_track_button
    assert stop.isVisibleTo(widget)  # shown for videos
    assert not stop.isEnabled()
    statuses = []
    widget.status_changed.connect(statuses.append)
    shown = []
    original = widget.masks.show_frame
    widget.masks.show_frame = lambda i, labels: (shown.append(i), original(i, labels))
    widget.track(tmp_path / "stopped")
    assert stop.isEnabled()
    stop.click()  # before the first frame finishes: the track ends after it
    _idle(qtbot, widget)
    assert shown == [0]
    assert "tracking stopped after frame 1 of 3" in " ".join(statuses)
    assert not (tmp_path / "stopped").exists()  # nothing of the stopped track is left
    assert widget.session.tracked is None and not stop.isEnabled()
    with pytest.raises(LfsamError, match="nothing to save"):
        widget.save(tmp_path / "saved")
    # a full track afterwards; then a stopped one shows it again and Save still writes it
    widget.track(tmp_path / "full")
    _idle(qtbot, widget)
    full = widget.session.tracked
    assert full is not None and len(full) == 3
    widget.track(tmp_path / "again")
    widget.stop_tracking()
    _idle(qtbot, widget)
    assert widget.session.tracked is full and not (tmp_path / "again").exists()
    assert "previous track is shown again" in statuses[-1]
    layer = widget.layers[L.COMMITTED].data
    for f in range(3):
        np.testing.assert_array_equal(layer[f], full.labels[f])
    saved = lfsam.load_result(widget.save(tmp_path / "saved"))
    np.testing.assert_array_equal(saved.labels[2], full.labels[2])


def test_saved_track_reopens_editable_and_tracks_again(make_napari_viewer, qtbot, clip, tmp_path):
    """Issue 38: a track saved by the dock reopens with ``lfsam view VIDEO --result FOLDER``
    with the same objects, editable, their prompts on their frames; a click added on frame 2
    and Track again re-track them (equal to ``track_video`` with the new prompts)."""
    from lfsam.api import RunOptions, SegmentOptions
    from lfsam.cli.main import build_parser
    from lfsam.cli.view import open_viewer
    from lfsam.video.tracking.track import track_video

    viewer, widget = _open(make_napari_viewer, qtbot, clip)
    video = read_video(clip)
    points = widget.layers[L.POINTS]
    _click(viewer, points, 0, CENTER, _interior(video.frame(0).labels[CENTER], FIRST))
    _idle(qtbot, widget)
    widget.commit()
    _idle(qtbot, widget)
    _click(viewer, points, 1, CENTER, _interior(video.frame(1).labels[CENTER], LATER))
    _idle(qtbot, widget)
    widget.track()
    _idle(qtbot, widget)
    saved = widget.save(tmp_path / "saved")
    objects = dict(widget.session.video_objects)
    first_id, later_id = sorted(objects)
    assert [p.frame for p in objects[later_id].points] == [1]

    args = build_parser().parse_args(["view", str(clip), "--model", "oracle", "--disparity",
                                      "gt", "--result", str(saved)])
    viewer, widget = open_viewer(args, show=False)
    try:
        qtbot.waitUntil(lambda: widget.session.tracked is not None and not widget.busy,
                        timeout=TIMEOUT)
        session = widget.session
        assert session.video_objects == objects  # the same objects, prompts and frames
        assert session.committed == {first_id, later_id}
        assert session.current_id == later_id + 1
        listed = [widget.objects.item(i).text() for i in range(widget.objects.count())]
        assert listed == [f"{first_id}  (committed)", f"{later_id}  (committed)"]
        assert "editable" in widget.status.text()
        tracked = lfsam.load_result(saved)
        for f in range(3):  # the tracked labels are shown, read from the folder
            np.testing.assert_array_equal(widget.layers[L.COMMITTED].data[f], tracked.labels[f])
        # edit the later object: its prompts go to the points layer with their frames
        widget.edit_object(later_id)
        _idle(qtbot, widget)
        assert session.current_id == later_id
        np.testing.assert_array_equal(widget.layers[L.POINTS].data[:, :3], [[1, *CENTER]])
        # a click on frame 2, then Track again
        pixel = _interior(video.frame(2).labels[CENTER], LATER)
        _click(viewer, widget.layers[L.POINTS], 2, CENTER, pixel)
        _idle(qtbot, widget)
        edited = session.video_objects[later_id]
        assert [p.frame for p in edited.points] == [1, 2]
        assert session.video_objects[first_id] == objects[first_id]
        widget.track(tmp_path / "again")
        _idle(qtbot, widget)
        again = session.tracked
        assert again is not tracked and again.path == tmp_path / "again"
        prompts = [session.video_objects[i] for i in sorted(session.video_objects)]
        assert again.stored_prompts() == prompts  # the edited prompts are stored in turn
        direct = track_video(video, prompts, tmp_path / "direct", model="oracle",
                             disparity="gt",
                             options=SegmentOptions(run=RunOptions(progress=False)))
        for f in range(3):
            np.testing.assert_array_equal(widget.layers[L.COMMITTED].data[f], direct.labels[f])
            np.testing.assert_array_equal(again.labels[f], direct.labels[f])
        # a session with objects does not drop them for another result folder
        with pytest.raises(LfsamError, match="has objects already"):
            widget.show_tracked(tracked)
    finally:
        viewer.close()
    # File > Open of the folder, then "Reopen selected labels layer": the same
    viewer, widget = _open(make_napari_viewer, qtbot, clip)
    (layer,) = viewer.open(str(saved), plugin="lfsam")
    viewer.layers.selection.active = layer
    widget.controls.open_labels_button.click()
    _idle(qtbot, widget)
    assert widget.session.video_objects == objects and widget.session.tracked.path == saved
    assert widget.session.committed == {first_id, later_id}
