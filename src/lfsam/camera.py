"""The light-field camera: from disparity (pixels per view step) to metres (docs/design.md §11).

A light field's views are pinhole cameras of focal length ``f`` pixels on a regular grid with
spacing ``b`` metres (the baseline between neighbouring views), all looking along the same
direction; when the views are converged at a focus distance ``z0`` (the HCI 4D benchmark's
shifted sensors, a refocused plenoptic camera), points at ``z0`` have zero disparity. lfsam's
disparity ``d`` (docs/design.md section 1, larger = closer) then gives the depth

    z = f b / (d + f b / z0)        (z = f b / d for parallel views, no ``z0``)

which is the HCI 4D benchmark toolkit's ``disp2depth`` written in pixels and metres
(Honauer et al., ACCV 2016; its ``parameters.cfg`` gives ``f = focal_length_mm *
max(width, height) / sensor_size_mm`` and ``b = baseline_mm / 1000``).

Points are in the center view's camera frame: x right, y down, z forward (along the optical
axis), metres; pixel ``(u, v)`` (row, column) of the center view at depth ``z`` is at
``x = (v - c_x) z / f``, ``y = (u - c_y) z / f`` with the principal point ``(c_x, c_y)`` at the
view's middle ``((V - 1) / 2, (U - 1) / 2)`` unless given. A pixel of another view ``(s, t)``
is first moved to the center view by the package convention (``u + d (s - s_c)``,
``v + d (t - t_c)``, :mod:`lfsam.geometry`), which is the same point seen from the center.

A camera comes from a JSON file (``--camera CAMERA.json``)::

    {"focal_px": 700.0, "baseline_m": 0.01, "focus_distance_m": 1.2}

(``focus_distance_m`` may be absent or null for parallel views; ``principal_point_px``
``[c_x, c_y]`` is optional), from an HCI 4D scene's ``parameters.cfg`` (read by
:func:`lfsam.io.read_lightfield` into ``meta["parameters"]``) or from the ``camera`` an lfsam
scene folder carries (``lfsam synth`` writes one; :func:`camera_of`).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from lfsam.errors import LfsamError

__all__ = [
    "CAMERA_EXAMPLE",
    "Camera",
    "back_project",
    "camera_from_hci",
    "camera_of",
    "depth_from_disparity",
    "disparity_from_depth",
    "load_camera",
    "missing_camera_message",
    "synthetic_camera",
]

#: What a ``--camera`` file looks like (for error messages and ``--help``).
CAMERA_EXAMPLE = '{"focal_px": 700, "baseline_m": 0.01, "focus_distance_m": 1.2}'


@dataclass(frozen=True)
class Camera:
    """Pinhole views on a regular grid (module docstring).

    Attributes
    ----------
    focal_px : float
        Focal length in pixels (> 0).
    baseline_m : float
        Distance between neighbouring views in metres (> 0).
    focus_distance_m : float or None
        Distance at which the views converge (zero disparity); None for parallel views.
    principal_point_px : (c_x, c_y) or None
        Principal point of the center view (column, row); None: the view's middle.
    """

    focal_px: float
    baseline_m: float
    focus_distance_m: float | None = None
    principal_point_px: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        for name in ("focal_px", "baseline_m"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise LfsamError(f"camera {name} must be a positive number, got {value!r}")
        z0 = self.focus_distance_m
        if z0 is not None and not (isinstance(z0, (int, float)) and math.isfinite(z0) and z0 > 0):
            raise LfsamError(
                f"camera focus_distance_m must be a positive number or null, got {z0!r}"
            )

    @property
    def fb(self) -> float:
        """``f b`` in pixel-metres: depth times the disparity of parallel views."""
        return self.focal_px * self.baseline_m

    @property
    def zero_disparity_offset(self) -> float:
        """``f b / z0`` (0 for parallel views): the disparity a point at infinity has, negated."""
        return 0.0 if self.focus_distance_m is None else self.fb / self.focus_distance_m

    def principal_point(self, view_size: tuple[int, int]) -> tuple[float, float]:
        """``(c_x, c_y)`` for views of ``view_size`` (rows, columns)."""
        if self.principal_point_px is not None:
            return float(self.principal_point_px[0]), float(self.principal_point_px[1])
        return (view_size[1] - 1) / 2.0, (view_size[0] - 1) / 2.0

    def to_json(self) -> dict[str, Any]:
        """The JSON form (the ``--camera`` file's keys; absent optional keys left out)."""
        out = {key: value for key, value in asdict(self).items() if value is not None}
        if "principal_point_px" in out:
            out["principal_point_px"] = list(out["principal_point_px"])
        return out

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], where: str) -> Camera:
        """A camera from a ``--camera``-style mapping; ``where`` names it in errors."""
        if not isinstance(data, Mapping):
            raise LfsamError(f"{where} must be a JSON object like {CAMERA_EXAMPLE}")
        missing = [key for key in ("focal_px", "baseline_m") if data.get(key) is None]
        if missing:
            raise LfsamError(
                f"{where} lacks {', '.join(missing)}; a camera is {CAMERA_EXAMPLE} "
                "(focus_distance_m may be left out for parallel views)"
            )
        unknown = set(data) - {"focal_px", "baseline_m", "focus_distance_m", "principal_point_px"}
        if unknown:
            raise LfsamError(
                f"{where} has unknown keys {sorted(unknown)}; a camera is {CAMERA_EXAMPLE}"
            )
        point = data.get("principal_point_px")
        if point is not None:
            if not (isinstance(point, (list, tuple)) and len(point) == 2):
                raise LfsamError(f"{where}: principal_point_px must be [c_x, c_y] in pixels")
            point = (_number(point[0], where), _number(point[1], where))
        z0 = data.get("focus_distance_m")
        return cls(
            focal_px=_number(data["focal_px"], where),
            baseline_m=_number(data["baseline_m"], where),
            focus_distance_m=None if z0 is None else _number(z0, where),
            principal_point_px=point,
        )


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise LfsamError(f"{where}: {value!r} is not a number")
    return float(value)


def load_camera(path: str | os.PathLike) -> Camera:
    """Read a ``--camera`` JSON file (module docstring).

    Raises
    ------
    LfsamError
        If the file is missing, not JSON, or lacks ``focal_px`` or ``baseline_m``.
    """
    path = Path(path)
    if not path.is_file():
        raise LfsamError(f"camera file {str(path)!r} not found; write one like {CAMERA_EXAMPLE}")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise LfsamError(f"cannot read camera file {str(path)!r} ({exc})") from None
    return Camera.from_mapping(data, f"camera file {str(path)!r}")


def camera_from_hci(parameters: Mapping[str, Mapping[str, Any]]) -> Camera:
    """The camera of an HCI 4D scene from its parsed ``parameters.cfg``.

    ``f = focal_length_mm * max(image_resolution_x_px, image_resolution_y_px) /
    sensor_size_mm``, ``b = baseline_mm / 1000``, ``z0 = focus_distance_m`` (the benchmark
    toolkit's ``disp2depth``; Honauer et al., ACCV 2016).

    Raises
    ------
    LfsamError
        Naming the parameters missing from the file.
    """
    intrinsics = parameters.get("intrinsics", {})
    extrinsics = parameters.get("extrinsics", {})
    wanted = {
        "intrinsics.focal_length_mm": intrinsics.get("focal_length_mm"),
        "intrinsics.sensor_size_mm": intrinsics.get("sensor_size_mm"),
        "intrinsics.image_resolution_x_px": intrinsics.get("image_resolution_x_px"),
        "intrinsics.image_resolution_y_px": intrinsics.get("image_resolution_y_px"),
        "extrinsics.baseline_mm": extrinsics.get("baseline_mm"),
    }
    missing = [key for key, value in wanted.items() if not isinstance(value, (int, float))]
    if missing:
        raise LfsamError(
            f"parameters.cfg lacks {', '.join(missing)}; give --camera CAMERA.json instead "
            f"({CAMERA_EXAMPLE})"
        )
    resolution = max(wanted["intrinsics.image_resolution_x_px"],
                     wanted["intrinsics.image_resolution_y_px"])
    z0 = extrinsics.get("focus_distance_m")
    return Camera(
        focal_px=float(wanted["intrinsics.focal_length_mm"]) * resolution
        / float(wanted["intrinsics.sensor_size_mm"]),
        baseline_m=float(wanted["extrinsics.baseline_mm"]) / 1000.0,
        focus_distance_m=float(z0) if isinstance(z0, (int, float)) and z0 > 0 else None,
    )


def camera_of(meta: Mapping[str, Any]) -> Camera | None:
    """The camera a light field carries in its ``meta``: ``camera`` (an lfsam scene folder,
    ``lfsam synth``) or ``parameters`` (an HCI 4D scene's ``parameters.cfg``); None if neither.

    Raises
    ------
    LfsamError
        If the carried camera is incomplete or invalid (the message names what is missing).
    """
    if meta.get("camera") is not None:
        return Camera.from_mapping(meta["camera"], "the light field's camera")
    parameters = meta.get("parameters")
    if isinstance(parameters, Mapping) and parameters:
        return camera_from_hci(parameters)
    return None


def missing_camera_message(source: str) -> str:
    """The one line for a light field without camera parameters."""
    return (
        f"{source} carries no camera (focal_px and baseline_m are missing, focus_distance_m "
        f"optional); give --camera CAMERA.json with {CAMERA_EXAMPLE}"
    )


def synthetic_camera(size: tuple[int, int], disparity_range: tuple[float, float]) -> Camera:
    """The camera ``lfsam synth`` gives a synthetic scene: ``f`` = the view's larger side (a
    53-degree field of view across it), converged at ``z0 = 1`` m, and ``f b`` = twice the
    farthest disparity's magnitude (at least 1 px), so the farthest possible disparity lies at
    2 m and every disparity of the range maps to a finite, positive depth.

    Examples
    --------
    >>> cam = synthetic_camera((240, 320), (-2.0, 2.0))
    >>> cam.focal_px, cam.baseline_m, cam.focus_distance_m
    (320.0, 0.0125, 1.0)
    >>> float(depth_from_disparity(-2.0, cam)), round(float(depth_from_disparity(2.0, cam)), 4)
    (2.0, 0.6667)
    """
    focal = float(max(size))
    fb = 2.0 * max(-float(disparity_range[0]), 1.0)
    return Camera(focal_px=focal, baseline_m=fb / focal, focus_distance_m=1.0)


def depth_from_disparity(disparity, camera: Camera):
    """Depth ``z = f b / (d + f b / z0)`` in metres (module docstring).

    Parameters
    ----------
    disparity : float or array_like
        lfsam disparity, pixels per view step (larger = closer).
    camera : Camera

    Returns
    -------
    float ndarray (float64) of the same shape
        NaN where ``d + f b / z0 <= 0`` (at or beyond infinity: no finite depth).

    Examples
    --------
    >>> cam = Camera(focal_px=500.0, baseline_m=0.01, focus_distance_m=1.0)
    >>> float(depth_from_disparity(0.0, cam))  # zero disparity: the focus distance
    1.0
    >>> float(depth_from_disparity(5.0, cam))
    0.5
    """
    d = np.asarray(disparity, dtype=np.float64)
    denominator = d + camera.zero_disparity_offset
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = np.where(denominator > 0, camera.fb / denominator, np.nan)
    return depth


def disparity_from_depth(depth, camera: Camera):
    """The inverse of :func:`depth_from_disparity`: ``d = f b / z - f b / z0``."""
    z = np.asarray(depth, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(z > 0, camera.fb / z, np.nan) - camera.zero_disparity_offset


def back_project(
    rows,
    cols,
    disparity,
    camera: Camera,
    view_size: tuple[int, int],
    view_offset: tuple[float, float] = (0.0, 0.0),
) -> np.ndarray:
    """3D points (x right, y down, z forward; metres, center camera frame) of pixels.

    Parameters
    ----------
    rows, cols : array_like
        Pixel rows ``u`` and columns ``v`` in the view (sub-pixel allowed).
    disparity : array_like
        The pixels' disparity.
    camera : Camera
    view_size : (U, V)
        Rows and columns of a view (for the default principal point).
    view_offset : (s - s_c, t - t_c)
        The view's offset from the center view; its pixels are moved to the center view first
        (module docstring).

    Returns
    -------
    (N, 3) float64 ndarray
        NaN rows where the disparity has no finite depth.

    Examples
    --------
    >>> cam = Camera(focal_px=100.0, baseline_m=0.02)
    >>> back_project([4.5], [14.5], [2.0], cam, (10, 10)).tolist()  # z = 100 * 0.02 / 2 = 1
    [[0.1, 0.0, 1.0]]
    """
    u = np.asarray(rows, dtype=np.float64).reshape(-1)
    v = np.asarray(cols, dtype=np.float64).reshape(-1)
    d = np.asarray(disparity, dtype=np.float64).reshape(-1)
    z = depth_from_disparity(d, camera)
    u_c = u + d * view_offset[0]
    v_c = v + d * view_offset[1]
    cx, cy = camera.principal_point(view_size)
    return np.stack([(v_c - cx) * z / camera.focal_px, (u_c - cy) * z / camera.focal_px, z],
                    axis=1)
