"""lfsam: Segment Anything 2 in light fields via constrained prompting.

Implements Goncharov & Dansereau, "Segment Anything in Light Fields for Real-Time Applications via
Constrained Prompting", WACV 2025 workshops. The pipeline's four steps are
:mod:`lfsam.pipeline.initial` (initial segmentation), :mod:`lfsam.pipeline.propagation`
(disparity propagation), :mod:`lfsam.pipeline.occlusion` (semantic occluding) and
:mod:`lfsam.pipeline.refinement` (segmentation refinement). Batch use: :func:`lfsam.segment`;
interactive use: :class:`lfsam.LightFieldPredictor`, wrapped by
:class:`lfsam.LightFieldMaskGenerator` for the automatic mode.
"""

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField, snake_order
from lfsam.prompts import TextPrompt
from lfsam.result import SegmentationResult, load_result, save_result
from lfsam.version import __version__


def __getattr__(name: str):
    # lfsam.segment, lfsam.LightFieldPredictor and the option groups load torch and the
    # pipeline; importing them lazily keeps `import lfsam` (and the CLI's --help) light.
    if name in ("segment", "SegmentOptions", "ModelOptions", "RunOptions"):
        from lfsam import api

        return getattr(api, name)
    if name == "LightFieldPredictor":
        from lfsam.predictor import LightFieldPredictor

        return LightFieldPredictor
    if name == "LightFieldMaskGenerator":
        from lfsam.generator import LightFieldMaskGenerator

        return LightFieldMaskGenerator
    raise AttributeError(f"module 'lfsam' has no attribute {name!r}")

__all__ = [
    "LfsamError",
    "LightField",
    "LightFieldMaskGenerator",
    "LightFieldPredictor",
    "ModelOptions",
    "RunOptions",
    "SegmentOptions",
    "SegmentationResult",
    "TextPrompt",
    "__version__",
    "load_result",
    "save_result",
    "segment",
    "snake_order",
]
