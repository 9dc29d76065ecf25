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

- :func:`sam2_config_for` (:mod:`~lfsam.segmenters.transformers.sam2_config`) reads the
  architecture from the built Meta modules (widths, depths, heads, windows, pooling, neck
  levels, decoder sizes, dynamic multimask settings) and refuses the few settings ``Sam2Model``
  cannot express (e.g. bilinear FPN interpolation, no object-score head, IoU head without
  sigmoid).
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

from lfsam.errors import LfsamError
from lfsam.segmenters.transformers.sam2_config import require, sam2_config_for

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


def _check_structure(model: SAM2Base, hf: Any) -> None:
    """Raise unless each Hiera block of ``hf`` has the Meta block's dims, heads and windows."""
    meta_blocks = list(model.image_encoder.trunk.blocks)
    hf_blocks = list(hf.vision_encoder.backbone.blocks)
    require(len(meta_blocks) == len(hf_blocks), "different numbers of trunk blocks")
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
            require(
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
