"""The viewer's edges of issue 46: Save checks its place before any work, Follow's automatic
mode (the dock's box, ``lfsam view --follow --auto``), ``--text`` with ``--follow``, a notice
for clicks posted after the last frame, and a configuration fault ending the stream in one
line. Oracle, ground-truth disparity, tiny synthetic frames. Needs a display (``xvfb-run``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import lfsam
from lfsam.cli.main import build_parser
from lfsam.cli.view import open_viewer
from lfsam.io import write_lightfield
from lfsam.synth import generate_scene
from lfsam.video import read_video
from lfsam.video.io.synth import generate_video, write_video_frames
from lfsam.viewer import controls as C
from lfsam.viewer.widget import LightFieldWidget
from napari_events import register_plugin
from stream_files import frame_folders, land_frame

TIMEOUT = 60_000
CENTER = (1, 1)
TILE = 3  # the ground-truth label of the "noise tile" in the clip below

register_plugin()


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """A 3-frame video of 3x3 views of 48x64, 3 objects, as a folder of frame folders."""
    path = tmp_path_factory.mktemp("viewer_edges") / "source"
    write_video_frames(generate_video(grid=(3, 3), size=(48, 64), frames=3, seed=0,
                                      num_objects=3), path)
    return path




def _dock(make_napari_viewer, **options):
    viewer = make_napari_viewer()
    widget = LightFieldWidget(viewer, **{"model": "oracle", "disparity": "gt", **options})
    viewer.window.add_dock_widget(widget)
    statuses: list[str] = []
    widget.status_changed.connect(statuses.append)
    return viewer, widget, statuses


def _ended(qtbot, widget):
    qtbot.waitUntil(lambda: not widget.follow.running, timeout=TIMEOUT)
    qtbot.waitUntil(lambda: widget.work.idle, timeout=TIMEOUT)


def test_save_checks_its_place_before_waiting_for_the_work(make_napari_viewer, qtbot,
                                                           monkeypatch, tmp_path):
    scene = generate_scene(grid=(3, 3), size=(48, 64), seed=0, num_objects=3)
    _viewer, widget, statuses = _dock(make_napari_viewer, lightfield=scene)
    qtbot.waitUntil(lambda: widget.session.loaded and not widget.busy, timeout=TIMEOUT)
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    monkeypatch.setattr(type(widget.work), "busy", property(lambda self: True))  # work running
    monkeypatch.setattr(C, "ask_save_file", lambda *a, **k: str(blocker / "result.npz"))
    widget._save_dialog()
    assert "does not exist" in statuses[-1] and not widget.work.actions  # refused at once
    monkeypatch.setattr(C, "ask_save_file", lambda *a, **k: str(tmp_path / "result.npz"))
    widget._save_dialog()
    assert len(widget.work.actions) == 1  # a good place: written once the work is done


def test_follow_box_finds_every_object_of_the_first_frame(make_napari_viewer, qtbot, source,
                                                          monkeypatch, tmp_path):
    """"Follow: everything in the first frame" (Follow's automatic mode) through the dock's
    Follow… dialog: objects found in frame 0 without a click, tracked with their ids."""
    _viewer, widget, _statuses = _dock(make_napari_viewer)
    live, out = tmp_path / "cam", tmp_path / "out"
    live.mkdir()
    for frame in frame_folders(source):
        land_frame(frame, live)
    (live / "END").write_text("")
    monkeypatch.setattr(C, "ask_open_folder", lambda *a, **k: str(live))
    monkeypatch.setattr(C, "ask_save_file", lambda *a, **k: str(out))
    widget.controls.follow_auto_box.setChecked(True)
    widget.controls.follow_button.click()
    _ended(qtbot, widget)
    result = lfsam.load_result(out)
    assert len(result) == 3 and result.meta["prompt_mode"] == "auto"
    found, later = (set(np.unique(result.labels[f])) - {0} for f in (0, 2))
    assert len(found) >= 3 and later and later <= found


def test_lfsam_view_follow_auto_and_text(make_napari_viewer, qtbot, source, tmp_path):
    """``lfsam view --follow --text tile``: the phrase found in the first frame, then tracked;
    ``--auto`` checks the dock's box."""
    live, out = tmp_path / "cam", tmp_path / "out"
    live.mkdir()
    for frame in frame_folders(source):
        land_frame(frame, live)
    (live / "END").write_text("")
    args = build_parser().parse_args(["view", str(live), "--follow", "--out", str(out),
                                      "--model", "oracle", "--disparity", "gt",
                                      "--text", "tile"])
    viewer, widget = open_viewer(args, show=False)
    try:
        assert not widget.controls.follow_auto_box.isChecked()
        _ended(qtbot, widget)
        result = lfsam.load_result(out)
        [find] = result.meta["text"]
        assert find["phrase"] == "tile" and find["found"] == 1
        [obj_id] = find["ids"]
        video = read_video(source)
        for f in range(3):
            truth, mine = video.frame(f).labels == TILE, result.labels[f] == obj_id
            assert (mine & truth).sum() / (mine | truth).sum() > 0.8
    finally:
        viewer.close()
    args = build_parser().parse_args(["view", str(live), "--follow", "--auto", "--model",
                                      "oracle", "--out", str(tmp_path / "out2")])
    viewer, widget = open_viewer(args, show=False)
    try:
        assert widget.controls.follow_auto_box.isChecked() and widget.follow.tracker.auto
        _ended(qtbot, widget)
    finally:
        viewer.close()


def test_a_click_after_the_last_frame_is_reported_not_dropped(make_napari_viewer, qtbot,
                                                              source, tmp_path):
    _viewer, widget, statuses = _dock(make_napari_viewer)
    live = tmp_path / "cam"
    live.mkdir()
    follow = widget.follow
    follow.start(live, tmp_path / "out")
    land_frame(frame_folders(source)[0], live)
    qtbot.waitUntil(lambda: len(follow.names) == 1, timeout=TIMEOUT)
    follow.click((*CENTER, 20, 30))  # posted for the next frame, which never comes
    (live / "END").write_text("")
    _ended(qtbot, widget)
    ended = [line for line in statuses if line.startswith("stream ended")]
    assert "1 click(s) came after the last frame and were not used" in ended[-1]


def test_a_configuration_fault_stops_the_stream_in_one_line(make_napari_viewer, qtbot,
                                                            source, tmp_path):
    """The oracle on frames without ground-truth labels: the stream stops at the first frame
    with one line (not one skipped line per frame)."""
    _viewer, widget, statuses = _dock(make_napari_viewer, disparity="estimate")
    live = tmp_path / "cam"
    live.mkdir()
    for index, frame in enumerate(frame_folders(source)):
        lf = read_video(source).frame(index)
        write_lightfield(replace(lf, labels=None, categories=None, disparity=None),
                         live / frame.name)
    follow = widget.follow
    follow.start(live, tmp_path / "out", auto=True)
    _ended(qtbot, widget)
    assert follow.report is None and not any("skipped" in line for line in statuses)
    assert "ground-truth labels" in statuses[-1] and "the stream stopped" in statuses[-1]
    assert "at frame_0000" in statuses[-1] and not (tmp_path / "out").exists()
