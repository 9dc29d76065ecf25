"""Every object's 6D pose over a light-field video (docs/design.md section 12).

Per object and frame: the rigid **motion** (4x4, metres, the center camera's frame: x right,
y down, z forward) that carries the object's points at its first frame to its points at this
frame, and its **pose** (object frame: origin at the first frame's centroid, axes its principal
axes, largest variance first, right-handed; ``pose = motion @ first_pose``), with a quality
(``inliers``: the share of the frame's points within 3 mm of the registered model; ``rmse_m``:
their RMS point-to-plane distance) and a status (``tracked``, ``uncertain``: a pose whose fit is
several times worse than the object's own, ``lost``, ``found again``). A lost
object gets no pose.

The light-field way to register (:class:`PoseTracker`, plain arrays in and out):

1. the object's points come from every chosen view that sees it (the light field sees around
   occluders), its masks' doubtful rims left out (:mod:`lfsam.poses.rim`: pixels just behind a
   depth jump, or near another label and not the object's silhouette: where an imperfect mask
   carries the background),
   voxel-averaged to :attr:`PoseOptions.voxel_m`;
2. coarse: SIFT features inside the object's masks in a few views (the center and the four
   corners), matched view by view against the last keyframe and the previous frame, lifted to
   3D with the disparity, RANSAC + Kabsch (:mod:`lfsam.spatial.features`,
   :mod:`lfsam.spatial.registration`); a constant-velocity guess without enough matches;
3. fine: point-to-plane ICP of all the frame's points onto the object's **keyframe model** (its
   points at the first frame, joined by later keyframes' points moved back by their motion), the
   feature inliers kept as fixed pairs that pin what planes cannot (a pair farther apart than
   the gate left out, as a point is), the motion predicted at constant velocity
   (:mod:`lfsam.poses.prediction`) holding what neither pins; registering to the model and
   not only to the previous frame is what keeps the motion from drifting;
4. a new keyframe when the object has turned :attr:`PoseOptions.keyframe_deg` since the last
   one or the model explains less than :attr:`PoseOptions.keyframe_inliers` of its points,
   and the fit's points pin all six directions.

An object partly covered by a nearer one starts once what shows of it pins a motion or stops
growing (:attr:`PoseOptions.covered_start`; docs/design.md section 12, "Poses through
occlusions").

:func:`poses_of_video` (:mod:`lfsam.poses.video`) runs it over ``(result, light field)`` frames
with a disparity source (``"estimate"``, ``"gt"``, a map) and a camera, as :mod:`lfsam.objects3d`
does.

The package: :mod:`~lfsam.poses.tracker` (the registration), :mod:`~lfsam.poses.rim` (which
pixels of a mask to trust), :mod:`~lfsam.poses.video` (a whole
video), :mod:`~lfsam.poses.files` (JSON, CSV and BOP files); every name below is importable from
:mod:`lfsam.poses`.
"""

from lfsam.metrics.pose import rotation_error_deg
from lfsam.poses.files import bop_csv, poses_csv, poses_json
from lfsam.poses.rim import RimOptions, trusted_labels
from lfsam.poses.tracker import (
    POSE_VIEWS,
    STATUSES,
    FramePose,
    ObjectPoses,
    PoseOptions,
    PoseTracker,
    ViewData,
    default_pose_views,
    first_pose,
)
from lfsam.poses.video import VideoPoses, poses_of_video

__all__ = [
    "POSE_VIEWS",
    "STATUSES",
    "FramePose",
    "ObjectPoses",
    "PoseOptions",
    "PoseTracker",
    "RimOptions",
    "VideoPoses",
    "ViewData",
    "bop_csv",
    "default_pose_views",
    "first_pose",
    "poses_csv",
    "poses_json",
    "poses_of_video",
    "rotation_error_deg",
    "trusted_labels",
]
