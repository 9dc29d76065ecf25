"""A ``transformers`` SAM 2 / EdgeTAM / SAM in the shape of Meta's ``SAM2Base`` image model
(docs/design.md section 3.8).

:class:`TransformersImageModel` holds the ``transformers`` model (its image encoder runs as
``transformers`` runs it: ``get_image_embeddings``, with the decoder's two 1x1 convolutions and
the no-memory embedding) and SAM 2's prompt encoder and mask decoder rebuilt as Meta's modules
with the same weights (:mod:`lfsam.segmenters.transformers.heads`). It answers what lfsam's SAM 2
code asks
of a ``SAM2Base``: ``image_size``, ``device``, ``sam_prompt_encoder``, ``sam_mask_decoder``,
``no_mem_embed``, ``directly_add_no_mem_embed``, ``forward_image`` and
``_prepare_backbone_features`` (the automatic generator's extra crops). It has no video memory:
Meta's video predictor refuses it (``lfsam.baseline.predictor.video_predictor_for``).

A ``SamModel`` (SAM v1) has one embedding level and no no-memory embedding: its image embedding
is the only level (``use_high_res_features_in_sam`` False, ``num_feature_levels`` 1),
``no_mem_embed`` stays zero and is not added (``directly_add_no_mem_embed`` False), box prompts
go to the prompt encoder as boxes (``boxes_as_points`` False, as SAM v1's predictors pass them),
and ``padded_input`` tells the backend that the view is resized by its longest side and padded
(:mod:`lfsam.segmenters.transformers.sam1`; docs/design.md section 3.8).

An image encoder built of ``timm`` blocks with inference-time fusions (EdgeTAM's RepViT: each
convolution's batch norm, and each RepVGG block's 3x3, 1x1 and identity branches, folded into one
convolution) runs fused (:func:`fuse_timm_encoder`; the segmenter runs it channels-last): the
same function, 1.5x faster on a CPU (docs/design.md section 3.8, "EdgeTAM's encoder fused").
"""

from __future__ import annotations

from typing import Any

import torch
from torch import nn

from lfsam.segmenters.transformers.heads import build_meta_heads, load_meta_heads

__all__ = ["CachedPositions", "TransformersImageModel", "fuse_timm_encoder"]


class CachedPositions(nn.Module):
    """The FPN neck's sine position encodings, made once per feature-map size.

    ``transformers`` builds them on every forward (a one-entry cache for the neck's four sizes:
    about 0.1 s per view for EdgeTAM on a CPU, for maps lfsam's image path never reads); they
    depend only on the size, so they are kept here, one batch row per size, and expanded.

    Parameters
    ----------
    encoding : nn.Module
        The neck's ``position_encoding`` (called as ``encoding(shape, device, dtype)``).
    """

    def __init__(self, encoding: nn.Module) -> None:
        super().__init__()
        self.encoding = encoding
        self._made: dict[tuple[Any, ...], torch.Tensor] = {}

    def forward(
        self, shape: torch.Size, device: torch.device | str, dtype: torch.dtype,
        mask: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """The encoding of a ``(B, C, H, W)`` map (computed afresh only with a mask)."""
        if mask is not None:
            return self.encoding(shape, device, dtype, mask)
        key = (tuple(shape[1:]), str(device), dtype)
        if key not in self._made:
            self._made[key] = self.encoding(torch.Size((1, *shape[1:])), device, dtype)
        return self._made[key].expand(shape[0], -1, -1, -1)


def fuse_timm_encoder(hf_model: nn.Module) -> bool:
    """Fold the inference-time branches of a ``timm`` image encoder into single convolutions,
    in place; False (and nothing changed) for an encoder that is not ``timm``'s.

    ``timm.utils.model.reparameterize_model`` replaces each module that has a ``fuse`` method
    with its fused form: in EdgeTAM's RepViT every ``ConvNorm`` (convolution + batch norm) and
    every ``RepVggDw`` (3x3 depth-wise convolution + 1x1 depth-wise convolution + identity +
    batch norm) becomes one convolution, the structural re-parameterisation RepViT was designed
    for (Wang et al., "RepViT: Revisiting Mobile CNN From ViT Perspective", CVPR 2024). In eval
    mode the function is the same; floating-point sums in another order give embeddings within
    about 1e-6 of the unfused ones (relative to their largest value; ``tests/
    test_segmenters_transformers.py``). The segmenter then runs the encoder channels-last, the
    layout oneDNN's convolutions run fastest on (``TransformersSegmenter``). Measured on the
    2-core CPU (docs/performance.md, "EdgeTAM's encoder fused"): one 1024 x 1024 view 0.99 s
    unfused, 0.89 s fused, 0.67 s fused and channels-last.

    Parameters
    ----------
    hf_model : nn.Module
        A ``transformers`` SAM 2-family model (``EdgeTamModel``; others are left alone).

    Returns
    -------
    bool
        Whether the encoder was fused.
    """
    backbone = getattr(getattr(hf_model, "vision_encoder", None), "backbone", None)
    timm_model = getattr(backbone, "timm_model", None)
    if timm_model is None:
        return False
    from timm.utils.model import reparameterize_model

    with torch.no_grad():
        reparameterize_model(timm_model, inplace=True)
    return True


class TransformersImageModel(nn.Module):
    """SAM 2's image model from a ``transformers`` checkpoint (``Sam2Model``, ``EdgeTamModel``).

    Parameters
    ----------
    hf_model : transformers.PreTrainedModel
        ``Sam2Model``, ``EdgeTamModel`` or ``SamModel`` (its heads' weights are copied into
        Meta's modules).
    info : dict
        What :func:`lfsam.segmenters.transformers.build.build_transformers_sam` knows of the model
        (name, hub_id, checkpoint, model_type, random_weights, seed); ``params`` and
        ``image_size`` are added.
    """

    directly_add_no_mem_embed = True
    use_high_res_features_in_sam = True
    num_feature_levels = 3
    boxes_as_points = True
    padded_input = False

    def __init__(self, hf_model: nn.Module, info: dict[str, Any]) -> None:
        super().__init__()
        config = hf_model.config
        heads = build_meta_heads(config)
        load_meta_heads(heads, hf_model.state_dict())
        neck = hf_model.vision_encoder.neck
        if hasattr(neck, "position_encoding"):  # SAM 2's FPN (SamModel's neck has none)
            neck.position_encoding = CachedPositions(neck.position_encoding)
        if config.model_type == "sam":
            self.directly_add_no_mem_embed = False
            self.use_high_res_features_in_sam = False
            self.num_feature_levels = 1
            self.boxes_as_points = False
            self.padded_input = True
        self.hf_model = hf_model
        self.sam_prompt_encoder = heads.sam_prompt_encoder
        self.sam_mask_decoder = heads.sam_mask_decoder
        self.no_mem_embed = heads.no_mem_embed
        self.image_size = int(config.prompt_encoder_config.image_size)
        self.lfsam_info = {
            **info,
            "params": int(sum(p.numel() for p in hf_model.parameters())),
            "image_size": self.image_size,
        }
        #: the encoder's timm blocks fused (EdgeTAM; :func:`fuse_timm_encoder`)
        self.fused_encoder = fuse_timm_encoder(hf_model)

    @property
    def device(self) -> torch.device:
        """Where the weights are."""
        return self.no_mem_embed.device

    def image_embeddings(self, pixel_values: torch.Tensor) -> list[torch.Tensor]:
        """``transformers``' image embeddings of a normalised batch ``(B, 3, S, S)``: the two
        high-resolution levels after the decoder's 1x1 convolutions and the embedding with the
        no-memory embedding added, each ``(B, C, H, W)``, finest first (SAM v1: the embedding
        alone)."""
        if self.padded_input:
            return [self.hf_model.get_image_embeddings(pixel_values)]
        return list(self.hf_model.get_image_embeddings(pixel_values))

    def forward_image(self, img_batch: torch.Tensor) -> dict[str, Any]:
        """Meta's ``SAM2Base.forward_image`` output for a normalised batch (without the
        no-memory embedding, which the caller adds as for Meta's models; SAM v1: one level,
        with the prompt encoder's dense positional encoding)."""
        if self.padded_input:
            embed = self.hf_model.get_image_embeddings(img_batch)
            pos = self.hf_model.get_image_wide_positional_embeddings().to(embed.dtype)
            pos = pos.expand(embed.shape[0], -1, -1, -1)
            return {"vision_features": embed, "vision_pos_enc": [pos], "backbone_fpn": [embed]}
        out = self.hf_model.get_image_features(img_batch, return_dict=True)
        sizes = self.hf_model.config.vision_config.backbone_feature_sizes
        batch = img_batch.shape[0]

        def grid(flat: torch.Tensor, size: list[int]) -> torch.Tensor:
            return flat.permute(1, 2, 0).reshape(batch, -1, *size)

        levels = [grid(f, s) for f, s in zip(out.fpn_hidden_states, sizes, strict=True)]
        pos = [grid(p, s) for p, s in zip(out.fpn_position_encoding, sizes, strict=True)]
        return {"vision_features": levels[-1], "vision_pos_enc": pos, "backbone_fpn": levels}

    def _prepare_backbone_features(
        self, backbone_out: dict[str, Any]
    ) -> tuple[dict[str, Any], list[torch.Tensor], list[torch.Tensor], list[tuple[int, int]]]:
        """Flattened features ``(HW, B, C)`` and their sizes, as Meta's method returns them."""
        maps = backbone_out["backbone_fpn"][-self.num_feature_levels :]
        pos = backbone_out["vision_pos_enc"][-self.num_feature_levels :]
        sizes = [(int(x.shape[-2]), int(x.shape[-1])) for x in pos]
        flat = [x.flatten(2).permute(2, 0, 1) for x in maps]
        flat_pos = [x.flatten(2).permute(2, 0, 1) for x in pos]
        return backbone_out, flat, flat_pos, sizes
