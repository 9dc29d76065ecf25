"""The 3D dock's pose axes and paths as vertex arrays (docs/design.md section 12, "Viewer";
:mod:`lfsam.viewer.pose_visuals`): plain arrays, no Qt."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from lfsam.synth.rigid import box_surface_points, rotation_about
from lfsam.viewer import pose_visuals as PV

unit = st.floats(-1.0, 1.0, allow_nan=False)


def _pose(axis, angle, shift) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = rotation_about(np.asarray(axis) + np.array([0.0, 0.0, 1e-3]), angle)
    pose[:3, 3] = shift
    return pose


@settings(max_examples=30, deadline=None)
@given(axis=st.tuples(unit, unit, unit), angle=st.floats(-3.1, 3.1),
       shift=st.tuples(unit, unit, st.floats(0.3, 3.0)),
       lengths=st.tuples(*[st.floats(1e-3, 0.5)] * 3))
def test_axes_run_from_the_origin_along_each_column_of_r(axis, angle, shift, lengths):
    pose = _pose(axis, angle, shift)
    vertices = PV.axes_segments(pose, lengths)
    assert vertices.shape == (6, 3)
    for k in range(3):
        np.testing.assert_allclose(vertices[2 * k], pose[:3, 3], atol=1e-12)
        np.testing.assert_allclose(vertices[2 * k + 1], pose[:3, 3] + pose[:3, k] * lengths[k],
                                   atol=1e-12)
        assert np.isclose(np.linalg.norm(vertices[2 * k + 1] - vertices[2 * k]), lengths[k])


def test_axis_lengths_follow_the_objects_reach_along_its_axes():
    half = np.array([0.06, 0.04, 0.025])
    pose = _pose((0.3, -0.5, 0.8), 0.7, (0.1, -0.05, 1.0))
    local = box_surface_points(2 * half, 0.004)  # a box centred on its own frame's origin
    xyz = local @ pose[:3, :3].T + pose[:3, 3]
    np.testing.assert_allclose(PV.axis_lengths(xyz, pose), PV.AXIS_SCALE * half, rtol=1e-9)
    flat = np.array([0.06, 0.04, 0.001])
    lengths = PV.axis_lengths(box_surface_points(2 * flat, 0.004), np.eye(4), scale=1.0)
    np.testing.assert_allclose(lengths, [0.06, 0.04, PV.MIN_AXIS_SHARE * 0.06])
    assert np.array_equal(PV.axis_lengths(np.zeros((0, 3)), pose), np.zeros(3))


def test_path_is_the_origins_in_frame_order_without_lost_frames():
    rng = np.random.default_rng(0)
    poses = [_pose(rng.normal(size=3), rng.uniform(-1, 1), rng.normal(size=3)) for _ in range(6)]
    frames = [4, 0, 5, 2, 1, 3]  # not in order
    shown = [poses[i] for i in range(6)]
    shown[2] = None  # frame 5 lost
    shown[4] = None  # frame 1 lost
    path = PV.path_points(frames, shown)
    expected = [poses[frames.index(f)][:3, 3] for f in (0, 2, 3, 4)]
    np.testing.assert_array_equal(path, np.stack(expected))
    assert PV.path_points([0, 1], [None, None]).shape == (0, 3)
    assert PV.pose_at(frames, shown, 5) is None and PV.pose_at(frames, shown, 9) is None
    np.testing.assert_array_equal(PV.pose_at(frames, shown, 3), poses[5])


def test_frame_axes_show_only_the_objects_posed_at_that_frame():
    a, b = _pose((1, 0, 0), 0.3, (0, 0, 1)), _pose((0, 1, 0), -0.2, (0.1, 0, 1.2))
    tracks = [([0, 1, 2], [a, None, a], np.array([0.1, 0.05, 0.02])),
              ([1, 2], [b, b], np.array([0.2, 0.2, 0.2]))]
    vertices, colors, shown = PV.frame_axes(tracks, 1)
    assert shown == [1]
    np.testing.assert_allclose(vertices, PV.axes_segments(b, [0.2, 0.2, 0.2]))
    np.testing.assert_array_equal(colors, np.repeat(PV.AXIS_COLORS, 2, axis=0))
    vertices, colors, shown = PV.frame_axes(tracks, 2)
    assert shown == [0, 1] and vertices.shape == (12, 3) and colors.shape == (12, 4)
    np.testing.assert_allclose(vertices[:6], PV.axes_segments(a, tracks[0][2]))
    assert PV.frame_axes(tracks, 7)[0].shape == (0, 3)


def test_path_segments_join_each_paths_points_and_never_two_paths():
    first = np.arange(9.0).reshape(3, 3)
    single = np.ones((1, 3))
    second = -np.arange(6.0).reshape(2, 3)
    vertices, connect, owner = PV.path_segments([first, single, second])
    np.testing.assert_array_equal(vertices, np.concatenate([first, single, second]))
    assert connect.tolist() == [[0, 1], [1, 2], [4, 5]]
    assert owner.tolist() == [0, 0, 0, 1, 2, 2]
    empty = PV.path_segments([])
    assert empty[0].shape == (0, 3) and empty[1].shape == (0, 2) and empty[2].shape == (0,)


def test_the_canvas_shows_camera_up_as_its_up():
    xyz = np.array([[0.1, -0.2, 1.5]])  # y down in the camera: -0.2 is up
    np.testing.assert_allclose(PV.to_canvas(xyz), [[0.1, 1.5, 0.2]], rtol=1e-6)
