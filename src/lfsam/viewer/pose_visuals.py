"""Pose axes and paths as vertex arrays for the viewer's 3D dock (Qt-free, plain arrays).

docs/design.md section 12 ("Viewer"). The "Objects in 3D" dock
(:mod:`lfsam.viewer.objects3d_dock`) draws, per object of :func:`lfsam.poses.poses_of_video`,

- its **axes** at the frame shown: three line segments from the pose's origin along the pose's
  x, y and z axes (the object's principal axes, largest variance first), coloured red, green and
  blue, each as long as the object reaches along it times :data:`AXIS_SCALE`
  (:func:`axis_lengths`), so the axes stick out of the object's surface;
- its **path**: the pose's origin at every frame it was found in, joined in frame order (lost
  frames, which have no pose, are left out).

Everything is in the center view's camera frame (x right, y down, z forward, metres);
:func:`to_canvas` maps it to the canvas' axes as the dock's point clouds are.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = [
    "AXIS_COLORS",
    "AXIS_SCALE",
    "axes_segments",
    "axis_lengths",
    "frame_axes",
    "path_points",
    "path_segments",
    "pose_at",
    "to_canvas",
]

#: RGBA of the x, y and z axes.
AXIS_COLORS = np.array([[1.0, 0.25, 0.25, 1.0], [0.25, 1.0, 0.25, 1.0], [0.35, 0.55, 1.0, 1.0]])
#: An axis is this many times as long as the object reaches along it.
AXIS_SCALE = 1.5
#: No axis shorter than this share of the longest (a flat object still shows its normal).
MIN_AXIS_SHARE = 0.3


def axis_lengths(xyz: np.ndarray, pose: np.ndarray, scale: float = AXIS_SCALE) -> np.ndarray:
    """How long to draw each axis of ``pose`` for an object whose points are ``xyz``.

    Parameters
    ----------
    xyz : ndarray, shape (N, 3)
        The object's points in the camera frame of ``pose`` (e.g. its keyframe model and its
        first pose, :meth:`lfsam.poses.PoseTracker.model_points`).
    pose : ndarray, shape (4, 4)
        Object frame to camera.
    scale : float

    Returns
    -------
    ndarray, shape (3,)
        ``scale`` times the farthest any point lies from the origin along each axis, at least
        :data:`MIN_AXIS_SHARE` of the longest; zeros without points.
    """
    xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
    if not len(xyz):
        return np.zeros(3)
    local = (xyz - pose[:3, 3]) @ pose[:3, :3]  # coordinates along the object's axes
    reach = np.abs(local).max(axis=0)
    return scale * np.maximum(reach, MIN_AXIS_SHARE * reach.max())


def axes_segments(pose: np.ndarray, lengths: Sequence[float] | np.ndarray) -> np.ndarray:
    """The three axes of ``pose`` as line segments: ``(6, 3)`` vertices, pairs ``(origin,
    origin + R[:, k] * lengths[k])`` for k = x, y, z (``pose = [R t; 0 1]``)."""
    pose = np.asarray(pose, dtype=np.float64)
    origin, rot = pose[:3, 3], pose[:3, :3]
    tips = origin + rot.T * np.asarray(lengths, dtype=np.float64)[:, None]  # row k: axis k
    return np.stack([np.broadcast_to(origin, (3, 3)), tips], axis=1).reshape(6, 3)


def pose_at(frames: Sequence[int], poses: Sequence[np.ndarray | None],
            frame: int) -> np.ndarray | None:
    """The pose at ``frame`` (None where the object is lost there or not yet seen)."""
    for index, pose in zip(frames, poses, strict=True):
        if int(index) == int(frame):
            return None if pose is None else np.asarray(pose, dtype=np.float64)
    return None


def path_points(frames: Sequence[int], poses: Sequence[np.ndarray | None]) -> np.ndarray:
    """The poses' origins ``(N, 3)`` in frame order, frames without a pose left out."""
    found = sorted((int(f), i) for i, (f, p) in enumerate(zip(frames, poses, strict=True))
                   if p is not None)
    if not found:
        return np.zeros((0, 3))
    return np.stack([np.asarray(poses[i], dtype=np.float64)[:3, 3] for _, i in found])


def frame_axes(tracks: Sequence[tuple[Sequence[int], Sequence[np.ndarray | None], np.ndarray]],
               frame: int) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Every object's axes at ``frame``.

    Parameters
    ----------
    tracks : sequence of (frames, poses, lengths)
        Per object its frame indices, its poses there (None where lost) and its axis lengths.
    frame : int

    Returns
    -------
    vertices : ndarray, shape (6 K, 3)
        :func:`axes_segments` of the K objects posed at ``frame``.
    colors : ndarray, shape (6 K, 4)
        :data:`AXIS_COLORS`, each for both ends of its axis.
    shown : list of int
        The indices into ``tracks`` of those K objects.
    """
    parts, shown = [], []
    for index, (frames, poses, lengths) in enumerate(tracks):
        pose = pose_at(frames, poses, frame)
        if pose is not None:
            parts.append(axes_segments(pose, lengths))
            shown.append(index)
    if not parts:
        return np.zeros((0, 3)), np.zeros((0, 4)), []
    colors = np.tile(np.repeat(AXIS_COLORS, 2, axis=0), (len(parts), 1))
    return np.concatenate(parts), colors, shown


def path_segments(paths: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Several paths as one line visual: ``vertices`` (N, 3) (the paths one after another),
    ``connect`` (E, 2) (vertex index pairs joining each path's consecutive points, never two
    paths) and ``owner`` (N,) (the index of each vertex's path)."""
    vertices, connect, owner, start = [], [], [], 0
    for index, path in enumerate(paths):
        path = np.asarray(path, dtype=np.float64).reshape(-1, 3)
        vertices.append(path)
        owner.append(np.full(len(path), index))
        steps = np.arange(start, start + len(path) - 1)
        connect.append(np.stack([steps, steps + 1], axis=1))
        start += len(path)
    if not start:
        return np.zeros((0, 3)), np.zeros((0, 2), np.int64), np.zeros(0, np.int64)
    return (np.concatenate(vertices), np.concatenate(connect).astype(np.int64).reshape(-1, 2),
            np.concatenate(owner).astype(np.int64))


def to_canvas(xyz: np.ndarray) -> np.ndarray:
    """Camera points ``(x, y, z)`` as the canvas shows them: ``(x, z, -y)`` float32 (vispy's
    up, ``+z``, is the image's up)."""
    xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
    return np.stack([xyz[:, 0], xyz[:, 2], -xyz[:, 1]], axis=1).astype(np.float32)
