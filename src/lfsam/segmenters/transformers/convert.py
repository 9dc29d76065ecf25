"""Meta's SAM 2 image model as a Hugging Face ``transformers`` ``Sam2Model``.

lfsam has two ways to run SAM 2: on Meta's ``sam2`` package (``SAM2Base``,
:mod:`lfsam.segmenters.sam2.build`) and on ``transformers``' ``Sam2Model``. This module carries
one model's weights from the first to the second, so that parity tests can compare the two
backends on the same weights, including random ones and the tiny test model ``sam2-tiny-test``
that has no published checkpoint (docs/design.md section 6). It follows what ``transformers``'
own SAM 2 conversion does for the image part: Hiera trunk, FPN neck, prompt encoder, mask decoder
and the no-memory embedding. The memory modules (memory attention, memory encoder, object
pointers) have no counterpart in ``Sam2Model`` and are left out.

Three steps, each usable alone:

- :func:`sam2_config_for` reads the architecture from the built Meta modules (widths, depths,
  heads, windows, pooling, neck levels, decoder sizes, dynamic multimask settings) and refuses
  the few settings ``Sam2Model`` cannot express (e.g. bilinear FPN interpolation, no object-score
  head, IoU head without sigmoid).
- :func:`sam2_state_dict_to_transformers` renames the keys (Meta's ``norm1`` -> ``layer_norm1``,
  ``out_proj`` -> ``o_proj``, MLP ``layers.{0..d-1}`` -> ``proj_in, layers.*, proj_out``, ...),
  merges the four point embeddings into one table and writes the random Fourier matrix of the
  prompt encoder to both places ``Sam2Model`` keeps it.
- :func:`sam2_to_transformers` builds the ``Sam2Model`` and loads the converted weights,
  requiring every key to be filled with a tensor of the right shape.

The same mapping also names the heads of ``transformers``' ``SamModel`` (SAM v1, SlimSAM,
MedSAM; ``target="SamModel"``, used by :func:`lfsam.segmenters.transformers.heads.load_meta_heads`):
``SamModel`` spells three of ``Sam2Model``'s head names differently (:data:`_SAM_V1_NAMES`:
attention ``out_proj`` for ``o_proj``, the two-way blocks' MLP ``lin1``/``lin2`` for
``proj_in``/``proj_out``) and keeps the four point embeddings as four one-row tables
(``prompt_encoder.point_embed.{i}.weight``); it has no no-memory embedding, no object-score head
and no high-resolution convolutions (docs/design.md section 3.8).

Every mismatch (unknown or missing key, wrong shape, unsupported setting) raises
:class:`lfsam.errors.LfsamError` naming the keys. ``transformers`` is imported only inside the
functions: it is an optional dependency of :mod:`lfsam.segmenters`.

Notes
-----
Feeding the same normalised pixels to both, ``Sam2Model.get_image_embeddings`` equals Meta's
``forward_image`` -> ``_prepare_backbone_features`` -> ``+ no_mem_embed`` (what
``SAM2ImagePredictor.set_image`` does), and ``Sam2Model(image_embeddings=..., input_points=...,
input_labels=..., input_boxes=...)`` equals ``SAM2ImagePredictor``'s prompt path (a box is two
points with labels 2 and 3 plus a padding point) up to float rounding. Meta's prompt encoder
called with ``boxes=`` directly adds no padding point and so differs from both.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import torch
from torch import nn

from lfsam.errors import LfsamError

if TYPE_CHECKING:
    import transformers
    from sam2.modeling.sam2_base import SAM2Base

__all__ = [
    "TARGETS",
    "sam2_config_for",
    "sam2_state_dict_to_transformers",
    "sam2_to_transformers",
]

# Meta state-dict entries of the video (memory) part: no counterpart in Sam2Model, dropped.
_MEMORY_PARAMS = frozenset(
    {"maskmem_tpos_enc", "no_mem_pos_enc", "no_obj_ptr", "no_obj_embed_spatial"}
)
_MEMORY_MODULES = (
    "memory_attention.",
    "memory_encoder.",
    "mask_downsample.",
    "obj_ptr_proj.",
    "obj_ptr_tpos_proj.",
)

_PE_MATRIX = "sam_prompt_encoder.pe_layer.positional_encoding_gaussian_matrix"
_PE_TARGETS = (
    "prompt_encoder.shared_embedding.positional_embedding",
    "shared_image_embedding.positional_embedding",
)
_POINT_EMBED = re.compile(r"sam_prompt_encoder\.point_embeddings\.(\d+)\.weight")
_POINT_TARGET = "prompt_encoder.point_embed.weight"
_NO_MEM = "no_mem_embed"

TARGETS = ("Sam2Model", "SamModel")
"""The ``transformers`` classes whose names :func:`sam2_state_dict_to_transformers` writes
(``Sam2Model``'s names are also ``EdgeTamModel``'s for the heads)."""

_SAM_V1_NAMES: tuple[tuple[re.Pattern[str], str], ...] = (
    (re.compile(r"\.o_proj\."), ".out_proj."),
    (re.compile(r"(transformer\.layers\.\d+\.mlp)\.proj_in\."), r"\1.lin1."),
    (re.compile(r"(transformer\.layers\.\d+\.mlp)\.proj_out\."), r"\1.lin2."),
)
"""Where ``SamModel`` names a ``Sam2Model`` head parameter differently (applied to the names the
rules below give): its attentions' output projection and its two-way blocks' two-layer MLP."""

_WB = r"(?P<wb>weight|bias)"
_MLP_LAYER = r"layers\.(?P<layer>\d+)\." + _WB
_MASK_DOWNSCALING = {
    "0": "conv1",
    "1": "layer_norm1",
    "3": "conv2",
    "4": "layer_norm2",
    "6": "conv3",
}
_OUTPUT_UPSCALING = {"0": "upscale_conv1", "1": "upscale_layer_norm", "3": "upscale_conv2"}
_ATTN_PROJ = {"q_proj": "q_proj", "k_proj": "k_proj", "v_proj": "v_proj", "out_proj": "o_proj"}

# (Meta key pattern, HF key template, group -> {Meta name: HF name}). ``{mlp}`` in a template is
# the HF name of Meta's MLP layer ``layers.{layer}``: proj_in, layers.{layer - 1}, proj_out.
_RULES: tuple[tuple[re.Pattern[str], str, dict[str, dict[str, str]]], ...] = tuple(
    (re.compile(pattern), template, maps)
    for pattern, template, maps in (
        # Hiera trunk
        (
            r"image_encoder\.trunk\.(?P<p>pos_embed|pos_embed_window)",
            "vision_encoder.backbone.{p}",
            {},
        ),
        (
            r"image_encoder\.trunk\.patch_embed\.proj\." + _WB,
            "vision_encoder.backbone.patch_embed.projection.{wb}",
            {},
        ),
        (
            r"image_encoder\.trunk\.blocks\.(?P<b>\d+)\.norm(?P<n>[12])\." + _WB,
            "vision_encoder.backbone.blocks.{b}.layer_norm{n}.{wb}",
            {},
        ),
        (
            r"image_encoder\.trunk\.blocks\.(?P<b>\d+)\.(?P<m>attn\.qkv|attn\.proj|proj)\." + _WB,
            "vision_encoder.backbone.blocks.{b}.{m}.{wb}",
            {},
        ),
        (
            r"image_encoder\.trunk\.blocks\.(?P<b>\d+)\.mlp\." + _MLP_LAYER,
            "vision_encoder.backbone.blocks.{b}.mlp.{mlp}.{wb}",
            {},
        ),
        # FPN neck (Meta wraps each lateral conv in a Sequential named "conv")
        (
            r"image_encoder\.neck\.convs\.(?P<i>\d+)\.conv\." + _WB,
            "vision_encoder.neck.convs.{i}.{wb}",
            {},
        ),
        # prompt encoder (the point embeddings and the Fourier matrix are handled apart)
        (
            r"sam_prompt_encoder\.mask_downscaling\.(?P<i>\d+)\." + _WB,
            "prompt_encoder.mask_embed.{i}.{wb}",
            {"i": _MASK_DOWNSCALING},
        ),
        (
            r"sam_prompt_encoder\.(?P<e>no_mask_embed|not_a_point_embed)\.weight",
            "prompt_encoder.{e}.weight",
            {},
        ),
        # mask decoder: two-way transformer
        (
            r"sam_mask_decoder\.transformer\.layers\.(?P<l>\d+)\."
            r"(?P<a>self_attn|cross_attn_token_to_image|cross_attn_image_to_token)\."
            r"(?P<p>q_proj|k_proj|v_proj|out_proj)\." + _WB,
            "mask_decoder.transformer.layers.{l}.{a}.{p}.{wb}",
            {"p": _ATTN_PROJ},
        ),
        (
            r"sam_mask_decoder\.transformer\.layers\.(?P<l>\d+)\.norm(?P<n>[1-4])\." + _WB,
            "mask_decoder.transformer.layers.{l}.layer_norm{n}.{wb}",
            {},
        ),
        (
            r"sam_mask_decoder\.transformer\.layers\.(?P<l>\d+)\.mlp\." + _MLP_LAYER,
            "mask_decoder.transformer.layers.{l}.mlp.{mlp}.{wb}",
            {},
        ),
        (
            r"sam_mask_decoder\.transformer\.final_attn_token_to_image\."
            r"(?P<p>q_proj|k_proj|v_proj|out_proj)\." + _WB,
            "mask_decoder.transformer.final_attn_token_to_image.{p}.{wb}",
            {"p": _ATTN_PROJ},
        ),
        (
            r"sam_mask_decoder\.transformer\.norm_final_attn\." + _WB,
            "mask_decoder.transformer.layer_norm_final_attn.{wb}",
            {},
        ),
        # mask decoder: heads
        (
            r"sam_mask_decoder\.output_upscaling\.(?P<i>\d+)\." + _WB,
            "mask_decoder.{i}.{wb}",
            {"i": _OUTPUT_UPSCALING},
        ),
        (
            r"sam_mask_decoder\.(?P<h>output_hypernetworks_mlps\.\d+|iou_prediction_head"
            r"|pred_obj_score_head)\." + _MLP_LAYER,
            "mask_decoder.{h}.{mlp}.{wb}",
            {},
        ),
        (
            r"sam_mask_decoder\.(?P<c>conv_s0|conv_s1)\." + _WB,
            "mask_decoder.{c}.{wb}",
            {},
        ),
        (
            r"sam_mask_decoder\.(?P<t>iou_token|mask_tokens|obj_score_token)\.weight",
            "mask_decoder.{t}.weight",
            {},
        ),
        (r"no_mem_embed", "no_memory_embedding", {}),
    )
)


def _is_memory_key(key: str) -> bool:
    return key in _MEMORY_PARAMS or key.startswith(_MEMORY_MODULES)


def _mlp_depths(keys: list[str]) -> dict[str, int]:
    """Number of linear layers of every ``<prefix>.layers.<j>.*`` group among ``keys``."""
    depths: dict[str, int] = {}
    for key in keys:
        match = re.fullmatch(r"(?P<prefix>.+)\.layers\.(?P<j>\d+)\.(?:weight|bias)", key)
        if match:
            prefix, j = match["prefix"], int(match["j"])
            depths[prefix] = max(depths.get(prefix, 0), j + 1)
    return depths


def _mlp_name(key: str, layer: int, depths: dict[str, int]) -> str:
    """HF name of Meta's MLP layer ``layer`` (``Sam2FeedForward``: proj_in, layers, proj_out)."""
    depth = depths[key.rsplit(".layers.", 1)[0]]
    if depth < 2:
        raise LfsamError(f"cannot convert {key}: Sam2Model has no MLP with a single layer")
    if layer == 0:
        return "proj_in"
    if layer == depth - 1:
        return "proj_out"
    return f"layers.{layer - 1}"


def _rename(key: str, depths: dict[str, int], target: str = "Sam2Model") -> str | None:
    """The HF key of one Meta key in ``target``'s names, or None if no rule knows it."""
    name = _rename_sam2(key, depths)
    if name is not None and target == "SamModel":
        for pattern, replacement in _SAM_V1_NAMES:
            name = pattern.sub(replacement, name)
    return name


def _rename_sam2(key: str, depths: dict[str, int]) -> str | None:
    for pattern, template, maps in _RULES:
        match = pattern.fullmatch(key)
        if match is None:
            continue
        groups = dict(match.groupdict())
        for name, table in maps.items():
            if groups[name] not in table:
                return None
            groups[name] = table[groups[name]]
        if "layer" in groups:
            groups["mlp"] = _mlp_name(key, int(groups.pop("layer")), depths)
        return template.format(**groups)
    return None


def _preview(keys: list[str], limit: int = 8) -> str:
    shown = ", ".join(keys[:limit])
    return shown + (f" and {len(keys) - limit} more" if len(keys) > limit else "")


def sam2_state_dict_to_transformers(
    state_dict: Mapping[str, torch.Tensor],
    *,
    reference: Mapping[str, torch.Tensor] | None = None,
    target: str = "Sam2Model",
) -> dict[str, torch.Tensor]:
    """Meta ``SAM2Base`` state dict (image part) -> ``Sam2Model`` (or ``SamModel``) keys.

    Parameters
    ----------
    state_dict : mapping of str to torch.Tensor
        ``SAM2Base.state_dict()`` (or the ``"model"`` entry of a SAM 2 checkpoint). The memory
        modules' entries are dropped.
    reference : mapping of str to torch.Tensor, optional
        The target model's own ``state_dict()`` (with ``SamModel``: its head entries). When
        given, the result must have exactly its keys, each with the same shape.
    target : {"Sam2Model", "SamModel"}
        Whose names to write (:data:`TARGETS`). ``SamModel`` (SAM v1's heads as Meta's SAM 2
        modules built without high-resolution features and object scores,
        :func:`lfsam.segmenters.transformers.heads.build_meta_heads`): the renames of
        :data:`_SAM_V1_NAMES`, the point embeddings kept one table each, and no no-memory
        embedding (an entry ``no_mem_embed`` is dropped; docs/design.md section 3.8).

    Returns
    -------
    dict of str to torch.Tensor
        The same tensors (not copied) under the target's names; for ``Sam2Model`` the four
        point embeddings stacked into ``prompt_encoder.point_embed.weight``; the prompt
        encoder's Fourier matrix under both of the target's names (the second a copy).

    Raises
    ------
    LfsamError
        A key no rule knows, a missing point embedding, Fourier matrix or (``Sam2Model``)
        no-memory embedding, or (with ``reference``) a missing or extra key or a wrong shape.
    """
    if target not in TARGETS:
        raise LfsamError(f"unknown transformers target {target!r}; choose one of {TARGETS}")
    sam_v1 = target == "SamModel"
    keys = [k for k in state_dict if not _is_memory_key(k) and not (sam_v1 and k == _NO_MEM)]
    depths = _mlp_depths(keys)
    out: dict[str, torch.Tensor] = {}
    points: dict[int, torch.Tensor] = {}
    unknown: list[str] = []
    for key in keys:
        tensor = state_dict[key]
        if key == _PE_MATRIX:
            out[_PE_TARGETS[0]] = tensor
            out[_PE_TARGETS[1]] = tensor.detach().clone()
            continue
        point = _POINT_EMBED.fullmatch(key)
        if point:
            points[int(point[1])] = tensor
            continue
        new_key = _rename(key, depths, target)
        if new_key is None:
            unknown.append(key)
        elif new_key in out:
            raise LfsamError(f"two SAM 2 keys map to the transformers key {new_key}")
        else:
            out[new_key] = tensor
    if unknown:
        raise LfsamError(
            f"unknown SAM 2 state-dict keys (not SAM2Base's image part): {_preview(unknown)}"
        )
    if _PE_MATRIX not in state_dict:
        raise LfsamError(f"SAM 2 state dict lacks {_PE_MATRIX}")
    if not sam_v1 and _NO_MEM not in state_dict:
        raise LfsamError("SAM 2 state dict lacks no_mem_embed")
    if not points or sorted(points) != list(range(len(points))):
        raise LfsamError(
            "SAM 2 state dict lacks sam_prompt_encoder.point_embeddings.{i}.weight for some of "
            f"i = 0..{max(points, default=3)} (found {sorted(points)})"
        )
    rows = [points[i] for i in range(len(points))]
    if any(r.dim() != 2 or r.shape[0] != 1 or r.shape != rows[0].shape for r in rows):
        raise LfsamError(
            "SAM 2 point embeddings must each be (1, C); got "
            + ", ".join(str(tuple(r.shape)) for r in rows)
        )
    if sam_v1:  # SamModel: one embedding table per point label
        out.update({f"prompt_encoder.point_embed.{i}.weight": row for i, row in enumerate(rows)})
    else:
        out[_POINT_TARGET] = torch.cat(rows, dim=0)
    if reference is not None:
        _check_against(out, reference)
    return out


def _check_against(
    converted: Mapping[str, torch.Tensor], reference: Mapping[str, torch.Tensor]
) -> None:
    """Raise unless ``converted`` has exactly ``reference``'s keys and shapes."""
    missing = sorted(set(reference) - set(converted))
    extra = sorted(set(converted) - set(reference))
    if missing or extra:
        parts = []
        if missing:
            parts.append(f"transformers keys not filled: {_preview(missing)}")
        if extra:
            parts.append(f"converted keys transformers does not have: {_preview(extra)}")
        raise LfsamError("SAM 2 -> transformers conversion mismatch; " + "; ".join(parts))
    wrong = [
        f"{k} {tuple(converted[k].shape)} vs {tuple(reference[k].shape)}"
        for k in sorted(reference)
        if converted[k].shape != reference[k].shape
    ]
    if wrong:
        raise LfsamError(f"SAM 2 -> transformers shape mismatch: {_preview(wrong)}")


# --- configuration --------------------------------------------------------------------------
def _require(condition: bool, what: str) -> None:
    if not condition:
        raise LfsamError(f"cannot convert this SAM 2 model to transformers' Sam2Model: {what}")


def _pair(value: int | tuple[int, ...]) -> list[int]:
    return [value, value] if isinstance(value, int) else [int(v) for v in value]


def _is_exact_gelu(module: nn.Module) -> bool:
    return isinstance(module, nn.GELU) and module.approximate == "none"


def _conv_out(size: int, kernel: int, stride: int, padding: int) -> int:
    return (size + 2 * padding - kernel) // stride + 1


def _hiera_config(trunk: Any, image_size: int) -> dict[str, Any]:
    """``Sam2HieraDetConfig`` arguments of a built Meta ``Hiera``."""
    from sam2.modeling.backbones.hieradet import Hiera

    _require(isinstance(trunk, Hiera), f"trunk is {type(trunk).__name__}, not Hiera")
    blocks = list(trunk.blocks)
    stage_ends = [int(e) for e in trunk.stage_ends]
    starts = [0] + [e + 1 for e in stage_ends[:-1]]
    proj = trunk.patch_embed.proj
    first = blocks[0]
    mlp_ratio = first.mlp.layers[0].out_features / first.dim_out
    for i, block in enumerate(blocks):
        _require(
            len(block.mlp.layers) == 2, f"trunk block {i} MLP has {len(block.mlp.layers)} layers"
        )
        _require(
            block.mlp.layers[0].out_features == int(block.dim_out * mlp_ratio),
            f"trunk block {i} has another MLP ratio than block 0",
        )
        _require(_is_exact_gelu(block.mlp.act), f"trunk block {i} MLP activation is not GELU")
        _require(
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
    _require(isinstance(neck, FpnNeck), f"neck is {type(neck).__name__}, not FpnNeck")
    _require(neck.fpn_interp_model == "nearest", f"FPN interpolation {neck.fpn_interp_model!r}")
    _require(neck.fuse_type == "sum", f"FPN fuse type {neck.fuse_type!r}")
    pos = neck.position_encoding
    _require(
        isinstance(pos, PositionEmbeddingSine)
        and pos.normalize
        and pos.temperature == 10000
        and abs(pos.scale - 2 * torch.pi) < 1e-12
        and 2 * pos.num_pos_feats == neck.d_model,
        "neck position encoding is not the normalised sine encoding of the neck width",
    )
    conv = neck.convs[0].conv
    channels = [int(c) for c in neck.backbone_channel_list]
    _require(
        channels == [int(c) for c in encoder.trunk.channel_list],
        f"neck channels {channels} are not the trunk's {encoder.trunk.channel_list}",
    )
    n_levels = len(channels) - int(encoder.scalp)
    _require(
        model.use_high_res_features_in_sam and model.num_feature_levels == 3 and n_levels == 3,
        f"the decoder must use 3 feature levels with high-resolution features (levels after "
        f"scalp {n_levels}, use_high_res_features_in_sam={model.use_high_res_features_in_sam})",
    )
    feature_sizes = _level_sizes(hiera, n_levels)
    embed_size = int(model.sam_image_embedding_size)
    _require(
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
    _require(
        tuple(pe.input_image_size) == (image_size, image_size)
        and pe.image_embedding_size[0] == pe.image_embedding_size[1]
        and image_size % pe.image_embedding_size[0] == 0,
        f"prompt encoder sizes {pe.input_image_size} / {pe.image_embedding_size}",
    )
    _require(
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
    _require(md.use_high_res_features, "mask decoder without high-resolution features")
    _require(
        md.pred_obj_scores and isinstance(md.pred_obj_score_head, MLP),
        "mask decoder without the object-score MLP (pred_obj_scores_mlp)",
    )
    _require(md.iou_prediction_head.sigmoid_output, "IoU head without sigmoid")
    _require(_is_exact_gelu(md.output_upscaling[2]), "upscaling activation is not GELU")
    _require(
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


def _check_structure(model: SAM2Base, hf: Any) -> None:
    """Raise unless each Hiera block of ``hf`` has the Meta block's dims, heads and windows."""
    meta_blocks = list(model.image_encoder.trunk.blocks)
    hf_blocks = list(hf.vision_encoder.backbone.blocks)
    _require(len(meta_blocks) == len(hf_blocks), "different numbers of trunk blocks")
    fields: list[tuple[str, Callable[[Any], Any], Callable[[Any], Any]]] = [
        ("dim", lambda b: b.dim, lambda b: b.dim),
        ("dim_out", lambda b: b.dim_out, lambda b: b.dim_out),
        ("heads", lambda b: b.attn.num_heads, lambda b: b.attn.num_attention_heads),
        ("window", lambda b: b.window_size, lambda b: b.window_size),
        (
            "q_stride",
            lambda b: None if not b.q_stride else list(b.q_stride),
            lambda b: None if not b.query_stride else list(b.query_stride),
        ),
    ]
    for i, (meta, ours) in enumerate(zip(meta_blocks, hf_blocks, strict=True)):
        for name, get_meta, get_hf in fields:
            _require(
                get_meta(meta) == get_hf(ours),
                f"trunk block {i} {name} {get_meta(meta)} != {get_hf(ours)} in Sam2Model",
            )


def sam2_to_transformers(model: SAM2Base) -> transformers.Sam2Model:
    """A transformers Sam2Model carrying exactly the Meta model's weights (eval mode, same device).

    Parameters
    ----------
    model : SAM2Base
        A built Meta SAM 2 model.

    Returns
    -------
    transformers.Sam2Model
        On the device and in the floating-point dtype of ``model``'s parameters, in eval mode
        (``Sam2Model`` applies the dynamic multimask fallback only in eval mode, like Meta's).

    Raises
    ------
    LfsamError
        See :func:`sam2_config_for` and :func:`sam2_state_dict_to_transformers`.
    """
    from transformers import Sam2Model

    config = sam2_config_for(model)
    hf = Sam2Model(config)
    _check_structure(model, hf)
    converted = sam2_state_dict_to_transformers(model.state_dict(), reference=hf.state_dict())
    hf.load_state_dict(converted, strict=True)
    param = next(model.parameters())
    return hf.to(device=param.device, dtype=param.dtype).eval()
