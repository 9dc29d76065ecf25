"""The LFSAM pipeline (paper section 3), one module per step.

1. :mod:`lfsam.pipeline.initial` — initial segmentation of the center view;
2. :mod:`lfsam.pipeline.propagation` — disparity propagation into every view;
3. :mod:`lfsam.pipeline.occlusion` — semantic (and geometric) occluding;
4. :mod:`lfsam.pipeline.refinement` — refinement by re-prompting SAM 2;

then :mod:`lfsam.pipeline.fusion` (label fusion) and :mod:`lfsam.pipeline.segment`, which streams
the light field view by view through the four steps.
"""

from lfsam.pipeline.config import ABLATIONS, OCCLUSION_MODES, PipelineConfig
from lfsam.pipeline.fusion import fuse_labels
from lfsam.pipeline.initial import SourceMasks, initial_segmentation, validate_prompts
from lfsam.pipeline.occlusion import semantic_occlusion, source_features
from lfsam.pipeline.propagation import forward_warp, propagate_masks
from lfsam.pipeline.refinement import refine_masks, refinement_prompts
from lfsam.pipeline.segment import segment_lightfield

__all__ = [
    "ABLATIONS",
    "OCCLUSION_MODES",
    "PipelineConfig",
    "SourceMasks",
    "forward_warp",
    "fuse_labels",
    "initial_segmentation",
    "propagate_masks",
    "refine_masks",
    "refinement_prompts",
    "segment_lightfield",
    "semantic_occlusion",
    "source_features",
    "validate_prompts",
]
