"""The viewer's Follow (issue 35, docs/design.md section 10): a growing frames folder segmented
live in napari, each frame shown as it lands, clicks posted as new objects, Stop and END.

Frames land as a camera writer should put them (copied under a hidden name, then renamed in),
from a thread; a tiny synthetic video (4 frames of 3x3 views of 48x64) with the oracle and
ground-truth disparity, whose answers are exact. Needs a display: run under ``xvfb-run``.
"""

from __future__ import annotations

import re
import threading
import time

import numpy as np
import pytest
from napari.utils._proxies import ReadOnlyWrapper
from napari.utils.interactions import mouse_press_callbacks, mouse_release_callbacks
from qtpy.QtCore import QTimer
from scipy import ndimage

import lfsam
from hidden_status import check_hidden_lines
from lfsam.cli.main import main
from lfsam.errors import LfsamError
from lfsam.video import read_video
from lfsam.video.io.result import RESULT_MARKER
from lfsam.video.io.synth import generate_video, write_video_frames
from lfsam.video.tracking.online import OnlineTracker
from lfsam.viewer import layers as L
from lfsam.viewer.follow_dock import default_out
from lfsam.viewer.widget import LightFieldWidget
from napari_events import MouseEvent, register_plugin
from stream_files import frame_folders, land_frame

TIMEOUT = 60_000
CENTER = (1, 1)
OBJECT = 3  # a ground-truth label clicked (label 1 is the backdrop)

register_plugin()


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """A 4-frame video of 3x3 views of 48x64, 3 objects, as a folder of frame folders."""
    path = tmp_path_factory.mktemp("viewer_follow") / "source"
    write_video_frames(generate_video(grid=(3, 3), size=(48, 64), frames=4, seed=0,
                                      num_objects=3), path)
    return path




def _land(frames, folder, end=False, pause=0.0):
    """Land ``frames`` (then END) in ``folder`` from a writer thread; returns the thread."""

    def write():
        for frame in frames:
            land_frame(frame, folder)
            time.sleep(pause)
        if end:
            (folder / "END").write_text("")

    thread = threading.Thread(target=write, daemon=True)
    thread.start()
    return thread


def _dock(make_napari_viewer, **options):
    viewer = make_napari_viewer()
    widget = LightFieldWidget(viewer, **{"model": "oracle", "disparity": "gt", **options})
    viewer.window.add_dock_widget(widget)
    statuses = []
    widget.status_changed.connect(statuses.append)
    return viewer, widget, statuses


def _shown(qtbot, follow, count):
    """Frame ``count - 1`` is shown and its file, written behind the tracking (issue 44), is in
    the live result folder."""
    qtbot.waitUntil(lambda: len(follow.names) >= count, timeout=TIMEOUT)
    out = follow.out
    if out is not None:
        qtbot.waitUntil(lambda: (out / RESULT_MARKER).is_file() and len(
            lfsam.load_result(out)) >= count, timeout=TIMEOUT)


def _ended(qtbot, widget):
    """The stream is over and the dock idle (the followed result opened as a video)."""
    qtbot.waitUntil(lambda: not widget.follow.running, timeout=TIMEOUT)
    qtbot.waitUntil(lambda: widget.work.idle, timeout=TIMEOUT)


def _interior(mask):
    depth = ndimage.distance_transform_edt(mask)
    return tuple(int(i) for i in np.unravel_index(depth.argmax(), depth.shape))


def _click(viewer, layer, view, pixel):
    """Press and release on ``pixel`` of ``view`` (the sliders moved there first)."""
    viewer.dims.current_step = (*view, *viewer.dims.current_step[2:])
    for kind, dispatch in (("mouse_press", mouse_press_callbacks),
                           ("mouse_release", mouse_release_callbacks)):
        event = MouseEvent(kind, (*view, *pixel), dims_displayed=[2, 3])
        dispatch(layer, ReadOnlyWrapper(event, exceptions=("handled",)))


def test_following_an_empty_folder_shows_each_frame_and_a_click_starts_an_object(
        make_napari_viewer, qtbot, source, tmp_path):
    viewer, widget, statuses = _dock(make_napari_viewer)
    live, out = tmp_path / "incoming", tmp_path / "result"
    live.mkdir()
    follow, controls = widget.follow, widget.controls
    assert follow.start(live, out) == out
    assert follow.running and controls.stop_follow_button.isEnabled()
    assert not controls.follow_button.isEnabled()
    assert "waiting for frames" in statuses[-1]
    qtbot.wait(200)
    assert follow.layers == {} and follow.names == []  # nothing landed, nothing shown
    frames, video = frame_folders(source), read_video(source)
    with pytest.raises(LfsamError, match="once it is shown"):
        follow.click((*CENTER, 10, 10))

    _land(frames[:1], live).join()
    _shown(qtbot, follow, 1)
    result = lfsam.load_result(out)  # the live result folder, readable while it grows
    assert len(result) == 1 and not result.labels[0].any()  # no click yet: no object
    np.testing.assert_array_equal(follow.layers["image"].data, video.frame(0).views)
    np.testing.assert_array_equal(follow.layers["labels"].data, result.labels[0])
    assert re.fullmatch(r"frame 0 \(frame_0000\): \d+\.\d\d s from arrival, no object .*",
                        statuses[-1])
    assert tuple(viewer.dims.current_step[:2]) == CENTER
    assert viewer.dims.axis_labels[:2] == ("s", "t") and widget.session is None
    with pytest.raises(LfsamError, match="lands on none"):  # a negative click on no object
        follow.click((*CENTER, 10, 10), positive=False)

    # a click on frame 0, on an object that is still there in frame 1
    first, second = (video.frame(f).labels[CENTER] == OBJECT for f in (0, 1))
    pixel = _interior(first & second)
    _click(viewer, follow.layers["points"], CENTER, pixel)
    assert "object 1 (new object in view 1,1): segmented from the next frame on" in (
        widget.status.text())
    for f in (1, 2):
        _land(frames[f:f + 1], live).join()
        _shown(qtbot, follow, f + 1)
        result = lfsam.load_result(out)
        assert len(result) == f + 1
        np.testing.assert_array_equal(follow.layers["image"].data, video.frame(f).views)
        np.testing.assert_array_equal(follow.layers["labels"].data, result.labels[f])
        assert statuses[-1].startswith(f"frame {f} ({frames[f].name}): ")
        assert "objects [1]" in statuses[-1]
        assert len(follow.layers["points"].data) == 0  # the click was on an earlier frame
    labels = result.labels
    assert not (labels[0] == 1).any()  # segmented from the next frame on: absent before
    assert (labels[1] == 1).any() and (labels[2] == 1).any()  # same id in later frames
    np.testing.assert_array_equal(labels[1][CENTER] == 1, second)  # the oracle is exact
    (obj,) = result.stored_prompts()
    (point,) = obj.points
    assert obj.obj_id == 1 and point.frame == 1 and point.view == CENTER and point.positive
    assert (point.y, point.x) == pixel

    controls.stop_follow_button.click()  # Stop
    _ended(qtbot, widget)
    assert follow.report.ended_by == "stopped" and follow.report.frames == 3
    assert any("stream ended (stopped) after 3 frame(s)" in line for line in statuses)
    result = lfsam.load_result(out)
    assert len(result) == 3 and result.meta["ended_by"] == "stopped"
    assert controls.follow_button.isEnabled() and not controls.stop_follow_button.isEnabled()
    # the viewer had nothing open: the frames segmented are shown as a video with the result
    assert widget.is_video and follow.layers == {} and viewer.dims.axis_labels[0] == "frame"
    assert viewer.dims.current_step[0] == 2  # on the last frame, as while following
    assert widget.session.tracked.path == out and widget.session.video.shape == result.shape
    for f in range(3):
        np.testing.assert_array_equal(widget.layers[L.COMMITTED].data[f], result.labels[f])
    assert widget.session.video_objects[1].points[0].frame == 1  # editable, as any result
    assert "shown as a video" in statuses[-1]


def test_a_stream_already_in_the_folder_ends_at_END(make_napari_viewer, qtbot, source, tmp_path):
    """Frames already there are segmented first, the others as they land; END ends it, with
    the objects the automatic mode found in frame 0 tracked through (default result folder)."""
    _viewer, widget, statuses = _dock(make_napari_viewer)
    live = tmp_path / "cam"
    live.mkdir()
    frames = frame_folders(source)
    for frame in frames[:2]:
        land_frame(frame, live)
    out = widget.follow.start(live, auto=True)
    assert out == tmp_path / "cam_live"
    writer = _land(frames[2:], live, end=True, pause=0.2)
    _ended(qtbot, widget)
    writer.join()
    report = widget.follow.report
    assert report.ended_by == "END" and report.frames == 4 and not report.skipped
    assert widget.follow.names == [frame.name for frame in frames]
    assert any("stream ended (END file) after 4 frame(s)" in line for line in statuses)
    result = lfsam.load_result(out)
    assert len(result) == 4 and result.meta["ended_by"] == "END"
    found = set(np.unique(result.labels[0])) - {0}  # the automatic mode's objects
    later = set(np.unique(result.labels[3])) - {0}
    assert len(found) >= 3 and len(later) >= 2 and later <= found  # tracked, ids kept
    # the frames folder (END is no frame) opens with its result like any video result
    assert read_video(live).shape == result.shape
    assert widget.session.tracked.path == out
    np.testing.assert_array_equal(widget.layers[L.COMMITTED].data[3], result.labels[3])
    assert default_out(live) == tmp_path / "cam_live_2"  # cam_live is taken now



def test_the_status_names_the_objects_searched_for_and_their_hidden_frames(
        make_napari_viewer, qtbot, tmp_path):
    """Issue 47: an object not found in a frame is named in that frame's status as searched
    for, under its id, since the first frame of its run of hidden frames, and the end line
    gives its hidden frames; checked against the result's states (``meta["tracks"]``) in a
    video whose first object leaves the frame in frames 2-4 (the ground truth)."""
    source = tmp_path / "source"
    write_video_frames(generate_video(grid=(3, 3), size=(48, 64), frames=6, seed=0,
                                      num_objects=3), source)
    _viewer, widget, statuses = _dock(make_napari_viewer)
    live = tmp_path / "cam"
    live.mkdir()
    frames = frame_folders(source)
    widget.follow.start(live, auto=True)
    writer = _land(frames, live, end=True)
    _ended(qtbot, widget)
    writer.join()
    result = lfsam.load_result(widget.follow.out)
    video = read_video(source)
    gone = [f for f in range(6) if not (video.frame(f).labels == 2).any()]
    assert gone == [2, 3, 4]
    hidden = check_hidden_lines(statuses, [f.name for f in frames], result.meta["tracks"],
                                "stream ended (END file)")
    assert all(hidden[f] for f in gone)

def test_newest_frame_only_skips_the_backlog(make_napari_viewer, qtbot, source, tmp_path):
    """The dock's "Newest frame only" (issue 44, --latest): with frames waiting, the newest is
    segmented and the older ones are listed as skipped, each by name."""
    _viewer, widget, statuses = _dock(make_napari_viewer)
    live = tmp_path / "cam"
    live.mkdir()
    frames = frame_folders(source)
    for frame in frames:
        land_frame(frame, live)
    (live / "END").write_bytes(b"")
    widget.controls.latest_box.setChecked(True)
    out = widget.follow.start(live, tmp_path / "out", auto=True)
    _ended(qtbot, widget)
    report = widget.follow.report
    names = [frame.name for frame in frames]
    assert report.ended_by == "END" and report.frames < len(frames)
    assert widget.follow.names[-1] == names[-1]
    skipped = [s["name"] for s in report.skipped]
    assert sorted(widget.follow.names + skipped) == names
    assert all(s["reason"] == "newer frame available" for s in report.skipped)
    assert lfsam.load_result(out).meta["latest"] is True
    assert any("older skipped" in line for line in statuses)


def test_the_gui_thread_runs_while_a_frame_is_segmented_and_stop_keeps_that_frame(
        make_napari_viewer, qtbot, source, tmp_path, monkeypatch):
    _viewer, widget, _statuses = _dock(make_napari_viewer)
    entered, release = threading.Event(), threading.Event()
    original = OnlineTracker.track

    def held(self, lightfield):  # a slow model: segmenting waits until the test releases it
        entered.set()
        assert release.wait(30)
        return original(self, lightfield)

    monkeypatch.setattr(OnlineTracker, "track", held)
    live = tmp_path / "incoming"
    live.mkdir()
    follow = widget.follow
    follow.start(live, tmp_path / "out")
    _land(frame_folders(source)[:1], live).join()
    qtbot.waitUntil(entered.is_set, timeout=TIMEOUT)
    ticks = []
    timer = QTimer()
    timer.timeout.connect(lambda: ticks.append(time.monotonic()))
    timer.start(10)
    qtbot.wait(400)  # the frame is being segmented all this time
    timer.stop()
    assert len(ticks) >= 10  # the event loop kept running
    assert follow.thread.is_alive() and follow.running and follow.names == []
    widget.controls.stop_follow_button.click()
    assert "stopping the stream" in widget.status.text()
    release.set()
    _ended(qtbot, widget)
    assert follow.names == ["frame_0000"]  # the frame being segmented is finished and kept
    assert follow.report.ended_by == "stopped" and follow.report.frames == 1
    assert len(lfsam.load_result(tmp_path / "out")) == 1


def test_follow_refuses_in_one_line(make_napari_viewer, qtbot, tmp_path):
    _viewer, widget, statuses = _dock(make_napari_viewer)
    follow = widget.follow
    with pytest.raises(LfsamError, match="does not exist"):
        follow.start(tmp_path / "missing")
    full = tmp_path / "full"
    (full / "x").mkdir(parents=True)
    with pytest.raises(LfsamError, match="is not empty"):
        follow.start(tmp_path, full)
    assert not follow.running
    follow.start(full, tmp_path / "out", timeout=0.3)  # x: a folder that holds no frame
    with pytest.raises(LfsamError, match="already following"):
        follow.start(full, tmp_path / "out2")
    _ended(qtbot, widget)
    assert follow.report.ended_by == "timeout" and follow.report.frames == 0
    assert any(line.startswith("frame x skipped: ") for line in statuses)  # said, and on
    assert "after 0 frame(s), 1 skipped; nothing was written" in widget.status.text()
    assert not (tmp_path / "out").exists() and widget.session is None
    _viewer2, widget2, _ = _dock(make_napari_viewer, disparity=str(tmp_path / "d.npy"))
    with pytest.raises(LfsamError, match="not a file"):
        widget2.follow.start(full)


@pytest.mark.parametrize(("argv", "message"), [
    (["{tmp}/missing", "--follow"], "does not exist"),
    (["--follow"], "watches a frames folder"),
    (["{tmp}", "--out", "{tmp}/r"], "go with --follow"),
    (["{tmp}", "--follow", "--result", "{tmp}/r"], "writes a new result"),
    (["{tmp}", "--follow", "--out", "{tmp}"], "is not empty"),
    (["{tmp}", "--follow", "--disparity", "{tmp}/d.npy"], "not a file"),
    (["{tmp}", "--auto"], "go with --follow"),
    (["{tmp}", "--follow", "--auto", "--text", "disc"], "--text or --auto, not both"),
])
def test_lfsam_view_follow_checks_its_arguments_before_opening(argv, message, tmp_path, capsys):
    (tmp_path / "a_frame").mkdir()
    code = main(["view", *(a.format(tmp=tmp_path) for a in argv)])
    err = capsys.readouterr().err
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1


def test_lfsam_view_follow_opens_on_an_empty_folder(make_napari_viewer, qtbot, tmp_path):
    from lfsam.cli.main import build_parser
    from lfsam.cli.view import open_viewer

    live = tmp_path / "incoming"
    live.mkdir()
    args = build_parser().parse_args(["view", str(live), "--follow", "--out", str(tmp_path / "r"),
                                      "--model", "oracle", "--disparity", "gt"])
    viewer, widget = open_viewer(args, show=False)
    try:
        assert widget.follow.running and widget.follow.out == tmp_path / "r"
        assert widget.session is None and len(viewer.layers) == 0  # nothing read as a video
        (live / "END").write_text("")
        _ended(qtbot, widget)
        assert widget.follow.report.ended_by == "END" and not (tmp_path / "r").exists()
    finally:
        viewer.close()
