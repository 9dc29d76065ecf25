"""6D pose accuracy: ADD and rotation error (docs/design.md section 12).

ADD (Hinterstoisser et al., ACCV 2012) is the mean distance between an object's model points
moved by the estimated and by the true transform; it is reported as a share of the object's
diameter, and a pose counts as correct at ``ADD < 0.1 d`` (ADD-0.1d recall). The rotation error
is the angle of ``R_est R_true^T``. Plain arrays in and out.
"""

from __future__ import annotations

import numpy as np

__all__ = ["add_error", "add_recall", "rotation_error_deg"]


def add_error(points: np.ndarray, estimated: np.ndarray, true: np.ndarray) -> float:
    """Mean distance between ``points`` (N, 3) moved by the 4x4 ``estimated`` and ``true``.

    Examples
    --------
    >>> shift = np.eye(4); shift[0, 3] = 0.01
    >>> add_error(np.zeros((4, 3)), shift, np.eye(4))
    0.01
    """
    points = np.asarray(points, dtype=np.float64)
    a = points @ np.asarray(estimated)[:3, :3].T + np.asarray(estimated)[:3, 3]
    b = points @ np.asarray(true)[:3, :3].T + np.asarray(true)[:3, 3]
    return float(np.linalg.norm(a - b, axis=1).mean())


def rotation_error_deg(estimated: np.ndarray, true: np.ndarray) -> float:
    """The angle (degrees) of the rotation between two 4x4 or 3x3 transforms."""
    rot = np.asarray(estimated)[:3, :3] @ np.asarray(true)[:3, :3].T
    return float(np.degrees(np.arccos(np.clip((np.trace(rot) - 1) / 2, -1.0, 1.0))))


def add_recall(add_share: np.ndarray, threshold: float = 0.1) -> float:
    """The share of ADD values (as shares of the diameter) below ``threshold`` (NaN: a miss)."""
    add_share = np.asarray(add_share, dtype=np.float64)
    return float(np.mean(np.nan_to_num(add_share, nan=np.inf) < threshold))
