"""Center-view disparity for the pipeline (paper section 3.2; docs/design.md section 3.2).

- :func:`estimate_disparity`: structure tensor on sheared EPIs (torch, any device).
- :func:`estimate_disparity_baseline`: the plain single-scale structure tensor in NumPy, kept as
  the comparison baseline.
- :func:`estimate_disparity_range`: the disparity range of a light field from a coarse sweep.
- :func:`resolve_disparity`: the disparity the pipeline uses, from ``"estimate"``, ``"gt"`` or a
  ``.npy`` file.
"""

from lfsam.disparity.baseline import estimate_disparity_baseline
from lfsam.disparity.estimate import DisparityEstimate
from lfsam.disparity.range import estimate_disparity_range
from lfsam.disparity.source import resolve_disparity
from lfsam.disparity.structure_tensor import candidate_disparities, estimate_disparity

__all__ = [
    "DisparityEstimate",
    "candidate_disparities",
    "estimate_disparity",
    "estimate_disparity_baseline",
    "estimate_disparity_range",
    "resolve_disparity",
]
