"""Automatic mask generation of the SAM 2 backend (paper section 4; docs/design.md section 3.1):
``SAM2AutomaticMaskGenerator`` run on an encoded view, fed its cached embedding instead of
encoding the view again (:class:`AutomaticMaskGeneration`, a base of
:class:`lfsam.segmenters.sam2.backend.Sam2Segmenter`), with the paper's settings
(:data:`PAPER_AMG_OPTIONS`) unless given others.
"""

from __future__ import annotations

import inspect
import warnings
from typing import Any

import numpy as np

from lfsam.errors import LfsamError
from lfsam.segmenters.base import AutoMasks, ViewEmbedding
from lfsam.segmenters.sam2.adapter import (
    CachedFeaturePredictor,
)
from lfsam.segmenters.sam2.build import (
    inference_context,
    make_image_predictor,
)
from lfsam.segmenters.sam2.decoder import default_chunk_size

__all__ = ["PAPER_AMG_OPTIONS", "AutomaticMaskGeneration"]

PAPER_AMG_OPTIONS: dict[str, Any] = {
    "points_per_side": 64,
    "pred_iou_thresh": 0.88,
    "stability_score_thresh": 0.95,
    "stability_score_offset": 1.0,
    "box_nms_thresh": 0.7,
    "min_mask_region_area": 0,
}
"""Automatic mask generation settings of the paper (section 4; docs/design.md section 3.1)."""


class AutomaticMaskGeneration:
    """:meth:`generate` of :class:`~lfsam.segmenters.sam2.backend.Sam2Segmenter` (module
    docstring). A base of the segmenter: it reads the segmenter's ``model``, ``amg_options``,
    ``device``, ``precision``, ``_view_features`` and ``_generator``, and counts the generator's
    own encoder passes in ``crop_encode_calls``."""

    @staticmethod
    def _check_amg_options(options: dict[str, Any]) -> dict[str, Any]:
        from sam2.automatic_mask_generator import SAM2AutomaticMaskGenerator

        allowed = set(inspect.signature(SAM2AutomaticMaskGenerator.__init__).parameters)
        allowed -= {"self", "model", "kwargs", "output_mode"}
        unknown = sorted(set(options) - allowed)
        if unknown:
            raise LfsamError(
                f"unknown automatic-mask-generation option(s) {', '.join(unknown)}; "
                f"valid: {', '.join(sorted(allowed))}"
            )
        return {**PAPER_AMG_OPTIONS, **options}

    def _mask_generator(self) -> Any:
        if self._generator is None:
            from sam2.automatic_mask_generator import SAM2AutomaticMaskGenerator

            with warnings.catch_warnings():  # its own predictor uses torch.jit.script
                warnings.filterwarnings("ignore", ".*torch.jit.script.*", FutureWarning)
                generator = SAM2AutomaticMaskGenerator(self.model, **self.amg_options)
            area = self.amg_options.get("min_mask_region_area", 0)
            predictor = make_image_predictor(
                self.model,
                CachedFeaturePredictor,
                mask_threshold=generator.mask_threshold,
                max_hole_area=area,
                max_sprinkle_area=area,
            )
            predictor.decode_chunk_size = default_chunk_size(self.device)
            generator.predictor = predictor
            self._generator = generator
        return self._generator

    def generate(
        self, embedding: ViewEmbedding, image: np.ndarray, points: np.ndarray | None = None
    ) -> AutoMasks:
        """SAM 2 automatic mask generation on an encoded view, reusing its embedding (with
        ``points``, those pixels replace the generator's point grid).

        Runs ``SAM2AutomaticMaskGenerator`` with :attr:`amg_options` (the paper's settings by
        default); the whole-view crop takes the cached embedding, so with the default
        ``crop_n_layers=0`` the image encoder does not run again.

        Returns
        -------
        AutoMasks
            ``masks`` (M, U, V) bool in the generator's order, ``scores`` = predicted IoU.
        """
        image = np.asarray(image)
        if image.shape != (*embedding.image_size, 3) or image.dtype != np.uint8:
            raise LfsamError(
                f"generate() needs the encoded view as a (U, V, 3) uint8 image of size "
                f"{tuple(embedding.image_size)}, got {image.shape} {image.dtype}"
            )
        generator = self._mask_generator()
        predictor = generator.predictor
        predictor.cached = (self._view_features(embedding), tuple(embedding.image_size))
        before = predictor.encoder_passes
        grids = generator.point_grids
        u_size, v_size = embedding.image_size
        if points is not None:
            points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
            if len(points) == 0:
                return AutoMasks(
                    masks=np.zeros((0, u_size, v_size), dtype=bool),
                    scores=np.zeros(0, np.float32),
                )
            # the generator scales its [0, 1] grids by the crop's (width, height)
            generator.point_grids = [points / np.array([v_size, u_size])] * len(grids)
        try:
            with inference_context(self.device, inference_mode=False, precision=self.precision):
                records = generator.generate(image)
        finally:
            generator.point_grids = grids
            predictor.cached = None
            self.crop_encode_calls += predictor.encoder_passes - before
        if not records:
            return AutoMasks(
                masks=np.zeros((0, u_size, v_size), dtype=bool), scores=np.zeros(0, np.float32)
            )
        masks = np.stack([np.asarray(r["segmentation"], dtype=bool) for r in records])
        scores = np.array([r["predicted_iou"] for r in records], dtype=np.float32)
        return AutoMasks(masks=masks, scores=scores)

