"""Where an object is and how big it is, from its 3D points (docs/design.md section 11).

``centroid_m`` is the mean of the object's confident points, ``median_depth_m`` their median z.
The extent is an oriented box on the points' principal axes (the eigenvectors of their
covariance, largest variance first, signs fixed so each axis' largest component is positive
and the frame right-handed); along each axis the box spans the 2nd to the 98th percentile of
the points, so a few stray points (a mislabelled edge pixel carried to the background's depth)
do not stretch it. With a reference disparity (the ground truth) of the same pixels, the depth
errors are the median of the per-point absolute depth errors and the relative error of the
median depth.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from lfsam.camera import Camera, depth_from_disparity
from lfsam.spatial.points import ObjectPoints

__all__ = ["BOX_PERCENTILES", "ObjectMeasure", "OrientedBox", "measure_object", "oriented_box"]

#: The box spans these percentiles of the points along each principal axis.
BOX_PERCENTILES = (2.0, 98.0)


@dataclass(frozen=True)
class OrientedBox:
    """A box on principal axes: ``center`` (3,), ``axes`` (3, 3) rows = unit axes, ``size``
    (3,) full edge lengths along them, metres."""

    center: np.ndarray
    axes: np.ndarray
    size: np.ndarray

    def to_json(self) -> dict[str, Any]:
        return {"center_m": _round(self.center), "axes": _round(self.axes, 6),
                "size_m": _round(self.size)}


def _round(array: np.ndarray, digits: int = 5) -> list:
    return np.round(np.asarray(array, dtype=np.float64), digits).tolist()


def oriented_box(xyz: np.ndarray) -> OrientedBox | None:
    """The oriented box of ``(N, 3)`` points (module docstring); None for fewer than 3 points.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> points = rng.uniform([-2, -0.5, -0.1], [2, 0.5, 0.1], (5000, 3))
    >>> box = oriented_box(points)
    >>> np.round(box.size, 1).tolist(), np.round(np.abs(box.axes[0]), 1).tolist()
    ([3.8, 1.0, 0.2], [1.0, 0.0, 0.0])
    """
    xyz = np.asarray(xyz, dtype=np.float64)
    if len(xyz) < 3:
        return None
    mean = xyz.mean(axis=0)
    centered = xyz - mean
    _, vectors = np.linalg.eigh(centered.T @ centered)
    axes = vectors[:, ::-1].T.copy()  # rows, largest variance first
    for row in axes[:2]:
        if row[np.argmax(np.abs(row))] < 0:
            row *= -1
    axes[2] = np.cross(axes[0], axes[1])
    coords = centered @ axes.T
    low, high = np.percentile(coords, BOX_PERCENTILES, axis=0)
    return OrientedBox(center=mean + ((low + high) / 2) @ axes, axes=axes, size=high - low)


@dataclass
class ObjectMeasure:
    """One object's position and size (module docstring). NaN / None where it has no points."""

    object_id: int
    category: str | None
    pixels: int
    points: int
    confident_share: float
    centroid_m: np.ndarray
    median_depth_m: float
    box: OrientedBox | None
    gt_median_depth_m: float | None = None
    median_abs_depth_error_m: float | None = None
    median_depth_relative_error: float | None = None

    def to_json(self) -> dict[str, Any]:
        """JSON-ready (NaN as null)."""

        def number(value):
            return None if value is None or not np.isfinite(value) else round(float(value), 6)

        out = {
            "id": int(self.object_id),
            "category": self.category,
            "pixels": int(self.pixels),
            "points": int(self.points),
            "confident_share": number(self.confident_share),
            "centroid_m": [number(v) for v in self.centroid_m],
            "median_depth_m": number(self.median_depth_m),
            "extent": None if self.box is None else self.box.to_json(),
        }
        if self.gt_median_depth_m is not None:
            out.update(
                gt_median_depth_m=number(self.gt_median_depth_m),
                median_abs_depth_error_m=number(self.median_abs_depth_error_m),
                median_depth_relative_error=number(self.median_depth_relative_error),
            )
        return out


def measure_object(
    points: ObjectPoints, camera: Camera, category: str | None = None
) -> ObjectMeasure:
    """Measure one object from its points (module docstring)."""
    xyz = points.xyz
    empty = len(xyz) == 0
    centroid = np.full(3, np.nan) if empty else xyz.mean(axis=0)
    median_depth = float("nan") if empty else float(np.median(xyz[:, 2]))
    measure = ObjectMeasure(
        object_id=points.object_id,
        category=category,
        pixels=points.pixels,
        points=len(xyz),
        confident_share=points.confident_share,
        centroid_m=centroid,
        median_depth_m=median_depth,
        box=oriented_box(xyz),
    )
    if points.reference_disparity is not None:
        truth = depth_from_disparity(points.reference_disparity, camera)
        valid = np.isfinite(truth)
        if valid.any():
            gt_median = float(np.median(truth[valid]))
            measure.gt_median_depth_m = gt_median
            measure.median_abs_depth_error_m = float(
                np.median(np.abs(xyz[valid, 2] - truth[valid]))
            )
            measure.median_depth_relative_error = abs(median_depth - gt_median) / gt_median
        else:
            measure.gt_median_depth_m = float("nan")
    return measure
