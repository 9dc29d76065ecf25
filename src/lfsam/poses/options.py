"""The settings of :class:`lfsam.poses.PoseTracker` (docs/design.md section 12): what each
decides and why."""

from __future__ import annotations

from dataclasses import dataclass, field

from lfsam.poses.rim import RimOptions

__all__ = ["PoseOptions"]


@dataclass(frozen=True)
class PoseOptions:
    """Settings of :class:`lfsam.poses.PoseTracker` (:mod:`lfsam.poses.tracker`).

    Attributes
    ----------
    voxel_m : float
        Points are averaged per voxel of this edge (metres) before registration.
    min_points : int
        Fewer voxels than this in a frame: the object is ``lost`` there.
    min_inliers : float
        A registration explaining less than this share of the points is refused (``lost``).
    keyframe_deg, keyframe_inliers : float
        When to add the frame's points to the object's model (docs/design.md section 12,
        "Keyframes").
    ransac_m : float
        Inlier distance of feature pairs in RANSAC (metres).
    min_matches : int
        RANSAC inliers needed to use the feature motion (else the constant-velocity guess).
    gates_m : tuple of float
        ICP's correspondence gates, coarse to fine (metres); the last one also defines
        ``inliers``.
    pair_weight, weak_pair_weight : float
        Weight of the feature pairs in ICP, relative to all the points' residuals together;
        the second where the planes leave a direction nearly free
        (:func:`lfsam.spatial.registration.icp`).
    normal_neighbours : int
        Neighbours of a model point that give its normal.
    max_dense, max_points, max_model : int
        Caps (evenly strided subsets, deterministic) on an object's raw points per frame, on
        the voxels it registers and on its model's points: a wall of a million pixels costs
        what a box does.
    uncertain_rmse, uncertain_floor_m, uncertain_inliers : float
        A fit is ``uncertain`` (its pose given, its points kept out of the model) where its
        RMS point-to-plane distance exceeds ``uncertain_rmse`` times the median of the object's
        earlier certain fits and ``uncertain_floor_m``, or where it explains less than
        ``uncertain_inliers`` of the points: a registration pulled off by what is not the
        object fits its points several times worse than the object's own noise (design.md
        section 12, "Imperfect masks").
    prior_weight : float
        Weight of the predicted motion in ICP (:func:`lfsam.spatial.registration.icp`'s
        ``prior_weight``), relative to all the points' residuals together, in the directions
        their planes leave nearly free (a strip of one face): docs/design.md section 12,
        "Poses through occlusions".
    pinned : float
        Points pin a motion where :func:`~lfsam.spatial.registration.plane_conditioning` is
        at least this: a fit joins the model only then, and an object starts only then while
        it is partly covered and growing.
    grow_uncovered : bool
        An uncertain fit that explains under ``uncertain_inliers`` of the points while its
        inliers pin all six directions and fit within ``uncertain_floor_m`` and as the object's
        own fits do adds the frame's points to the model (the rest is new surface: an object
        coming out from behind another); False keeps every uncertain fit out of the model.
    covered_start, still_growing : float
        An object not yet tracked waits while more than ``covered_start`` of the ring around
        its center-view mask lies nearer than it (:func:`lfsam.poses.rim.covered_share`), its
        points do not pin a motion and it has over ``still_growing`` times the voxels of the
        frame before: a sliver's frame and model are not the object's.
    rim : RimOptions or None
        Which pixels of each mask are lifted and matched (:mod:`lfsam.poses.rim`: not those
        just behind a depth jump, nor those near another label that are not the object's
        silhouette: where an imperfect mask carries the background); None trusts every
        labelled pixel.
    """

    voxel_m: float = 0.003
    min_points: int = 40
    min_inliers: float = 0.3
    keyframe_deg: float = 8.0
    keyframe_inliers: float = 0.8
    ransac_m: float = 0.006
    min_matches: int = 8
    gates_m: tuple[float, ...] = (0.015, 0.008, 0.004, 0.003)
    pair_weight: float = 0.01
    weak_pair_weight: float = 0.3
    normal_neighbours: int = 12
    max_dense: int = 300_000
    max_points: int = 5000
    max_model: int = 30_000
    uncertain_rmse: float = 3.0
    uncertain_floor_m: float = 0.0005
    uncertain_inliers: float = 0.5
    prior_weight: float = 0.0001
    pinned: float = 0.02
    grow_uncovered: bool = True
    covered_start: float = 0.1
    still_growing: float = 1.1
    rim: RimOptions | None = field(default_factory=RimOptions)
