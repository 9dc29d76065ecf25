"""SAM 2's heads of a ``transformers`` model as Meta's modules (docs/design.md section 3.8).

``transformers``' ``Sam2Model`` and ``EdgeTamModel`` carry the prompt encoder and mask decoder of
SAM 2 (Ravi et al. 2024) under other names: EdgeTAM (Zhou et al. 2025, "EdgeTAM: On-Device
Track Anything Model") changes the image encoder and the memory, not the heads. lfsam decodes
with the restructured decoder of :mod:`lfsam.segmenters.sam2.decoder`, which shares a view's
image side across all its prompts (one transformers forward of 16 prompts costs more than one
EdgeTAM encoder pass on a CPU; docs/performance.md). So the heads' weights are loaded into Meta's
``PromptEncoder`` and ``MaskDecoder`` (same arithmetic) by :func:`load_meta_heads`, with the
one key mapping of :mod:`lfsam.segmenters.transformers.convert` (Meta to ``transformers``, the way
``transformers``' own SAM 2 conversion goes) read backwards.

``SamModel`` (SAM v1, Kirillov et al. 2023; also SlimSAM and MedSAM checkpoints) has the decoder
SAM 2 grew from: the same two-way transformer, output tokens and hypernetworks, without the
high-resolution maps, the object-score token and the sigmoid on the IoU head, and without the
dynamic multimask fallback. Meta's SAM 2 ``MaskDecoder`` built with those switched off computes
it, so lfsam's decoder runs SAM v1 too (docs/design.md section 3.8).
"""

from __future__ import annotations

from typing import Any

import torch
from torch import nn

from lfsam.errors import LfsamError

__all__ = ["MetaHeads", "build_meta_heads", "load_meta_heads"]

_POINT_EMBED = "prompt_encoder.point_embed.weight"
_IMAGE_PE = "shared_image_embedding.positional_embedding"
_PROMPT_PE = "prompt_encoder.shared_embedding.positional_embedding"


class MetaHeads(nn.Module):
    """Meta's prompt encoder, mask decoder and ``no_mem_embed``, built to a config's sizes.

    ``hf_class`` names the ``transformers`` class whose parameter names the heads are loaded
    from (``"Sam2Model"`` also for EdgeTAM, or ``"SamModel"``, whose ``no_mem_embed`` stays
    zero: SAM v1 has none).
    """

    def __init__(
        self, prompt_encoder: nn.Module, mask_decoder: nn.Module, width: int,
        hf_class: str = "Sam2Model",
    ) -> None:
        super().__init__()
        self.sam_prompt_encoder = prompt_encoder
        self.sam_mask_decoder = mask_decoder
        self.no_mem_embed = nn.Parameter(torch.zeros(1, 1, width))
        self.hf_class = hf_class


def build_meta_heads(config: Any) -> MetaHeads:
    """Meta's heads with the sizes of a ``transformers`` ``Sam2Config`` / ``EdgeTamConfig``, or
    of a ``SamConfig`` (SAM v1: no high-resolution features, no object scores, IoU head without
    sigmoid, no dynamic multimask; its two-way blocks' LayerNorm epsilon taken from the config).

    Raises
    ------
    LfsamError
        A config whose heads lfsam's decoder cannot run (not two two-way blocks; for SAM v1 a
        two-way MLP activation other than ReLU).
    """
    from sam2.modeling.sam.mask_decoder import MaskDecoder
    from sam2.modeling.sam.prompt_encoder import PromptEncoder
    from sam2.modeling.sam.transformer import TwoWayTransformer

    pe, md = config.prompt_encoder_config, config.mask_decoder_config
    if int(md.num_hidden_layers) != 2:
        raise LfsamError(
            f"mask decoder with {md.num_hidden_layers} layers: lfsam decodes SAM 2's two-layer "
            "decoder only; use a SAM 2 or EdgeTAM checkpoint"
        )
    sam_v1 = config.model_type == "sam"
    if sam_v1 and str(md.hidden_act) != "relu":
        raise LfsamError(
            f"SAM mask decoder with {md.hidden_act!r} MLPs: lfsam's decoder runs ReLU ones; use a "
            "SAM, SAM 2 or EdgeTAM checkpoint"
        )
    side = int(pe.image_size)
    grid = side // int(pe.patch_size)
    prompt_encoder = PromptEncoder(
        embed_dim=int(pe.hidden_size),
        image_embedding_size=(grid, grid),
        input_image_size=(side, side),
        mask_in_chans=int(pe.mask_input_channels),
    )
    transformer = TwoWayTransformer(
        depth=int(md.num_hidden_layers),
        embedding_dim=int(md.hidden_size),
        num_heads=int(md.num_attention_heads),
        mlp_dim=int(md.mlp_dim),
        attention_downsample_rate=int(md.attention_downsample_rate),
    )
    if sam_v1:
        decoder_args: dict[str, Any] = {"use_high_res_features": False,
                                        "iou_prediction_use_sigmoid": False,
                                        "dynamic_multimask_via_stability": False,
                                        "pred_obj_scores": False}
        for layer in transformer.layers:  # SamModel's blocks take the config's epsilon
            for norm in (layer.norm1, layer.norm2, layer.norm3, layer.norm4):
                norm.eps = float(md.layer_norm_eps)
    else:
        decoder_args = {
            "use_high_res_features": True,
            "iou_prediction_use_sigmoid": True,
            "dynamic_multimask_via_stability": bool(md.dynamic_multimask_via_stability),
            "dynamic_multimask_stability_delta": float(md.dynamic_multimask_stability_delta),
            "dynamic_multimask_stability_thresh": float(md.dynamic_multimask_stability_thresh),
            "pred_obj_scores": True,
            "pred_obj_scores_mlp": True,
            "use_multimask_token_for_obj_ptr": True,
        }
    mask_decoder = MaskDecoder(
        transformer_dim=int(md.hidden_size),
        transformer=transformer,
        num_multimask_outputs=int(md.num_multimask_outputs),
        iou_head_depth=int(md.iou_head_depth),
        iou_head_hidden_dim=int(md.iou_head_hidden_dim),
        **decoder_args,
    )
    hf_class = "SamModel" if sam_v1 else "Sam2Model"
    return MetaHeads(prompt_encoder, mask_decoder, int(pe.hidden_size), hf_class)


def load_meta_heads(heads: MetaHeads, hf_state: dict[str, torch.Tensor]) -> None:
    """Load the heads of a ``transformers`` state dict into ``heads`` (every key checked).

    The key mapping is
    :func:`lfsam.segmenters.transformers.convert.sam2_state_dict_to_transformers`'s
    (Meta to ``transformers``, in the names of ``heads.hf_class``), read backwards: each Meta
    tensor is filled from the ``transformers`` key it converts to; the rows of ``Sam2Model``'s
    ``prompt_encoder.point_embed`` are Meta's four point embeddings (``SamModel`` keeps them
    apart). ``shared_image_embedding.positional_embedding`` must equal the prompt encoder's (Meta
    has one matrix for both).

    Raises
    ------
    LfsamError
        Missing or differently shaped parameters, or two positional matrices that differ (a
        checkpoint lfsam's decoder cannot reproduce).
    """
    from lfsam.segmenters.transformers.convert import sam2_state_dict_to_transformers

    meta = heads.state_dict(keep_vars=True)
    # the same tensors under transformers' keys
    targets = sam2_state_dict_to_transformers(meta, target=heads.hf_class)
    missing = sorted(k for k in targets if k not in hf_state)
    shaped = sorted(k for k in targets if k in hf_state and hf_state[k].shape != targets[k].shape)
    if missing or shaped:
        example = (missing or shaped)[0]
        raise LfsamError(
            f"the checkpoint's SAM heads do not fit {heads.hf_class}'s ({len(missing)} missing, "
            f"{len(shaped)} differently shaped parameters, e.g. {example!r}); pass a SAM, SAM 2 "
            "or EdgeTAM checkpoint in transformers format"
        )
    if not torch.equal(hf_state[_IMAGE_PE], hf_state[_PROMPT_PE]):
        raise LfsamError(
            "this checkpoint's image and prompt positional encodings differ (SAM shares one); "
            "it was not converted from SAM, SAM 2 or EdgeTAM: re-save it with transformers from "
            "such a checkpoint"
        )
    with torch.no_grad():
        for key, tensor in targets.items():
            if key == _POINT_EMBED:
                for i, row in enumerate(hf_state[key]):
                    meta[f"sam_prompt_encoder.point_embeddings.{i}.weight"].copy_(row[None])
            elif key != _IMAGE_PE:  # the copy of the prompt encoder's matrix
                tensor.copy_(hf_state[key])
