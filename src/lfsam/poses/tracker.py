"""One object's 6D pose tracked frame by frame (:mod:`lfsam.poses`, docs/design.md section 12):
what the tracker reads of a view (:class:`ViewData`), the poses it gives (:class:`FramePose`,
:class:`ObjectPoses`, :func:`first_pose`) and :class:`PoseTracker`, the registration (the
steps of the package docstring); its settings are :class:`lfsam.poses.options.PoseOptions`.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from lfsam.camera import Camera
from lfsam.errors import LfsamError
from lfsam.metrics.pose import rotation_error_deg
from lfsam.poses.options import PoseOptions
from lfsam.poses.prediction import predict_motion
from lfsam.poses.rim import covered_share, trusted_labels
from lfsam.spatial import MIN_CONFIDENCE, object_points
from lfsam.spatial.features import ViewFeatures, match_features, view_features
from lfsam.spatial.registration import (
    IcpResult,
    estimate_normals,
    icp,
    plane_conditioning,
    ransac_rigid,
    transform,
    voxel_downsample,
)

__all__ = [
    "POSE_VIEWS",
    "STATUSES",
    "FramePose",
    "ObjectPoses",
    "PoseOptions",
    "PoseTracker",
    "ViewData",
    "default_pose_views",
    "first_pose",
]

#: Which views' pixels become points: every present view, the center and the four corner views
#: (the longest baselines: 5 disparity estimates per frame instead of 49), or the center alone.
POSE_VIEWS = ("all", "corners", "center")


def default_pose_views(disparity: object) -> str:
    """The views whose pixels become points when none are named (issue 65): every view with a
    ground-truth or file disparity; the center and the corners with an estimate (5 estimates per
    frame instead of one per view, and the estimate targets are met with them: docs/design.md
    section 12)."""
    return "corners" if isinstance(disparity, str) and disparity == "estimate" else "all"

#: The statuses of an object in a frame: ``uncertain`` is a pose given whose fit is poor
#: (:attr:`PoseOptions.uncertain_rmse`), never silently ``tracked`` (issue 64).
STATUSES = ("tracked", "uncertain", "lost", "found again")


@dataclass
class ViewData:
    """One view of one frame, as plain arrays: ``offset`` ``(s - s_c, t - t_c)``, ``image``
    (U, V, 3) uint8, ``labels`` (U, V) int, ``disparity`` (U, V) float and optionally its
    ``confidence`` (U, V) in [0, 1] (None: confident everywhere)."""

    offset: tuple[int, int]
    image: np.ndarray
    labels: np.ndarray
    disparity: np.ndarray
    confidence: np.ndarray | None = None


@dataclass
class FramePose:
    """One object in one frame. ``motion`` and ``pose`` are None where it is ``lost``."""

    frame: int
    status: str
    motion: np.ndarray | None
    pose: np.ndarray | None
    inliers: float | None
    rmse_m: float | None
    points: int
    matches: int
    seconds: float

    def to_json(self) -> dict[str, Any]:
        def matrix(m):
            return None if m is None else np.round(m, 9).tolist()

        def number(x, digits):
            return None if x is None or not np.isfinite(x) else round(float(x), digits)

        return {"frame": self.frame, "status": self.status, "motion": matrix(self.motion),
                "pose": matrix(self.pose), "inliers": number(self.inliers, 4),
                "rmse_m": number(self.rmse_m, 7), "points": self.points,
                "feature_matches": self.matches, "seconds": round(self.seconds, 4)}


@dataclass
class ObjectPoses:
    """One object over the video: its ``first_pose`` (4x4, object frame to camera at its first
    frame) and one :class:`FramePose` per frame from its first."""

    object_id: int
    category: str | None
    first_pose: np.ndarray
    frames: list[FramePose] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {"id": self.object_id, "category": self.category,
                "first_pose": np.round(self.first_pose, 9).tolist(),
                "frames": [f.to_json() for f in self.frames]}


def first_pose(xyz: np.ndarray) -> np.ndarray:
    """The object frame of points ``xyz`` (N, 3): origin at their centroid, axes their
    principal axes (largest variance first, each axis' largest component positive,
    right-handed), as a 4x4 object-to-camera transform.

    Examples
    --------
    >>> pts = np.random.default_rng(0).normal(size=(500, 3)) * [0.01, 0.05, 0.02] + [0, 0, 1]
    >>> pose = first_pose(pts)
    >>> np.round(np.abs(pose[:3, 0]), 1).tolist(), round(float(np.linalg.det(pose[:3, :3])), 6)
    ([0.0, 1.0, 0.0], 1.0)
    """
    xyz = np.asarray(xyz, dtype=np.float64)
    centre = xyz.mean(axis=0)
    _, vectors = np.linalg.eigh(np.cov((xyz - centre).T))
    axes = vectors[:, ::-1].copy()  # columns, largest variance first
    for k in range(2):
        if axes[np.argmax(np.abs(axes[:, k])), k] < 0:
            axes[:, k] *= -1
    axes[:, 2] = np.cross(axes[:, 0], axes[:, 1])
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = axes, centre
    return pose


@dataclass
class _Track:
    """A tracked object's state."""

    result: ObjectPoses
    model: np.ndarray
    normals: np.ndarray
    tree: cKDTree
    key_motion: np.ndarray
    key_features: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]]
    prev_features: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]]
    motions: list[np.ndarray]
    frames: list[int]
    lost: bool = False
    rmses: list[float] = field(default_factory=list)


@dataclass
class _Pending:
    """An object held back from starting (:meth:`PoseTracker._start`): what its last frame
    would have started it with."""

    frame: int
    voxels: int
    model: np.ndarray
    normals: np.ndarray
    tree: cKDTree
    pose: np.ndarray
    features: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]]


def _features_in_model(features: dict[tuple[int, int], ViewFeatures], object_id: int,
                       to_model: np.ndarray) -> dict[tuple[int, int], tuple]:
    out = {}
    for view, found in features.items():
        xyz, descriptors = found.of(object_id)
        if len(xyz):
            out[view] = (transform(to_model, xyz), descriptors)
    return out


def _thin(xyz: np.ndarray, cap: int) -> np.ndarray:
    """At most ``cap`` of the points, evenly strided (deterministic)."""
    if len(xyz) <= cap:
        return xyz
    return xyz[np.linspace(0, len(xyz) - 1, cap).astype(np.int64)]


class PoseTracker:
    """Every object's motion and pose, frame by frame (module docstring).

    Parameters
    ----------
    camera : Camera
    view_size : (U, V)
    options : PoseOptions, optional
    categories : dict of id to str, optional

    Examples
    --------
    See ``tests/test_poses.py``; :func:`poses_of_video` drives it over a video.
    """

    def __init__(self, camera: Camera, view_size: tuple[int, int],
                 options: PoseOptions | None = None,
                 categories: dict[int, str] | None = None) -> None:
        self.camera = camera
        self.view_size = tuple(int(x) for x in view_size)
        self.options = options or PoseOptions()
        self.categories = dict(categories or {})
        self.tracks: dict[int, _Track] = {}
        self._waiting: dict[int, _Pending] = {}  # objects held back: their last sight
        self.frame = -1

    @property
    def objects(self) -> list[ObjectPoses]:
        """Every object seen so far, by id."""
        return [self.tracks[i].result for i in sorted(self.tracks)]

    def model_points(self, object_id: int) -> np.ndarray:
        """Object ``object_id``'s keyframe model ``(N, 3)``: its points in its first frame's
        camera coordinates (module docstring, step 3; the viewer sizes its axes by them).

        Raises
        ------
        KeyError
            For an object not tracked (never seen well enough to start).
        """
        return self.tracks[int(object_id)].model.copy()

    def _points(self, views: Sequence[ViewData], object_ids: list[int]):
        parts: dict[int, list[np.ndarray]] = {i: [] for i in object_ids}
        for view in views:
            clouds = object_points(view.labels, view.disparity, view.image, self.camera,
                                   confidence=view.confidence, view_offset=view.offset,
                                   object_ids=object_ids)
            for obj_id, cloud in clouds.items():
                if len(cloud.xyz):
                    parts[obj_id].append(cloud.xyz)
        cap = self.options.max_dense
        return {i: _thin(np.concatenate(p), cap) if p else np.zeros((0, 3))
                for i, p in parts.items()}

    def _view_features(self, views: Sequence[ViewData],
                  gray: np.ndarray | None) -> dict[tuple[int, int], ViewFeatures]:
        offsets = [v.offset for v in views]
        reach_s = max(abs(o[0]) for o in offsets)
        reach_t = max(abs(o[1]) for o in offsets)
        wanted = {(0, 0), (-reach_s, -reach_t), (-reach_s, reach_t), (reach_s, -reach_t),
                  (reach_s, reach_t)}
        out = {}
        for view in views:
            if tuple(view.offset) not in wanted:
                continue
            confident = (None if view.confidence is None
                         else np.asarray(view.confidence) >= MIN_CONFIDENCE)
            out[tuple(view.offset)] = view_features(view.image, view.labels, view.disparity,
                                                    self.camera, view.offset, confident,
                                                    gray=gray)
        return out

    def _model(self, xyz: np.ndarray):
        xyz = _thin(xyz, self.options.max_model)
        normals = estimate_normals(xyz, self.options.normal_neighbours)
        return xyz, normals, cKDTree(xyz)

    def _covered(self, views: Sequence[ViewData], object_ids: list[int]) -> dict[int, float]:
        """:func:`covered_share` of objects not started yet, in the center view (or the first
        view given)."""
        if not object_ids or self.options.rim is None:
            return {}
        view = next((v for v in views if tuple(v.offset) == (0, 0)), views[0])
        shares = covered_share(view.labels, view.disparity, self.options.rim,
                               zero_disparity_offset=self.camera.zero_disparity_offset,
                               object_ids=object_ids)
        return {i: shares.get(i, 0.0) for i in object_ids}

    def _start(self, obj_id: int, xyz: np.ndarray, dense: np.ndarray, features,
               covered: float = 0.0) -> list[FramePose]:
        """The object's first frame: its model and first pose, or nothing yet while more than
        :attr:`PoseOptions.covered_start` of the ring around it lies nearer (something covers
        it), its points leave the motion free (:func:`plane_conditioning` under
        :attr:`PoseOptions.pinned`) and it still grows (more than
        :attr:`PoseOptions.still_growing` times its voxels of the frame it was last seen in):
        the frame of a sliver coming out from behind another object is not the object's, and
        its model would pin nothing (docs/design.md section 12, "Poses through occlusions").
        An object that stopped growing starts at the frame it was last held back in (it showed
        as much there), this frame registered to it: both entries are returned."""
        model, normals, tree = self._model(xyz)
        now = _Pending(self.frame, len(xyz), model, normals, tree, first_pose(dense),
                       _features_in_model(features, obj_id, np.eye(4)))
        before = self._waiting.pop(obj_id, None)
        if before is not None and len(xyz) <= self.options.still_growing * before.voxels:
            first = self._begin(obj_id, before)
            return [first, self._follow(self.tracks[obj_id], obj_id, xyz, features)]
        if (covered > self.options.covered_start
                and plane_conditioning(model, normals) < self.options.pinned):
            self._waiting[obj_id] = now
            return []
        return [self._begin(obj_id, now)]

    def _begin(self, obj_id: int, start: _Pending) -> FramePose:
        """A track from ``start``, its first frame."""
        result = ObjectPoses(obj_id, self.categories.get(obj_id), start.pose)
        self.tracks[obj_id] = _Track(result, start.model, start.normals, start.tree, np.eye(4),
                                     start.features, start.features, [np.eye(4)],
                                     [start.frame])
        return FramePose(start.frame, "tracked", np.eye(4), start.pose.copy(), 1.0, 0.0,
                         start.voxels, 0, 0.0)

    def finish(self) -> list[FramePose]:
        """Start every object still held back (:meth:`_start`) at the last frame it was seen
        in: at the end of a video, or of a single light field, what showed is all there is.
        Returns their first entries (also added to :attr:`objects`)."""
        out = []
        for obj_id in sorted(self._waiting):
            entry = self._begin(obj_id, self._waiting[obj_id])
            self.tracks[obj_id].result.frames.append(entry)
            out.append(entry)
        self._waiting.clear()
        return out

    def _pairs(self, track: _Track, obj_id: int, features) -> tuple[np.ndarray, np.ndarray]:
        """(model points, current points) of feature matches against the keyframe and the
        previous frame, view by view."""
        model_pts, cur_pts = [], []
        for view, found in features.items():
            xyz, descriptors = found.of(obj_id)
            if len(xyz) < 2:
                continue
            for reference in (track.key_features, track.prev_features):
                if view not in reference:
                    continue
                ref_xyz, ref_desc = reference[view]
                pairs = match_features(descriptors, ref_desc)
                model_pts.append(ref_xyz[pairs[:, 1]])
                cur_pts.append(xyz[pairs[:, 0]])
                if reference is track.key_features and track.key_features is track.prev_features:
                    break
        if not model_pts:
            return np.zeros((0, 3)), np.zeros((0, 3))
        return np.concatenate(model_pts), np.concatenate(cur_pts)

    def _follow(self, track: _Track, obj_id: int, xyz: np.ndarray, features) -> FramePose:
        opts = self.options
        motions = track.motions
        guess = predict_motion(motions, track.frames, self.frame,
                               centre=track.result.first_pose[:3, 3])
        model_pts, cur_pts = self._pairs(track, obj_id, features)
        fitted, inliers = ransac_rigid(model_pts, cur_pts, opts.ransac_m,
                                       seed=self.frame * 1009 + obj_id)
        matches = int(inliers.sum())
        init = fitted if fitted is not None and matches >= opts.min_matches else guess
        pairs = ((cur_pts[inliers], model_pts[inliers]) if matches >= opts.min_matches
                 else None)
        found = icp(_thin(xyz, opts.max_points), track.model, track.normals,
                    np.linalg.inv(init), tree=track.tree, gates=opts.gates_m, pairs=pairs,
                    pair_weight=opts.pair_weight, weak_pair_weight=opts.weak_pair_weight,
                    prior=np.linalg.inv(guess), prior_weight=opts.prior_weight)
        if found.inliers < opts.min_inliers:
            track.lost = True
            return FramePose(self.frame, "lost", None, None, found.inliers, None, len(xyz),
                             matches, 0.0)
        to_model = found.transform
        motion = np.linalg.inv(to_model)
        poor = found.inliers < opts.uncertain_inliers or (
            len(track.rmses) >= 2
            and found.rmse > max(opts.uncertain_rmse * float(np.median(track.rmses)),
                                 opts.uncertain_floor_m))
        if opts.grow_uncovered and self._uncovered(track, found):
            # The part it explains pins the motion and fits as the object's own fits do: the
            # rest is surface the model never held (an object coming out from behind another).
            # It stays ``uncertain``, but its points join the model.
            self._join(track, transform(to_model, xyz))
        # A poor fit is uncertain even on the frame an object comes back in: "found again"
        # promises a pose as good as "tracked".
        status = "uncertain" if poor else "found again" if track.lost else "tracked"
        track.lost = False
        current = _features_in_model(features, obj_id, to_model)
        if not poor:  # an uncertain pose would carry its error into the next prediction and
            motions.append(motion)  # into the next frame's feature pairs
            track.frames.append(self.frame)
            track.prev_features = current
            track.rmses.append(found.rmse)
        turned = rotation_error_deg(motion, track.key_motion)
        if not poor and found.conditioning >= opts.pinned and (
                turned > opts.keyframe_deg or found.inliers < opts.keyframe_inliers):
            self._join(track, transform(to_model, xyz))
            track.key_motion = motion
            track.key_features = current
        pose = motion @ track.result.first_pose
        return FramePose(self.frame, status, motion, pose, found.inliers, found.rmse, len(xyz),
                         matches, 0.0)

    def _join(self, track: _Track, xyz: np.ndarray) -> None:
        """Add points (model coordinates) to the object's model, voxel by voxel."""
        (joined,) = voxel_downsample(np.concatenate([track.model, xyz]), self.options.voxel_m)
        track.model, track.normals, track.tree = self._model(joined)

    def _uncovered(self, track: _Track, found: IcpResult) -> bool:
        """Whether a fit explains only part of the frame's points because the rest is new
        surface (docs/design.md section 12, "Poses through occlusions"): it explains under
        ``uncertain_inliers`` of them, its inliers pin all six directions (``pinned``) and fit
        within ``uncertain_floor_m`` and within ``uncertain_rmse`` times the object's typical
        fit. Points pulled off by what is not the object fit several times worse."""
        opts = self.options
        typical = (opts.uncertain_rmse * float(np.median(track.rmses)) if track.rmses
                   else float("inf"))
        # Points noisier than the floor (estimated depth: about a millimetre) fit a wrong pose
        # as well as the right one, so their fit cannot vouch for new surface.
        return (found.inliers < opts.uncertain_inliers
                and found.conditioning >= opts.pinned
                and found.rmse <= min(typical, opts.uncertain_floor_m))

    def add_frame(self, views: Sequence[ViewData], frame: int | None = None,
                  grid: np.ndarray | None = None) -> list[FramePose]:
        """Register every labelled object of one frame; returns its :class:`FramePose` per
        object seen so far (objects absent from this frame are ``lost``).

        ``grid`` (S, T, U, V, 3), every view of the frame, is given with estimated
        disparities: the features' disparities are then refined by photo-consistency across
        the outermost views (:func:`lfsam.spatial.features.refine_disparity`)."""
        self.frame = self.frame + 1 if frame is None else int(frame)
        if not views:
            raise LfsamError("a frame needs at least one view")
        start = time.perf_counter()
        seen: set[int] = set()
        for view in views:
            counts = np.bincount(np.asarray(view.labels).ravel().clip(0))
            seen |= {int(i) for i in np.flatnonzero(counts) if i != 0}
        ids = sorted(seen | set(self.tracks))
        covered = self._covered(views, [i for i in ids if i not in self.tracks])
        if self.options.rim is not None:
            views = [dataclasses.replace(
                view, labels=trusted_labels(
                    view.labels, view.disparity, self.options.rim,
                    zero_disparity_offset=self.camera.zero_disparity_offset))
                for view in views]
        clouds = self._points(views, ids)
        gray = None if grid is None else np.asarray(grid, dtype=np.float32).mean(axis=-1)
        features = self._view_features(views, gray)
        shared = (time.perf_counter() - start) / max(len(ids), 1)
        out = []
        for obj_id in ids:
            began = time.perf_counter()
            dense = clouds[obj_id]
            (xyz,) = voxel_downsample(dense, self.options.voxel_m)
            track = self.tracks.get(obj_id)
            if len(xyz) < self.options.min_points:
                if track is None:
                    continue  # not yet seen well enough to start
                track.lost = True
                entry = FramePose(self.frame, "lost", None, None, None, None, len(xyz), 0, 0.0)
            elif track is None:
                started = self._start(obj_id, xyz, dense, features, covered.get(obj_id, 0.0))
                if not started:
                    continue  # partly covered, and what shows leaves its pose free
                *earlier, entry = started
                for first in earlier:
                    self.tracks[obj_id].result.frames.append(first)
                    out.append(first)
            else:
                entry = self._follow(track, obj_id, xyz, features)
            entry.seconds = shared + time.perf_counter() - began
            self.tracks[obj_id].result.frames.append(entry)
            out.append(entry)
        return out
