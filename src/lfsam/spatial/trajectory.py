"""Objects over a light-field video's frames: positions and speeds (docs/design.md section 11).

An object's trajectory is its centroid (:class:`lfsam.spatial.ObjectMeasure`) in every frame
where it has confident points; its speed between two consecutive such frames is the distance
divided by the time between them (frames / ``fps``, or per frame without ``fps``). Frames
where the object is missing break nothing: the next speed spans the gap.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from lfsam.spatial.measure import ObjectMeasure

__all__ = ["Trajectory", "trajectories", "trajectories_csv"]


@dataclass
class Trajectory:
    """One object's path: ``frames`` (K,), ``positions`` (K, 3) metres, ``speeds`` (K,)
    (metres per second with ``fps``, else per frame; NaN for the first point)."""

    object_id: int
    category: str | None
    frames: np.ndarray
    positions: np.ndarray
    speeds: np.ndarray
    per_second: bool

    @property
    def path_length_m(self) -> float:
        """Total distance travelled, metres."""
        if len(self.positions) < 2:
            return 0.0
        return float(np.linalg.norm(np.diff(self.positions, axis=0), axis=1).sum())

    def to_json(self) -> dict[str, Any]:
        unit = "m/s" if self.per_second else "m/frame"
        return {
            "id": int(self.object_id),
            "category": self.category,
            "frames": self.frames.tolist(),
            "positions_m": np.round(self.positions, 6).tolist(),
            f"speed_{unit.replace('/', '_per_')}": [
                None if not np.isfinite(v) else round(float(v), 6) for v in self.speeds
            ],
            "path_length_m": round(self.path_length_m, 6),
        }


def trajectories(
    per_frame: Sequence[Sequence[ObjectMeasure]], fps: float | None = None
) -> list[Trajectory]:
    """Every object's trajectory over the frames, by id (module docstring).

    Examples
    --------
    >>> from lfsam.spatial.measure import ObjectMeasure
    >>> def at(z):
    ...     return ObjectMeasure(3, None, 10, 10, 1.0, np.array([0.0, 0.0, z]), z, None)
    >>> (path,) = trajectories([[at(1.0)], [at(1.5)], [at(2.5)]], fps=2.0)
    >>> path.speeds.tolist()
    [nan, 1.0, 2.0]
    """
    found: dict[int, list[tuple[int, ObjectMeasure]]] = {}
    for frame, measures in enumerate(per_frame):
        for measure in measures:
            if measure.points and np.isfinite(measure.centroid_m).all():
                found.setdefault(measure.object_id, []).append((frame, measure))
    out = []
    step = 1.0 if fps is None else 1.0 / float(fps)
    for obj_id in sorted(found):
        frames = np.array([frame for frame, _ in found[obj_id]])
        positions = np.stack([m.centroid_m for _, m in found[obj_id]])
        speeds = np.full(len(frames), np.nan)
        if len(frames) > 1:
            distance = np.linalg.norm(np.diff(positions, axis=0), axis=1)
            speeds[1:] = distance / (np.diff(frames) * step)
        category = next((m.category for _, m in found[obj_id] if m.category), None)
        out.append(Trajectory(obj_id, category, frames, positions, speeds, fps is not None))
    return out


def trajectories_csv(paths: Sequence[Trajectory]) -> str:
    """One row per object and frame: ``id, category, frame, x_m, y_m, z_m, speed``."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    unit = "m_per_s" if paths and paths[0].per_second else "m_per_frame"
    writer.writerow(["id", "category", "frame", "x_m", "y_m", "z_m", f"speed_{unit}"])
    for path in paths:
        for frame, position, speed in zip(path.frames, path.positions, path.speeds, strict=True):
            writer.writerow([path.object_id, path.category or "", int(frame),
                             *(f"{v:.6f}" for v in position),
                             "" if not np.isfinite(speed) else f"{speed:.6f}"])
    return buffer.getvalue()
