"""lfsam: Segment Anything 2 in light fields via constrained prompting.

Implements Goncharov & Dansereau, "Segment Anything in Light Fields for Real-Time Applications via
Constrained Prompting", WACV 2025 workshops. The pipeline's four steps are
:mod:`lfsam.pipeline.initial` (initial segmentation), :mod:`lfsam.pipeline.propagation`
(disparity propagation), :mod:`lfsam.pipeline.occlusion` (semantic occluding) and
:mod:`lfsam.pipeline.refinement` (segmentation refinement).
"""

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField, snake_order
from lfsam.result import SegmentationResult, load_result, save_result

__version__ = "0.1.0"

__all__ = [
    "LfsamError",
    "LightField",
    "SegmentationResult",
    "__version__",
    "load_result",
    "save_result",
    "snake_order",
]
