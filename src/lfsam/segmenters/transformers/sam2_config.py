"""The architecture of Meta's SAM 2 image model as a ``transformers`` ``Sam2Config`` (step 1 of
:mod:`lfsam.segmenters.transformers.convert`): :func:`sam2_config_for` reads it from the built
Meta modules (widths, depths, heads, windows, pooling, neck levels, decoder sizes, dynamic
multimask settings) and refuses the few settings ``Sam2Model`` cannot express (e.g. bilinear FPN
interpolation, no object-score head, IoU head without sigmoid), raising
:class:`lfsam.errors.LfsamError`. ``transformers`` is imported only inside the function.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import torch
from torch import nn

from lfsam.errors import LfsamError

if TYPE_CHECKING:
    import transformers
    from sam2.modeling.sam2_base import SAM2Base



# --- configuration --------------------------------------------------------------------------
def require(condition: bool, what: str) -> None:
    if not condition:
        raise LfsamError(f"cannot convert this SAM 2 model to transformers' Sam2Model: {what}")

__all__ = ["sam2_config_for"]


def _pair(value: int | tuple[int, ...]) -> list[int]:
    return [value, value] if isinstance(value, int) else [int(v) for v in value]


def _is_exact_gelu(module: nn.Module) -> bool:
    return isinstance(module, nn.GELU) and module.approximate == "none"


def _conv_out(size: int, kernel: int, stride: int, padding: int) -> int:
    return (size + 2 * padding - kernel) // stride + 1


def _hiera_config(trunk: Any, image_size: int) -> dict[str, Any]:
    """``Sam2HieraDetConfig`` arguments of a built Meta ``Hiera``."""
    from sam2.modeling.backbones.hieradet import Hiera

    require(isinstance(trunk, Hiera), f"trunk is {type(trunk).__name__}, not Hiera")
    blocks = list(trunk.blocks)
    stage_ends = [int(e) for e in trunk.stage_ends]
    starts = [0] + [e + 1 for e in stage_ends[:-1]]
    proj = trunk.patch_embed.proj
    first = blocks[0]
    mlp_ratio = first.mlp.layers[0].out_features / first.dim_out
    for i, block in enumerate(blocks):
        require(
            len(block.mlp.layers) == 2, f"trunk block {i} MLP has {len(block.mlp.layers)} layers"
        )
        require(
            block.mlp.layers[0].out_features == int(block.dim_out * mlp_ratio),
            f"trunk block {i} has another MLP ratio than block 0",
        )
        require(_is_exact_gelu(block.mlp.act), f"trunk block {i} MLP activation is not GELU")
        require(
            isinstance(block.norm1, nn.LayerNorm) and block.norm1.eps == first.norm1.eps,
            f"trunk block {i} norm is not LayerNorm(eps={first.norm1.eps})",
        )
    return {
        "hidden_size": int(proj.out_channels),
        "num_attention_heads": int(first.attn.num_heads),
        "num_channels": int(proj.in_channels),
        "image_size": [image_size, image_size],
        "patch_kernel_size": _pair(proj.kernel_size),
        "patch_stride": _pair(proj.stride),
        "patch_padding": _pair(proj.padding),
        "query_stride": _pair(trunk.q_stride),
        "window_positional_embedding_background_size": [int(s) for s in trunk.pos_embed.shape[2:]],
        "num_query_pool_stages": len(trunk.q_pool_blocks),
        "blocks_per_stage": [e - s + 1 for s, e in zip(starts, stage_ends, strict=True)],
        "embed_dim_per_stage": [int(blocks[e].dim_out) for e in stage_ends],
        "num_attention_heads_per_stage": [int(blocks[e].attn.num_heads) for e in stage_ends],
        "window_size_per_stage": [int(w) for w in trunk.window_spec],
        "global_attention_blocks": [int(b) for b in (trunk.global_att_blocks or ())],
        "mlp_ratio": float(mlp_ratio),
        "hidden_act": "gelu",
        "layer_norm_eps": float(first.norm1.eps),
    }


def _level_sizes(hiera: dict[str, Any], n_levels: int) -> list[list[int]]:
    """Spatial size of the trunk's first ``n_levels`` stage outputs (highest resolution first)."""
    sizes = []
    h, w = hiera["image_size"]
    (kh, kw), (sh, sw), (ph, pw) = (
        hiera["patch_kernel_size"],
        hiera["patch_stride"],
        hiera["patch_padding"],
    )
    h, w = _conv_out(h, kh, sh, ph), _conv_out(w, kw, sw, pw)
    qh, qw = hiera["query_stride"]
    for level in range(n_levels):
        if 0 < level <= hiera["num_query_pool_stages"]:
            h, w = h // qh, w // qw
        sizes.append([h, w])
    return sizes


def sam2_config_for(model: SAM2Base) -> transformers.Sam2Config:
    """A transformers Sam2Config with the same architecture as the Meta model (read from the built
    modules' attributes/shapes: trunk embed dim, heads, stages, global attention blocks, window
    sizes, window-pos-embed background size, q_pool/q_stride, neck d_model, backbone_channel_list,
    fpn_top_down_levels, scalp/num_feature_levels, image_size, backbone feature sizes, mask decoder
    and prompt encoder widths, mlp dims, iou head depth, dynamic multimask settings).

    Parameters
    ----------
    model : SAM2Base
        A built Meta SAM 2 model (image or video class).

    Returns
    -------
    transformers.Sam2Config

    Raises
    ------
    LfsamError
        A setting ``Sam2Model`` cannot express: no high-resolution features in the decoder, a
        number of feature levels other than 3, bilinear or averaging FPN fusion, a decoder
        without the object-score MLP or without sigmoid on the IoU head, other activations or
        MLP depths than ``Sam2Model`` hard-codes.
    """
    from sam2.modeling.backbones.image_encoder import FpnNeck
    from sam2.modeling.position_encoding import PositionEmbeddingSine
    from sam2.modeling.sam2_utils import MLP
    from transformers import (
        Sam2Config,
        Sam2HieraDetConfig,
        Sam2MaskDecoderConfig,
        Sam2PromptEncoderConfig,
        Sam2VisionConfig,
    )

    image_size = int(model.image_size)
    encoder = model.image_encoder
    neck = encoder.neck
    hiera = _hiera_config(encoder.trunk, image_size)

    # FPN neck
    require(isinstance(neck, FpnNeck), f"neck is {type(neck).__name__}, not FpnNeck")
    require(neck.fpn_interp_model == "nearest", f"FPN interpolation {neck.fpn_interp_model!r}")
    require(neck.fuse_type == "sum", f"FPN fuse type {neck.fuse_type!r}")
    pos = neck.position_encoding
    require(
        isinstance(pos, PositionEmbeddingSine)
        and pos.normalize
        and pos.temperature == 10000
        and abs(pos.scale - 2 * torch.pi) < 1e-12
        and 2 * pos.num_pos_feats == neck.d_model,
        "neck position encoding is not the normalised sine encoding of the neck width",
    )
    conv = neck.convs[0].conv
    channels = [int(c) for c in neck.backbone_channel_list]
    require(
        channels == [int(c) for c in encoder.trunk.channel_list],
        f"neck channels {channels} are not the trunk's {encoder.trunk.channel_list}",
    )
    n_levels = len(channels) - int(encoder.scalp)
    require(
        model.use_high_res_features_in_sam and model.num_feature_levels == 3 and n_levels == 3,
        f"the decoder must use 3 feature levels with high-resolution features (levels after "
        f"scalp {n_levels}, use_high_res_features_in_sam={model.use_high_res_features_in_sam})",
    )
    feature_sizes = _level_sizes(hiera, n_levels)
    embed_size = int(model.sam_image_embedding_size)
    require(
        feature_sizes[-1] == [embed_size, embed_size],
        f"lowest feature level {feature_sizes[-1]} is not the SAM embedding size {embed_size}",
    )
    vision = Sam2VisionConfig(
        backbone_config=Sam2HieraDetConfig(**hiera),
        backbone_channel_list=channels,
        backbone_feature_sizes=feature_sizes,
        fpn_hidden_size=int(neck.d_model),
        fpn_kernel_size=_pair(conv.kernel_size)[0],
        fpn_stride=_pair(conv.stride)[0],
        fpn_padding=_pair(conv.padding)[0],
        fpn_top_down_levels=[int(level) for level in neck.fpn_top_down_levels],
        num_feature_levels=n_levels,
        hidden_act="gelu",
        layer_norm_eps=hiera["layer_norm_eps"],
    )

    # prompt encoder
    pe = model.sam_prompt_encoder
    down = pe.mask_downscaling
    require(
        tuple(pe.input_image_size) == (image_size, image_size)
        and pe.image_embedding_size[0] == pe.image_embedding_size[1]
        and image_size % pe.image_embedding_size[0] == 0,
        f"prompt encoder sizes {pe.input_image_size} / {pe.image_embedding_size}",
    )
    require(
        _is_exact_gelu(down[2]) and _is_exact_gelu(down[5]) and down[1].eps == down[4].eps,
        "mask downscaling is not conv-LayerNorm2d-GELU twice",
    )
    prompt = Sam2PromptEncoderConfig(
        hidden_size=int(pe.embed_dim),
        image_size=image_size,
        patch_size=image_size // int(pe.image_embedding_size[0]),
        mask_input_channels=int(down[3].out_channels),
        num_point_embeddings=len(pe.point_embeddings),
        hidden_act="gelu",
        layer_norm_eps=float(down[1].eps),
    )

    # mask decoder
    md = model.sam_mask_decoder
    tr = md.transformer
    blocks = list(tr.layers)
    require(md.use_high_res_features, "mask decoder without high-resolution features")
    require(
        md.pred_obj_scores and isinstance(md.pred_obj_score_head, MLP),
        "mask decoder without the object-score MLP (pred_obj_scores_mlp)",
    )
    require(md.iou_prediction_head.sigmoid_output, "IoU head without sigmoid")
    require(_is_exact_gelu(md.output_upscaling[2]), "upscaling activation is not GELU")
    require(
        all(len(b.mlp.layers) == len(blocks) and isinstance(b.mlp.act, nn.ReLU) for b in blocks),
        "Sam2Model ties the two-way MLP depth to the number of blocks, with ReLU",
    )
    cross = blocks[0].cross_attn_token_to_image
    decoder = Sam2MaskDecoderConfig(
        hidden_size=int(md.transformer_dim),
        hidden_act="gelu",
        mlp_dim=int(tr.mlp_dim),
        num_hidden_layers=len(blocks),
        num_attention_heads=int(tr.num_heads),
        attention_downsample_rate=int(cross.embedding_dim // cross.internal_dim),
        num_multimask_outputs=int(md.num_multimask_outputs),
        iou_head_depth=int(md.iou_prediction_head.num_layers),
        iou_head_hidden_dim=int(md.iou_prediction_head.layers[0].out_features),
        dynamic_multimask_via_stability=bool(md.dynamic_multimask_via_stability),
        dynamic_multimask_stability_delta=float(md.dynamic_multimask_stability_delta),
        dynamic_multimask_stability_thresh=float(md.dynamic_multimask_stability_thresh),
    )
    return Sam2Config(
        vision_config=vision, prompt_encoder_config=prompt, mask_decoder_config=decoder
    )
