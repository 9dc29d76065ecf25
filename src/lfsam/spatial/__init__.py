"""Objects in 3D: point clouds, positions, sizes and trajectories in metres (docs/design.md §11).

Plain arrays in, plain arrays out (the light field's labels, disparity, confidence and colours of
a view, and a :class:`lfsam.camera.Camera`); :mod:`lfsam.objects3d` runs them over a result.

==================  ==============================================================================
module              one job
==================  ==============================================================================
``points``          every object's pixels of a view as coloured 3D points (confident ones kept)
``measure``         per object: centroid, median depth, oriented box, confident share, depth error
``trajectory``      per object over a video's frames: positions and speeds
``ply``             binary little-endian PLY files (x y z red green blue) written atomically
==================  ==============================================================================
"""

from lfsam.spatial.measure import ObjectMeasure, OrientedBox, measure_object, oriented_box
from lfsam.spatial.ply import read_ply, write_ply
from lfsam.spatial.points import (
    MIN_CONFIDENCE,
    ObjectPoints,
    merge_points,
    object_points,
)
from lfsam.spatial.trajectory import Trajectory, trajectories, trajectories_csv

__all__ = [
    "MIN_CONFIDENCE",
    "ObjectMeasure",
    "ObjectPoints",
    "OrientedBox",
    "Trajectory",
    "measure_object",
    "merge_points",
    "object_points",
    "oriented_box",
    "read_ply",
    "trajectories",
    "trajectories_csv",
    "write_ply",
]
