"""Where an object should be in a frame, from its motion so far (issue 64; docs/design.md
section 12, "Poses through occlusions"): constant velocity in SE(3), carried through the frames
the object was hidden in."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["predict_motion"]


def predict_motion(motions: Sequence[np.ndarray], frames: Sequence[int], frame: int
                   ) -> np.ndarray:
    """The motion (4x4) expected at ``frame`` from ``motions`` registered at ``frames``
    (ascending, the last before ``frame``): the last frame-to-frame step repeated once per frame
    since the last registration (constant velocity in SE(3)); where the last two registrations
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
    step = last @ np.linalg.inv(np.asarray(motions[-2], dtype=np.float64))
    return np.linalg.matrix_power(step, gap) @ last
