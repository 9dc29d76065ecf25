"""The LFSAM pipeline (paper section 3), one module per step.

1. :mod:`lfsam.pipeline.initial` — initial segmentation of the center view;
2. :mod:`lfsam.pipeline.propagation` — disparity propagation into every view;
3. :mod:`lfsam.pipeline.occlusion` — semantic (and geometric) occluding;
4. :mod:`lfsam.pipeline.refinement` — refinement by re-prompting SAM 2;

then :mod:`lfsam.pipeline.fusion` (label fusion). With ``refine_views`` other than ``"all"``,
:mod:`lfsam.pipeline.sparse` picks the views steps 3-4 run in and :mod:`lfsam.pipeline.fill`
carries their refined masks into the other views (docs/design.md section 3.7).
:mod:`lfsam.pipeline.engine` streams the views through the four steps for the objects of
:mod:`lfsam.pipeline.objects` (each object's clicks carried into other views there);
:mod:`lfsam.pipeline.references` chooses where the automatic mode looks beyond the center view.
"""

from lfsam.pipeline.config import ABLATIONS, OCCLUSION_MODES, PipelineConfig
from lfsam.pipeline.fusion import fuse_labels
from lfsam.pipeline.initial import SourceMasks, initial_segmentation, validate_prompts
from lfsam.pipeline.occlusion import semantic_occlusion, source_features
from lfsam.pipeline.propagation import forward_warp, propagate_masks
from lfsam.pipeline.refinement import refine_masks, refinement_prompts
from lfsam.pipeline.sparse import REFINE_VIEW_MODES, refined_views, sparse_view_count

__all__ = [
    "ABLATIONS",
    "OCCLUSION_MODES",
    "REFINE_VIEW_MODES",
    "PipelineConfig",
    "SourceMasks",
    "forward_warp",
    "fuse_labels",
    "initial_segmentation",
    "propagate_masks",
    "refine_masks",
    "refined_views",
    "refinement_prompts",
    "semantic_occlusion",
    "source_features",
    "sparse_view_count",
    "validate_prompts",
]
