"""Where an object should be in a frame, from its motion so far (issue 64; docs/design.md
section 12, "Poses through occlusions"): constant velocity in SE(3), carried through the frames
the object was hidden in."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["predict_motion"]


def predict_motion(motions: Sequence[np.ndarray], frames: Sequence[int], frame: int,
                   centre: np.ndarray | None = None) -> np.ndarray:
    """The motion (4x4) expected at ``frame`` from ``motions`` registered at ``frames``
    (ascending, the last before ``frame``), at constant velocity: the last frame-to-frame
    turn repeated once per frame since the last registration, about the object's own
    ``centre`` (its first frame's centroid, which each motion carries along), and the centre
    moving on by its last frame-to-frame shift each frame (a free body's centre of mass goes
    straight while it spins about it). Without ``centre``, the last step is repeated as a
    whole (a screw about a fixed axis in the camera's frame). Where the last two registrations
    are not consecutive frames, the last motion (no velocity is known).

    Examples
    --------
    >>> step = np.eye(4); step[0, 3] = 0.01
    >>> predict_motion([np.eye(4), step], [0, 1], 4)[0, 3].round(6)  # 3 frames on
    np.float64(0.04)
    """
    last = np.asarray(motions[-1], dtype=np.float64)
    gap = int(frame) - int(frames[-1])
    if len(motions) < 2 or int(frames[-1]) - int(frames[-2]) != 1 or gap < 1:
        return last.copy()
    before = np.asarray(motions[-2], dtype=np.float64)
    if centre is None:
        step = last @ np.linalg.inv(before)
        return np.linalg.matrix_power(step, gap) @ last
    c0 = np.asarray(centre, dtype=np.float64)
    c_last, c_before = last[:3, :3] @ c0 + last[:3, 3], before[:3, :3] @ c0 + before[:3, 3]
    turn = np.linalg.matrix_power(last[:3, :3] @ before[:3, :3].T, gap)
    out = np.eye(4)
    out[:3, :3] = turn @ last[:3, :3]
    out[:3, 3] = c_last + gap * (c_last - c_before) - out[:3, :3] @ c0
    return out
