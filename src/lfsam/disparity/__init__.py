"""Disparity for the pipeline (paper section 3.2; docs/design.md sections 3.2 and 8), of any view.

- :func:`estimate_disparity`: the disparity of any view by the estimator named ``method``
  (:mod:`lfsam.disparity.methods`): by default the occlusion-aware cost volume
  (:mod:`lfsam.disparity.occlusion_aware`), or the structure tensor on sheared EPIs
  (``method="structure-tensor"``); torch, any device, with a confidence map.
- :func:`estimate_disparity_baseline`: the plain single-scale structure tensor in NumPy, kept as
  the comparison baseline.
- :func:`estimate_disparity_range`: the disparity range of a light field from a coarse sweep.
- :func:`resolve_disparity`: the one resolver: the disparity of a view from ``"estimate"``,
  ``"gt"``, a ``.npy`` file or an array.
- :class:`ViewDisparities`: per-view disparities resolved lazily, once each (interactive use).
- :func:`warp_center_disparity`: the center view's disparity forward-warped into another view.
"""

from lfsam.disparity.baseline import estimate_disparity_baseline
from lfsam.disparity.center_warp import warp_center_disparity
from lfsam.disparity.estimate import DisparityEstimate
from lfsam.disparity.methods import DEFAULT_METHOD, METHODS, estimate_disparity
from lfsam.disparity.occlusion_aware import estimate_disparity_occlusion_aware
from lfsam.disparity.range import estimate_disparity_range
from lfsam.disparity.source import resolve_disparity
from lfsam.disparity.structure_tensor import candidate_disparities
from lfsam.disparity.views import ViewDisparities

__all__ = [
    "DEFAULT_METHOD",
    "METHODS",
    "DisparityEstimate",
    "ViewDisparities",
    "candidate_disparities",
    "estimate_disparity",
    "estimate_disparity_baseline",
    "estimate_disparity_occlusion_aware",
    "estimate_disparity_range",
    "resolve_disparity",
    "warp_center_disparity",
]
