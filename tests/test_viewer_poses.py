"""The 3D dock's poses (docs/design.md section 12, "Viewer"): "Poses" registers every object
over a light-field video's frames in a thread of its own, draws each object's axes at the frame
on the slider and its path, and the slider moves the axes.

A tiny rigid-box video (3 frames of 3x3 views of 60x80, one box under known motion, its camera
in its scene files) with the ground-truth labels (shown frame by frame, or reopened as a saved
track) and the ground-truth disparity. Needs a display: run under ``xvfb-run``.
"""

from __future__ import annotations

import numpy as np
import pytest
from qtpy.QtCore import QTimer

from lfsam.metrics.pose import rotation_error_deg
from lfsam.poses import poses_of_video
from lfsam.result import SegmentationResult
from lfsam.synth.rigid import generate_rigid_video
from lfsam.video.io.result import load_video_result, video_result_writer
from lfsam.video.io.synth import write_video_frames
from lfsam.viewer import layers as L
from lfsam.viewer import pose_visuals as PV
from lfsam.viewer.objects3d_dock import ObjectsDock
from lfsam.viewer.widget import LightFieldWidget
from napari_events import register_plugin

TIMEOUT = 60_000
BOX = 2  # the box's label (the wall is 1)

register_plugin()


@pytest.fixture(scope="module")
def rigid(tmp_path_factory):
    """The video's frames (light fields with their truth) and its folder."""
    frames = list(generate_rigid_video(boxes=1, frames=3, grid=(3, 3), size=(60, 80), seed=0,
                                       box_size_m=(0.05, 0.07), texels=32))
    path = tmp_path_factory.mktemp("viewer_poses") / "boxes"
    write_video_frames(iter(frames), path)
    track = path.parent / "track"
    with video_result_writer(track) as writer:
        for lightfield in frames:
            writer.write(SegmentationResult(labels=lightfield.labels))
    return frames, path, track


def _origin(obj, frame):
    return next(f.pose for f in obj.frames if f.frame == frame)[:3, 3]


@pytest.mark.parametrize("masks", ["shown", "track"])
def test_poses_draw_axes_and_paths_and_the_frame_slider_moves_the_axes(
        make_napari_viewer, qtbot, rigid, masks):
    frames, path, track = rigid
    viewer = make_napari_viewer()
    viewer.open(str(path), plugin="lfsam")
    widget = LightFieldWidget(viewer, model="oracle", disparity="gt")
    viewer.window.add_dock_widget(widget)
    qtbot.waitUntil(lambda: widget.session.loaded and not widget.busy, timeout=TIMEOUT)
    assert widget.is_video
    if masks == "shown":  # the truth's masks, frame by frame as a running track shows them
        for index, lightfield in enumerate(frames):
            widget.masks.show_frame(index, lightfield.labels)
    else:  # a saved track reopened: its frames are read from its folder
        widget.show_tracked(load_video_result(track))
        qtbot.waitUntil(lambda: not widget.busy, timeout=TIMEOUT)
        assert widget.layers[L.COMMITTED].data.result is not None
        assert widget.layers[L.COMMITTED].data.written() == []
    dock = ObjectsDock(viewer)
    viewer.window.add_dock_widget(dock, name="lfsam 3D", area="right")
    assert dock.widget is widget and not dock.axes.visible and not dock.paths.visible

    ticks = []
    timer = QTimer()
    timer.timeout.connect(lambda: ticks.append(1))
    timer.start(5)
    dock.compute_poses()
    assert dock.running and not dock.poses_button.isEnabled()
    qtbot.waitUntil(lambda: not dock.running, timeout=TIMEOUT)
    timer.stop()
    assert dock.poses is not None, dock.status.text()
    assert "poses of 2 object(s) over 3 frame(s)" in dock.status.text()
    assert dock.poses_button.isEnabled() and len(ticks) >= 2  # the GUI ran meanwhile

    # the dock's poses are lfsam.poses' on the same masks, disparity and camera
    _, direct = poses_of_video([(SegmentationResult(labels=lf.labels), lf) for lf in frames],
                               disparity="gt")
    assert [o.object_id for o in dock.poses] == [o.object_id for o in direct] == [1, BOX]
    for mine, theirs in zip(dock.poses, direct, strict=True):
        for a, b in zip(mine.frames, theirs.frames, strict=True):
            assert a.status == b.status == "tracked"
            np.testing.assert_allclose(a.pose, b.pose, atol=1e-9)
    box = dock.poses[1]
    truth = [np.array(lf.meta["rigid"]["objects"][0]["pose"]) for lf in frames]
    for frame in (1, 2):  # the box's motion is the true one
        moved = truth[frame] @ np.linalg.inv(truth[0])
        assert rotation_error_deg(box.frames[frame].motion, moved) < 1.0

    # the axes at the frame shown (0), the paths through every frame
    assert dock.pose_frame == 0 and dock.axes.visible and dock.paths.visible
    assert dock.axes_vertices.shape == (12, 3)
    np.testing.assert_allclose(dock.axes_vertices[6], _origin(box, 0))
    np.testing.assert_allclose(
        dock.axes_vertices[6:],
        PV.axes_segments(box.frames[0].pose, dock.pose_lengths[BOX]))
    lengths = dock.pose_lengths[BOX]
    diameter = frames[0].meta["rigid"]["objects"][0]["diameter_m"]
    assert 0.01 < lengths.min() and lengths.max() < 1.5 * diameter  # the box's size
    shown = dock.paths.pos  # canvas coordinates of the paths' vertices
    np.testing.assert_allclose(
        shown[3:], PV.to_canvas(np.stack([_origin(box, f) for f in range(3)])), atol=1e-6)

    # the frame slider moves the axes to that frame's pose
    viewer.dims.current_step = (2, *viewer.dims.current_step[1:])
    assert dock.pose_frame == 2
    np.testing.assert_allclose(dock.axes_vertices[6], _origin(box, 2))
    assert np.linalg.norm(_origin(box, 2) - _origin(box, 0)) > 0.005  # it moved
    np.testing.assert_allclose(
        dock.axes_vertices[6:],
        PV.axes_segments(box.frames[2].pose, dock.pose_lengths[BOX]))
    viewer.dims.current_step = (1, *viewer.dims.current_step[1:])
    np.testing.assert_allclose(dock.axes_vertices[6], _origin(box, 1))


def test_a_single_light_field_gives_each_objects_first_pose(make_napari_viewer, qtbot, rigid):
    frames = rigid[0]
    lightfield = frames[0]
    viewer = make_napari_viewer()
    widget = LightFieldWidget(viewer, lightfield=lightfield, model="oracle", disparity="gt",
                              autoload=False)
    viewer.window.add_dock_widget(widget, name="lfsam")
    dock = ObjectsDock(viewer, widget)
    dock.compute_poses(block=True)
    assert dock.poses is None and "no object to pose" in dock.status.text()
    widget.masks.show_labels(L.COMMITTED, lightfield.labels)
    dock.compute_poses(block=True)
    assert dock.poses is not None and "over 1 frame(s)" in dock.status.text()
    box = dock.poses[1]
    assert box.object_id == BOX and len(box.frames) == 1
    np.testing.assert_allclose(box.frames[0].motion, np.eye(4))
    np.testing.assert_allclose(dock.axes_vertices[6], _origin(box, 0))
    assert dock.axes.visible and not dock.paths.visible  # one point is no path
