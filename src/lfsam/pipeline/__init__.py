"""The LFSAM pipeline (paper section 3), one module per step.

1. :mod:`lfsam.pipeline.initial` — initial segmentation of the center view;
2. :mod:`lfsam.pipeline.propagation` — disparity propagation into every view;
3. :mod:`lfsam.pipeline.occlusion` — semantic (and geometric) occluding;
4. :mod:`lfsam.pipeline.refinement` — refinement by re-prompting SAM 2;

then :mod:`lfsam.pipeline.fusion` (label fusion). :mod:`lfsam.pipeline.engine` streams the views
through the four steps for the objects of :mod:`lfsam.pipeline.objects` (each object's clicks
carried into other views there); :mod:`lfsam.pipeline.references` chooses where the automatic
mode looks beyond the center view.
"""

from lfsam.pipeline.config import ABLATIONS, OCCLUSION_MODES, PipelineConfig
from lfsam.pipeline.fusion import fuse_labels
from lfsam.pipeline.initial import SourceMasks, initial_segmentation, validate_prompts
from lfsam.pipeline.occlusion import semantic_occlusion, source_features
from lfsam.pipeline.propagation import forward_warp, propagate_masks
from lfsam.pipeline.refinement import refine_masks, refinement_prompts

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
    "semantic_occlusion",
    "source_features",
    "validate_prompts",
]
