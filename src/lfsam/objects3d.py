"""Segmented objects in 3D: one entry point over a result and its light field (docs/design.md §11).

:func:`objects_in_3d` turns a segmentation result into metres: for every object its coloured
point cloud (:func:`lfsam.spatial.object_points` on the center view, or on every view with
``views="all"``) and its measures (:func:`lfsam.spatial.measure_object`: centroid, median
depth, oriented box, the share of confident pixels, and depth errors against the light field's
ground-truth disparity when it has one and another disparity was used).
:func:`objects_over_video` does it per frame of a light-field video and adds each object's 3D
trajectory and speed (:func:`lfsam.spatial.trajectories`).

The disparity is the default estimator's **with** its structure-tensor fusion
(:func:`lfsam.disparity.estimate_disparity`, the lower depth error; docs/design.md section 3.2)
and its confidence, each object whose inside shows something else than its surface (glass,
mirror: :func:`lfsam.disparity.non_lambertian.surface_disparity`) given its silhouette's depth
there, the ground truth (``"gt"``, every pixel confident), or a map (a ``.npy``
file or an array, every pixel confident). The camera is given (:class:`lfsam.camera.Camera` or
a ``--camera`` JSON path) or the one the light field carries (:func:`lfsam.camera.camera_of`).
"""

from __future__ import annotations

import json
import os
import weakref
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from lfsam.camera import (
    Camera,
    camera_from_hci,
    camera_of,
    load_camera,
    missing_camera_message,
)
from lfsam.disparity.methods import estimate_disparity
from lfsam.disparity.non_lambertian import surface_disparity_of_view
from lfsam.disparity.range import estimate_disparity_range
from lfsam.disparity.source import load_disparity_spec, resolve_view_disparity
from lfsam.errors import LfsamError
from lfsam.export.folder import atomic_folder
from lfsam.io.hci4d import read_parameters
from lfsam.lightfield import LightField, check_result_shape
from lfsam.result import SegmentationResult
from lfsam.spatial import (
    MIN_CONFIDENCE,
    ObjectMeasure,
    ObjectPoints,
    Trajectory,
    measure_object,
    merge_points,
    object_points,
    trajectories,
    write_ply,
)
from lfsam.version import __version__

__all__ = [
    "VIEWS",
    "Objects3D",
    "ViewEstimates",
    "estimates_for",
    "export_point_clouds",
    "format_table",
    "objects_in_3d",
    "objects_over_video",
    "resolve_camera",
]

#: Which views' pixels make the points: the center view's, or every present view's.
VIEWS = ("center", "all")


@dataclass
class Objects3D:
    """The objects of one light field in 3D.

    Attributes
    ----------
    camera : Camera
    clouds : dict of id to ObjectPoints
        Each object's confident points (center camera frame, metres).
    measures : list of ObjectMeasure
        In id order.
    disparity_source : str
        Where the disparity came from (``"estimate"``, ``"gt"``, ``"file:PATH"``, ``"array"``).
    views : {"center", "all"}
    min_confidence : float
    """

    camera: Camera
    clouds: dict[int, ObjectPoints]
    measures: list[ObjectMeasure]
    disparity_source: str
    views: str
    min_confidence: float

    def to_json(self) -> dict[str, Any]:
        """The measures and how they were made, JSON-ready."""
        return {
            "camera": self.camera.to_json(),
            "frame": "center view camera: x right, y down, z forward, metres",
            "disparity": self.disparity_source,
            "views": self.views,
            "min_confidence": self.min_confidence,
            "objects": [m.to_json() for m in self.measures],
        }


def resolve_camera(
    lightfield: LightField, camera: Camera | str | os.PathLike | None = None
) -> Camera:
    """The camera to use: ``camera`` (a Camera or a ``--camera`` JSON path), else the light
    field's own (:func:`lfsam.camera.camera_of`), else an HCI-style ``parameters.cfg`` beside
    the light field (in its folder, or next to its file; any format).

    Raises
    ------
    LfsamError
        One line naming the missing parameters when none gives a camera.
    """
    if isinstance(camera, Camera):
        return camera
    if camera is not None:
        return load_camera(camera)
    found = camera_of(lightfield.meta)
    if found is not None:
        return found
    source = lightfield.meta.get("source")
    if source:
        path = Path(str(source))
        cfg = (path if path.is_dir() else path.parent) / "parameters.cfg"
        if cfg.is_file():
            return camera_from_hci(read_parameters(cfg))
    raise LfsamError(missing_camera_message(str(source or "the light field")))


def _categories(result: SegmentationResult) -> dict[int, str]:
    raw = result.meta.get("categories") or {}
    return {int(key): str(value) for key, value in raw.items() if value}


class ViewEstimates:
    """The disparity estimates of one light field's views, each computed once and kept
    (issue 46; docs/design.md section 11).

    The scene's disparity range is found once, in the center view, and searched in every view
    (a scene point has one disparity in all of them); a view asked for again is not estimated
    again. :func:`objects_in_3d` keeps the last light field's set, so a second call on it (the
    viewer's 3D dock after each mask change, ``lfsam export`` of another format) estimates
    nothing.

    Parameters
    ----------
    lightfield : LightField
    device : str, optional
        For the estimates.

    Attributes
    ----------
    estimated : int
        How many views were estimated so far.
    """

    def __init__(self, lightfield: LightField, device: str | None = None) -> None:
        self.lightfield, self.device = lightfield, device
        self.disparity_range: tuple[float, float] | None = None
        self.estimated = 0
        self._views: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}

    def __call__(self, view: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        """``(disparity, confidence)`` of ``view``, estimated on the first call only."""
        view = (int(view[0]), int(view[1]))
        if view not in self._views:
            lf = self.lightfield
            if self.disparity_range is None:
                self.disparity_range = estimate_disparity_range(lf, device=self.device,
                                                                view=lf.center)
            estimate = estimate_disparity(lf, self.disparity_range, device=self.device,
                                          view=view)
            self._views[view] = (np.asarray(estimate.disparity),
                                 np.asarray(estimate.confidence))
            self.estimated += 1
        return self._views[view]


#: The last light field's :class:`ViewEstimates` (a weak reference to it, the device, the set).
_last_estimates: list[tuple[Any, str | None, ViewEstimates]] = []


def estimates_for(lightfield: LightField, device: str | None = None) -> ViewEstimates:
    """The kept :class:`ViewEstimates` of ``lightfield`` (the same object) and ``device``, or a
    new set that replaces it."""
    for ref, dev, estimates in _last_estimates:
        if ref() is lightfield and dev == device:
            return estimates
    estimates = ViewEstimates(lightfield, device)
    _last_estimates[:] = [(weakref.ref(lightfield), device, estimates)]
    return estimates


def _view_disparity(spec, lightfield: LightField, view, device, name: str,
                    estimates: ViewEstimates | None, labels=None, ids=(), surface: bool = True):
    """(disparity, confidence or None) of one view; an estimate gets its glass and mirror
    objects' surface depth from their silhouettes (``labels``, ``ids``;
    :func:`lfsam.disparity.non_lambertian.surface_disparity`)."""
    if isinstance(spec, str) and spec == "estimate":
        disparity, confidence = (estimates or estimates_for(lightfield, device))(view)
        if not (surface and len(ids)):
            return disparity, confidence
        confidence = np.array(confidence, dtype=np.float32)  # the kept estimate stays as it is
        masks = np.stack([labels == i for i in ids])
        disparity, _ = surface_disparity_of_view(
            lightfield.views, view, disparity, masks, lightfield.present,
            device=device, confidence=confidence,
        )
        return disparity, confidence
    disparity, _, _ = resolve_view_disparity(spec, lightfield, view=view, device=device,
                                             name=name)
    return np.asarray(disparity), None


def objects_in_3d(
    result: SegmentationResult,
    lightfield: LightField,
    *,
    disparity: str | os.PathLike | np.ndarray = "estimate",
    camera: Camera | str | os.PathLike | None = None,
    views: str = "center",
    min_confidence: float = MIN_CONFIDENCE,
    device: str | None = None,
    progress: Callable[[Iterable], Iterable] | None = None,
    estimates: ViewEstimates | None = None,
    surface_depth: bool = True,
) -> Objects3D:
    """Every object of ``result`` as points and measures in metres (module docstring).

    Parameters
    ----------
    result : SegmentationResult
        Labels ``[S, T, U, V]`` of ``lightfield`` (object id = label).
    lightfield : LightField
    disparity : {"estimate", "gt"}, .npy path or ndarray
        The disparity source (``(U, V)`` center or ``(S, T, U, V)`` map).
    camera : Camera, path to a ``--camera`` JSON, or None (the light field's own)
    views : {"center", "all"}
        ``"all"`` adds every present view's pixels (moved to the center camera frame): objects
        the center view does not see get points too. With ``"estimate"`` that is one disparity
        estimate per view (slow; each view's kept for the next call on the same light field:
        :class:`ViewEstimates`); a ground truth or an ``(S, T, U, V)`` map of every view costs
        nothing more.
    min_confidence : float
        Pixels whose disparity confidence is below this are left out (estimates only).
    device : str, optional
        For the disparity estimate.
    progress : callable, optional
        Wraps the iterable of views (e.g. ``tqdm``) with ``views="all"``.
    estimates : ViewEstimates, optional
        The estimates to use and fill (default: the set kept for ``lightfield``).
    surface_depth : bool
        With ``"estimate"``: glass and mirror objects get their silhouette's depth inside
        (:func:`lfsam.disparity.non_lambertian.surface_disparity`; docs/design.md section 3.2).

    Returns
    -------
    Objects3D

    Raises
    ------
    LfsamError
        Mismatched result, no camera, or a bad disparity source.

    Examples
    --------
    >>> from lfsam.synth import generate_scene
    >>> lf = generate_scene(grid=(3, 3), size=(48, 64), seed=0, num_objects=2)
    >>> found = objects_in_3d(SegmentationResult(labels=lf.labels), lf, disparity="gt")
    >>> [m.object_id for m in found.measures], found.measures[0].median_depth_m > 0
    ([1, 2, 3], True)
    """
    if views not in VIEWS:
        raise LfsamError(f"views must be one of {VIEWS}, got {views!r}")
    check_result_shape(result.labels.shape, lightfield, "the result")
    cam = resolve_camera(lightfield, camera)
    spec, name = load_disparity_spec(disparity, lightfield)
    present = lightfield.present & result.present_mask
    ids = np.unique(result.labels[present])
    ids = [int(i) for i in ids if i != 0]
    center = lightfield.center
    chosen = [center] if views == "center" else [tuple(int(x) for x in v)
                                                 for v in np.argwhere(present)]
    chosen = [v for v in chosen if (result.labels[v] != 0).any()] or [center]
    has_truth = lightfield.disparity is not None and name != "gt"
    parts: dict[int, list[ObjectPoints]] = {i: [] for i in ids}
    for view in progress(chosen) if progress is not None else chosen:
        disp, confidence = _view_disparity(spec, lightfield, view, device, name, estimates,
                                           result.labels[view], ids, surface_depth)
        truth = None
        if has_truth:
            truth, _, _ = resolve_view_disparity("gt", lightfield, view=view, device=device)
        clouds = object_points(
            result.labels[view], disp, lightfield.views[view], cam,
            confidence=confidence, min_confidence=min_confidence,
            view_offset=(view[0] - center[0], view[1] - center[1]), object_ids=ids,
            reference_disparity=truth,
        )
        for obj_id, cloud in clouds.items():
            parts[obj_id].append(cloud)
    merged = {i: merge_points(parts[i]) for i in ids}
    categories = _categories(result)
    measures = [measure_object(merged[i], cam, categories.get(i)) for i in ids]
    return Objects3D(cam, merged, measures, name, views, float(min_confidence))


def objects_over_video(
    frames: Iterable[tuple[SegmentationResult, LightField]],
    *,
    fps: float | None = None,
    **options: Any,
) -> tuple[list[Objects3D], list[Trajectory]]:
    """:func:`objects_in_3d` for every ``(result, light field)`` frame, and each object's
    trajectory over them (``fps`` for speeds in metres per second, else per frame).

    ``options`` are :func:`objects_in_3d`'s. A camera given once holds for every frame; without
    one each frame's own is used.
    """
    per_frame = [objects_in_3d(result, lf, **options) for result, lf in frames]
    return per_frame, trajectories([found.measures for found in per_frame], fps=fps)


def _number(value, digits: int = 3, width: int = 7) -> str:
    if value is None or not np.isfinite(value):
        return "-".rjust(width)
    return f"{value:{width}.{digits}f}"


def format_table(found: Objects3D) -> str:
    """The table of ``found``'s measures, one line per object: what ``lfsam objects`` prints
    and the viewer's "Objects in 3D" dock shows."""
    errors = any(m.gt_median_depth_m is not None for m in found.measures)
    head = (f"{'id':>5} {'category':<14} {'pixels':>7} {'conf.':>5}  "
            f"{'centroid x, y, z (m)':^25} {'median z':>8}  {'extent (m)':<23}")
    lines = [head + ("  depth error" if errors else "")]
    for m in found.measures:
        size = "-" if m.box is None else " x ".join(f"{v:.3f}" for v in m.box.size)
        line = (f"{m.object_id:>5} {(m.category or '-')[:14]:<14} {m.pixels:>7} "
                f"{_number(m.confident_share, 2, 5)}  "
                + " ".join(_number(v, 3, 8) for v in m.centroid_m)
                + f" {_number(m.median_depth_m, 3, 8)}  {size:<23}")
        if m.gt_median_depth_m is not None:
            rel = m.median_depth_relative_error
            line += (f"  {_number(None if rel is None else 100 * rel, 2, 6)} % "
                     f"(median |dz| {_number(m.median_abs_depth_error_m, 4, 6)} m)")
        if m.pixels and not m.points:
            line += "  no confident pixel"
        elif not m.pixels:
            line += "  not in these views (try --views all)"
        lines.append(line)
    return "\n".join(lines)


def _write_clouds(found: Objects3D, folder: Path) -> list[str]:
    names = []
    for measure in found.measures:
        cloud = found.clouds[measure.object_id]
        name = f"object_{measure.object_id:04d}.ply"
        write_ply(folder / name, cloud.xyz, cloud.rgb, comments=(
            f"lfsam {__version__}: object {measure.object_id}"
            + (f" ({measure.category})" if measure.category else ""),
            "frame: center view camera, x right, y down, z forward, metres",
            f"disparity: {found.disparity_source}; views: {found.views}; "
            f"min_confidence: {found.min_confidence}",
        ))
        names.append(name)
    (folder / "objects.json").write_text(json.dumps(found.to_json(), indent=1) + "\n")
    return names


def export_point_clouds(
    found: Objects3D | Sequence[Objects3D],
    out: str | os.PathLike,
    force: bool = False,
) -> Path:
    """Write one coloured PLY per object (``object_NNNN.ply``: x y z red green blue,
    binary little-endian, metres in the center camera frame) and ``objects.json`` (the
    measures) into the folder ``out``, atomically; a video's frames (a sequence) go into
    ``frame_FFFF/`` sub-folders.

    Raises
    ------
    LfsamError
        If ``out`` is a file, its parent is missing, or it is a non-empty folder without
        ``force``.
    """
    with atomic_folder(out, force) as tmp:
        if isinstance(found, Objects3D):
            _write_clouds(found, tmp)
        else:
            for index, frame in enumerate(found):
                (tmp / f"frame_{index:04d}").mkdir()
                _write_clouds(frame, tmp / f"frame_{index:04d}")
    return Path(out)
