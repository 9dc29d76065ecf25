"""The ``transformers`` backend: EdgeTAM and transformers-format SAM 2 checkpoints behind lfsam's
:class:`~lfsam.segmenters.base.Segmenter` interface (docs/design.md section 3.8).

:class:`TransformersSegmenter` is :class:`~lfsam.segmenters.sam2.backend.Sam2Segmenter` with
another image encoder: a view is encoded once as ``transformers`` encodes it (its image
processor's resize of the uint8 view, ImageNet normalisation, ``get_image_embeddings``), and the
embedding then serves every prompt batch, automatic generation and semantic occluding through
SAM 2's heads in Meta's modules
(:class:`~lfsam.segmenters.transformers.model.TransformersImageModel`) and
lfsam's batched decoder, which shares a view's image side across its prompts. The masks are those
of ``transformers``' own processor + model call for the same view and prompt
(``tests/test_segmenters_transformers.py``).

SAM v1 (``SamModel``) keeps the view's aspect and pads it
(:mod:`lfsam.segmenters.transformers.sam1`): its
pixels are ``SamImageProcessor``'s, the predictors' transforms are
:class:`~lfsam.segmenters.transformers.sam1.PaddedTransforms` (prompt coordinates, mask
post-processing
as ``SamProcessor``), and semantic occluding samples only the embedding cells over the view.
"""

from __future__ import annotations

import json
import os
from typing import Any

import numpy as np
import torch

from lfsam.segmenters.base import ViewEmbedding
from lfsam.segmenters.registry import TRANSFORMERS_FOLDER
from lfsam.segmenters.sam2.adapter import (
    IMAGENET_MEAN,
    IMAGENET_STD,
    image_transforms,
    use_image_transforms,
)
from lfsam.segmenters.sam2.backend import Sam2Features, Sam2Segmenter
from lfsam.segmenters.sam2.build import inference_context
from lfsam.segmenters.transformers.build import build_transformers_sam
from lfsam.segmenters.transformers.sam1 import PaddedTransforms, preprocess_padded, view_grid

__all__ = ["TransformersSegmenter", "preprocess_views"]


def preprocess_views(views: torch.Tensor, size: int) -> torch.Tensor:
    """``Sam2ImageProcessor``'s pixel values of a batch of uint8 views, vectorised.

    The processor resizes the uint8 image (bilinear, antialiased, rounded back to uint8) to the
    model's square input, then rescales to [0, 1] and normalises; Meta's ``SAM2Transforms``
    resizes the float image instead (up to 1/255 apart per pixel).

    Parameters
    ----------
    views : (B, U, V, 3) uint8 tensor
    size : int
        The model's input side.

    Returns
    -------
    (B, 3, size, size) float32 tensor
    """
    from torchvision.transforms.v2 import functional as tvf

    x = views.permute(0, 3, 1, 2).contiguous()
    x = tvf.resize(x, [size, size], interpolation=tvf.InterpolationMode.BILINEAR, antialias=True)
    mean = torch.tensor(IMAGENET_MEAN, device=x.device).view(1, 3, 1, 1)
    std = torch.tensor(IMAGENET_STD, device=x.device).view(1, 3, 1, 1)
    return (x.float() / 255.0 - mean) / std


class TransformersSegmenter(Sam2Segmenter):
    """EdgeTAM or a transformers-format SAM 2 or SAM as an lfsam :class:`Segmenter`.

    Parameters
    ----------
    model : TransformersImageModel
        From :func:`lfsam.segmenters.transformers.build.build_transformers_sam`.
    **kwargs
        As :class:`~lfsam.segmenters.sam2.backend.Sam2Segmenter` (``amg_options``,
        ``max_prompts_per_batch``, ``encode_batch_size``, ``mask_threshold``,
        ``keep_decoder_state``, ``precision``).

    Examples
    --------
    >>> seg = TransformersSegmenter.from_name("edgetam-tiny-test", device="cpu")
    >>> view = np.zeros((48, 64, 3), np.uint8)
    >>> emb = seg.encode(view[None])[0]
    >>> from lfsam.segmenters.base import Prompts
    >>> seg.predict(emb, Prompts(points=[[[30, 20]]], point_labels=[[1]])).masks.shape
    torch.Size([1, 3, 48, 64])
    """

    def __init__(self, model: torch.nn.Module, **kwargs: Any) -> None:
        super().__init__(model, **kwargs)
        #: bfloat16 convolutions run fastest on channels-last tensors (oneDNN), and so do a fused
        #: timm encoder's (EdgeTAM, :func:`~lfsam.segmenters.transformers.model.fuse_timm_encoder`);
        #: otherwise float32 keeps transformers' own layout, so its masks stay transformers' to
        #: the bit
        self.channels_last = self.autocast is not None or bool(
            getattr(self.model, "fused_encoder", False))
        if self.channels_last:
            self.model.hf_model.vision_encoder.to(memory_format=torch.channels_last)
        if self.model.padded_input:  # SAM v1: prompts and masks in the padded geometry
            self._use_padded_transforms(self._predictor)

    @staticmethod
    def _use_padded_transforms(predictor: Any) -> None:
        use_image_transforms(predictor, PaddedTransforms.like(image_transforms(predictor)))

    def _mask_generator(self) -> Any:
        """SAM 2's generator; for SAM v1 its predictor takes the padded transforms."""
        fresh = self._generator is None
        generator = super()._mask_generator()
        if fresh and self.model.padded_input:
            self._use_padded_transforms(generator.predictor)
        return generator

    def _feature_grid(self, embedding: ViewEmbedding) -> torch.Tensor:
        """The embedding; for SAM v1 the top-left ``ceil(h'/16) x ceil(w'/16)`` cells, those
        over the resized view (:func:`~lfsam.segmenters.transformers.sam1.view_grid`).

        The feature-grid convention (:mod:`lfsam.segmenters.feature_grid`) spreads those cells
        evenly over the view. Where ``h'`` (or ``w'``) is not a multiple of 16, the last row
        (column) of cells also covers padding, and pixel row ``r`` of ``U`` lands
        ``(r + 0.5) / U * (ceil(h'/16) - h'/16)`` cells below where the encoder saw it: nothing
        at the top, less than one cell at the bottom (an approximation; docs/design.md
        section 3.8).
        """
        embed = self._view_features(embedding).image_embed
        if not self.model.padded_input:
            return embed
        rows, cols = view_grid(tuple(embedding.image_size), int(self.model.image_size),
                               int(embed.shape[-1]))
        return embed[..., :rows, :cols]

    @classmethod
    def from_name(  # type: ignore[override]
        cls,
        name: str = TRANSFORMERS_FOLDER,
        *,
        checkpoint: str | os.PathLike | None = None,
        random_weights: bool = False,
        device: str | torch.device | None = None,
        seed: int = 0,
        **kwargs: Any,
    ) -> TransformersSegmenter:
        """Build the model with :func:`~lfsam.segmenters.transformers.build.build_transformers_sam`
        and
        wrap it (further keywords go to the segmenter)."""
        model = build_transformers_sam(
            name, checkpoint=checkpoint, random_weights=random_weights, device=device, seed=seed
        )
        return cls(model, **kwargs)

    def _encode_batch(self, chunk: np.ndarray) -> list[Sam2Features]:
        with inference_context(self.device, precision=self.precision):
            views = torch.from_numpy(np.ascontiguousarray(chunk)).to(self.device)
            side = int(self.model.image_size)
            if self.model.padded_input:
                pixels = preprocess_padded(views, side)
            else:
                pixels = preprocess_views(views, side)
            if self.channels_last:
                pixels = pixels.contiguous(memory_format=torch.channels_last)
            levels = self.model.image_embeddings(pixels)
            out = []
            for i in range(len(chunk)):
                per_view = [level[i : i + 1] for level in levels]
                if len(chunk) > 1:  # do not keep the whole batch alive through one view
                    per_view = [level.clone() for level in per_view]
                out.append(Sam2Features(image_embed=per_view[-1], high_res_feats=per_view[:-1]))
        return out

    def describe(self) -> dict[str, Any]:
        """SAM 2's description, with the backend, model type and checkpoint folder."""
        facts = super().describe()
        facts.update(
            backend="transformers",
            params=int(self.info.get("params", facts["params"])),
            model_type=self.info.get("model_type"),
            preprocessing=(
                "transformers image processor (uint8 resize of the longest side, padded)"
                if self.model.padded_input else "transformers image processor (uint8 resize)"
            ),
        )
        return facts

    def cache_identity(self) -> str:
        """As SAM 2's (weights hash, input size, precision), marked as this backend's: its
        pre-processing differs, so its embeddings never answer for Meta's."""
        identity = json.loads(super().cache_identity())
        identity.update(backend="transformers", model_type=self.info.get("model_type"))
        return json.dumps(identity, sort_keys=True)

