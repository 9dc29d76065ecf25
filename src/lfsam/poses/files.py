"""The poses written out (:mod:`lfsam.poses`): :func:`poses_json` (``lfsam poses``' JSON),
:func:`poses_csv` (one row per object and frame, the rotation as a quaternion) and
:func:`bop_csv` (the BOP challenge's format).
"""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence
from typing import Any

import numpy as np

from lfsam.camera import Camera
from lfsam.poses.tracker import ObjectPoses

__all__ = ["bop_csv", "poses_csv", "poses_json"]


def poses_json(camera: Camera, objects: Sequence[ObjectPoses], **extra: Any) -> dict[str, Any]:
    """The ``--json`` document: ``{"camera", "frame", "objects": [{"id", "category",
    "first_pose", "frames": [...]}]}`` plus ``extra`` keys."""
    return {"camera": camera.to_json(),
            "frame": "center view camera: x right, y down, z forward, metres; pose = object "
                     "frame (origin: first frame's centroid, axes: its principal axes) to camera; "
                     "motion = pose @ inverse(first_pose)",
            **extra, "objects": [o.to_json() for o in objects]}


def _quaternion(rot: np.ndarray) -> np.ndarray:
    """Unit quaternion ``(w, x, y, z)`` with ``w >= 0`` of a rotation matrix."""
    m = rot
    candidates = np.array([
        [1 + m[0, 0] + m[1, 1] + m[2, 2], m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]],
        [m[2, 1] - m[1, 2], 1 + m[0, 0] - m[1, 1] - m[2, 2], m[0, 1] + m[1, 0], m[0, 2] + m[2, 0]],
        [m[0, 2] - m[2, 0], m[0, 1] + m[1, 0], 1 - m[0, 0] + m[1, 1] - m[2, 2], m[1, 2] + m[2, 1]],
        [m[1, 0] - m[0, 1], m[0, 2] + m[2, 0], m[1, 2] + m[2, 1], 1 - m[0, 0] - m[1, 1] + m[2, 2]],
    ])
    q = candidates[int(np.argmax(np.diag(candidates)))]
    q = q / np.linalg.norm(q)
    return -q if q[0] < 0 else q


def poses_csv(objects: Sequence[ObjectPoses]) -> str:
    """One row per object and frame: ``id, category, frame, status, qw, qx, qy, qz, x_m, y_m,
    z_m`` (the pose) then the motion's ``motion_qw .. motion_z_m``, ``inliers, rmse_m``;
    empty cells where the object is lost."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["id", "category", "frame", "status", "qw", "qx", "qy", "qz", "x_m", "y_m",
                     "z_m", "motion_qw", "motion_qx", "motion_qy", "motion_qz", "motion_x_m",
                     "motion_y_m", "motion_z_m", "inliers", "rmse_m"])
    for obj in objects:
        for entry in obj.frames:
            cells = []
            for matrix in (entry.pose, entry.motion):
                if matrix is None:
                    cells += [""] * 7
                else:
                    cells += [f"{v:.9f}" for v in _quaternion(matrix[:3, :3])]
                    cells += [f"{v:.6f}" for v in matrix[:3, 3]]
            quality = ["" if x is None or not np.isfinite(x) else f"{x:.6g}"
                       for x in (entry.inliers, entry.rmse_m)]
            writer.writerow([obj.object_id, obj.category or "", entry.frame, entry.status,
                             *cells, *quality])
    return buffer.getvalue()


def bop_csv(objects: Sequence[ObjectPoses], scene_id: int = 0) -> str:
    """The BOP challenge's results CSV (``scene_id,im_id,obj_id,score,R,t,time``: R row-major
    and t in millimetres, space-separated; time in seconds, the same for every estimate of an
    image, -1 where unknown), one row per tracked object and frame (Hodaň et al., BOP 2020)."""
    lines = ["scene_id,im_id,obj_id,score,R,t,time"]
    per_frame: dict[int, float] = {}
    for obj in objects:
        for entry in obj.frames:
            per_frame[entry.frame] = per_frame.get(entry.frame, 0.0) + entry.seconds
    rows = []
    for obj in objects:
        for entry in obj.frames:
            if entry.pose is None:
                continue
            rot = " ".join(f"{v:.9f}" for v in entry.pose[:3, :3].ravel())
            trans = " ".join(f"{v:.4f}" for v in entry.pose[:3, 3] * 1000.0)
            score = entry.inliers if entry.inliers is not None else 1.0
            rows.append((entry.frame, obj.object_id,
                         f"{scene_id},{entry.frame},{obj.object_id},{score:.4f},{rot},{trans},"
                         f"{per_frame[entry.frame]:.4f}"))
    lines += [row for _, _, row in sorted(rows)]
    return "\n".join(lines) + "\n"
