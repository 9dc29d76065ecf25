"""SAM 2's mask decoder for many prompts on one image, restructured to share the image side.

:func:`decode_prompts` computes what ``SAM2ImagePredictor._predict`` computes before its
post-processing (prompt encoder, ``MaskDecoder.forward`` with its ``TwoWayTransformer``, token
selection, optional ``_dynamic_multimask_via_stability``, clamp of the logits to [-32, 32]) for N
prompts on one encoded image, but without ever copying the image embedding once per prompt. The
arithmetic is the same up to floating-point rounding (the rewrites below are exact identities);
tests/test_sam2_decoder.py checks it against Meta's code.

Why it is faster (lfsam issue #5). Meta's decoder repeats the 256 x 64 x 64 image embedding and its
positional encoding once per prompt and then runs every projection of the two-way transformer
(Kirillov et al. 2023, "Segment Anything", section 3 and appendix A; SAM 2, Ravi et al. 2024,
section 4, keeps that decoder) on B copies of the image. Here:

1. **Prompt-independent work is done once per image.** The dense prompt embedding without a mask
   input is ``no_mask_embed`` at every position, so ``image_embed + no_mask_embed`` is shared;
   so is the positional encoding. Until the first image-to-token attention has run, the image
   side of the transformer is the same for every prompt, so the first block's token-to-image keys
   ``k_proj(src + pe)`` and values ``v_proj(src)`` and its image-to-token queries
   ``q_proj(src + pe)`` are projected once; tokens of all prompts attend to those shared keys by
   batching the prompts along the query axis (no repeat copies). Positional-encoding projections
   of later blocks (``W_k pe``, ``W_q pe + b_q``) are also shared.
2. **Projections of per-prompt image tensors are moved to the token side**, where there are only
   ``heads x tokens`` rows (8 x 8 to 10) instead of 4096 pixels:

   * token-to-image scores ``(W_q t + b_q)_h . (W_k,h (x + pe) + b_k,h)`` equal
     ``((W_q t + b_q)_h W_k,h) . x + (W_q t + b_q)_h . (W_k,h pe)`` plus a term constant over
     the keys, ``(W_q t + b_q)_h . b_k,h``, which softmax ignores (softmax is shift invariant);
   * token-to-image outputs ``sum_i a_i (W_v,h x_i + b_v,h) = W_v,h (sum_i a_i x_i) + b_v,h``
     because the attention weights ``a_i`` sum to 1: the per-prompt value projection of the image
     becomes a projection of ``heads x tokens`` attention-weighted image sums;
   * image-to-token scores ``(W_q,h (x + pe) + b_q,h) . k_h = x . (W_q,h^T k_h) +
     (W_q,h pe + b_q,h) . k_h``: one product of the image with a ``C x (heads x tokens)`` matrix;
   * image-to-token outputs ``W_o concat_h(sum_j a_hj v_hj) + b_o =
     sum_h sum_j a_hj (W_o,h v_hj + b_o / heads)`` (weights of each head sum to 1): one product
     of the ``(pixels, heads x tokens)`` attention weights with per-prompt rows, fused with the
     residual add (``baddbmm``);
   * the final token-to-image attention and its norm act on each token separately, so they run
     only for the tokens the decoder reads (IoU token and the wanted mask tokens).

   Image-to-token scores are laid out (heads, tokens, pixels) so the softmax over the few tokens
   runs with the pixels contiguous (a softmax over a last axis of about 10 entries is ~20x
   slower on a CPU).
3. **The upscaling is written as matrix products in a pixel-block layout.** A transposed
   convolution with kernel 2 and stride 2 maps each input pixel to a 2 x 2 output block by one
   linear map (``out[c', 2y+di, 2x+dj] = sum_c W[c, c', di, dj] in[c, y, x] + b[c']``), so both
   upscaling steps are ``baddbmm`` calls whose additive input is the high-resolution feature map
   (plus bias) permuted once per image into the same block order; ``LayerNorm2d`` becomes
   ``F.layer_norm`` over the channel axis of that layout. Each embedding pixel feeds only its
   own 4 x 4 output block, so this runs on bands of embedding rows (:data:`DEFAULT_TILE_ROWS`)
   whose tensors stay in cache; each band's K mask logits (not its 32 feature maps) are
   unpermuted into the output.
4. **Prompts run in small chunks** (:func:`default_chunk_size`) so that the per-prompt
   image-sized tensors stay in cache.

Everything runs on the model's device in the caller's autocast context (bf16 on CUDA under
:func:`lfsam.segmenters.sam2.build.inference_context`), without autograd.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from lfsam.devices import CUDA_PROMPT_BATCH_SIZE
from lfsam.errors import LfsamError
from lfsam.segmenters.base import ABSENT_POINT
from lfsam.segmenters.sam2.image_state import ImageState
from lfsam.segmenters.sam2.two_way import _heads, absent_tokens, transformer

__all__ = [
    "ACCELERATOR_CHUNK_SIZE",
    "DEFAULT_CHUNK_SIZE",
    "DEFAULT_TILE_ROWS",
    "LOGIT_CLAMP",
    "ImageState",
    "absent_tokens",
    "decode_prompts",
    "default_chunk_size",
    "embed_prompts",
    "prepare_image",
    "stability_scores",
]

DEFAULT_CHUNK_SIZE = 2
"""Prompts decoded together by :func:`decode_prompts` on a CPU (measured best of 1, 2, 4, 8 on a
2-core CPU with ``sam2.1-hiera-small``, 16 prompts: benchmarks/bench_decoder.py)."""

ACCELERATOR_CHUNK_SIZE = CUDA_PROMPT_BATCH_SIZE
"""Chunk size :func:`default_chunk_size` gives for CUDA and MPS, where launch overhead, not cache
size, limits small batches (about 14 MB per prompt in float32). On an H100, 100 prompts per view
in one chunk instead of chunks of 16 took refinement of a 9x9x480x640 light field from 4.8 s to
the figure in docs/performance.md (benchmarks/bench_gpu.py)."""

DEFAULT_TILE_ROWS = 8
"""Embedding rows per band in the upscaling (:func:`_mask_logits`); 8 rows of a 64 x 64
embedding keep a band's tensors around 1 MB per prompt."""

LOGIT_CLAMP = 32.0
"""``SAM2ImagePredictor._predict`` clamps the returned low-resolution logits to +-32."""


# --- small helpers ---------------------------------------------------------------------------
def _project_heads(
    x: torch.Tensor, layer: nn.Linear, h: int, bias: bool = True, transpose: bool = False
) -> torch.Tensor:
    """``layer(x)`` for ``x`` (P, C), split into heads: (h, P, d), or (h, d, P) if ``transpose``."""
    y = F.linear(x, layer.weight, layer.bias if bias else None).view(x.shape[0], h, -1)
    return (y.permute(1, 2, 0) if transpose else y.transpose(0, 1)).contiguous()


def _deconv_matrix(deconv: nn.ConvTranspose2d) -> torch.Tensor:
    """A kernel-2, stride-2 transposed convolution as a (C_in, 4 C_out) matrix.

    Columns are ordered ``(di, dj, c_out)``: ``out[c', 2y+di, 2x+dj] = sum_c W[c, c', di, dj]
    in[c, y, x] + b[c']`` (no overlap between blocks, PyTorch's ``ConvTranspose2d`` definition).
    """
    k, s = tuple(deconv.kernel_size), tuple(deconv.stride)
    if k != (2, 2) or s != (2, 2) or tuple(deconv.padding) != (0, 0) or deconv.groups != 1:
        raise LfsamError(
            "this SAM 2 mask decoder's upscaling is not a 2x2 stride-2 transposed convolution; "
            "decode it with SAM2ImagePredictor instead"
        )
    w = deconv.weight  # (C_in, C_out, 2, 2)
    return w.permute(0, 2, 3, 1).reshape(w.shape[0], -1)


def _block_order(feat: torch.Tensor, levels: int, h: int, w: int) -> torch.Tensor:
    """Permute a (C', 2^levels h, 2^levels w) map into the decoder's pixel-block order.

    ``levels=1``: rows ``(y, x)``, columns ``(di, dj, c)`` for pixel ``(2y+di, 2x+dj)``.
    ``levels=2``: rows ``(y, x, di, dj)``, columns ``(di2, dj2, c)`` for pixel
    ``(4y+2di+di2, 4x+2dj+dj2)``.
    """
    c = feat.shape[0]
    if levels == 1:
        f = feat.reshape(c, h, 2, w, 2).permute(1, 3, 2, 4, 0)
        return f.reshape(h * w, 4 * c)
    f = feat.reshape(c, h, 2, 2, w, 2, 2).permute(1, 4, 2, 5, 3, 6, 0)
    return f.reshape(h * w * 4, 4 * c)


# --- per-image preparation -------------------------------------------------------------------
def prepare_image(
    model: nn.Module, image_embed: torch.Tensor, high_res_feats: list[torch.Tensor] | None
) -> ImageState:
    """Compute the prompt-independent part of the mask decoder for one image (module docstring).

    Parameters
    ----------
    model : SAM2Base
        Provides ``sam_prompt_encoder`` and ``sam_mask_decoder``.
    image_embed : (1, C, H, W) tensor
        The image embedding as ``SAM2ImagePredictor`` keeps it (``no_mem_embed`` added).
    high_res_feats : list of two tensors or None
        ``(1, C/8, 4H, 4W)`` and ``(1, C/4, 2H, 2W)``; needed when the decoder uses
        high-resolution features.

    Returns
    -------
    ImageState
    """
    dec = model.sam_mask_decoder
    penc = model.sam_prompt_encoder
    tr = dec.transformer
    if image_embed.dim() != 4 or image_embed.shape[0] != 1:
        raise LfsamError(
            f"decode_prompts takes one image embedding (1, C, H, W), got {tuple(image_embed.shape)}"
        )
    if len(tr.layers) < 1:
        raise LfsamError("the SAM 2 mask decoder has no transformer blocks; nothing to decode")
    _, c, hh, ww = image_embed.shape
    hw = hh * ww
    with torch.no_grad():
        src = image_embed[0].reshape(c, hw).t() + penc.no_mask_embed.weight.reshape(1, c)
        pe = penc.get_dense_pe()[0].reshape(c, hw).t().to(src.dtype)
        src_pe = src + pe
        first = tr.layers[0]
        h, _ = _heads(first.cross_attn_token_to_image)
        first_k = _project_heads(src_pe, first.cross_attn_token_to_image.k_proj, h)
        first_v = _project_heads(src, first.cross_attn_token_to_image.v_proj, h)
        h2, _ = _heads(first.cross_attn_image_to_token)
        first_q = _project_heads(src_pe, first.cross_attn_image_to_token.q_proj, h2, transpose=True)
        pe_k, pe_q = [], []
        for layer in tr.layers[1:]:
            t2i, i2t = layer.cross_attn_token_to_image, layer.cross_attn_image_to_token
            pe_k.append(_project_heads(pe, t2i.k_proj, _heads(t2i)[0], bias=False, transpose=True))
            pe_q.append(_project_heads(pe, i2t.q_proj, _heads(i2t)[0], transpose=True))
        final = tr.final_attn_token_to_image
        pe_k.append(_project_heads(pe, final.k_proj, _heads(final)[0], bias=False, transpose=True))

        dc1, _ln1, _act1, dc2, _act2 = dec.output_upscaling
        w1, w2 = _deconv_matrix(dc1), _deconv_matrix(dc2)
        c4, c8 = w1.shape[1] // 4, w2.shape[1] // 4
        if dec.use_high_res_features:
            if high_res_feats is None or len(high_res_feats) != 2:
                raise LfsamError(
                    "this SAM 2 model's decoder needs the two high-resolution feature maps; "
                    "encode the view with the same segmenter"
                )
            feat_s0, feat_s1 = high_res_feats
            up1 = feat_s1[0].reshape(c4, 2 * hh, 2 * ww) + dc1.bias.reshape(c4, 1, 1)
            up2 = feat_s0[0].reshape(c8, 4 * hh, 4 * ww) + dc2.bias.reshape(c8, 1, 1)
            up1 = _block_order(up1, 1, hh, ww)
            up2 = _block_order(up2, 2, hh, ww)
        else:
            up1 = dc1.bias.repeat(4).reshape(1, 4 * c4)
            up2 = dc2.bias.repeat(4).reshape(1, 4 * c8)
    return ImageState(
        grid=(hh, ww),
        src=src,
        first_k=first_k,
        first_v=first_v,
        first_q=first_q,
        pe_k=pe_k,
        pe_q=pe_q,
        up1=up1.contiguous(),
        up2=up2.contiguous(),
        w1=w1,
        w2=w2,
    )


# --- prompts ---------------------------------------------------------------------------------
def embed_prompts(
    model: nn.Module,
    point_coords: torch.Tensor | None,
    point_labels: torch.Tensor | None,
    boxes: torch.Tensor | None,
) -> torch.Tensor:
    """Sparse prompt embeddings, merged exactly as ``SAM2ImagePredictor._predict`` merges them.

    Box corners come first with labels 2 and 3, then the points; the prompt encoder appends its
    padding point (label -1) because boxes go in as points. Point label -1 marks padding. A model
    whose ``boxes_as_points`` is False (SAM v1 from ``transformers``, whose predictors pass boxes
    as boxes) gets the points first, without the padding point when there is a box, then the box
    corners (``PromptEncoder.forward(points, boxes)``; docs/design.md section 3.8). A point
    labelled :data:`~lfsam.segmenters.base.ABSENT_POINT` is embedded as padding; the decoder
    masks it out when given :func:`absent_tokens`.

    Parameters
    ----------
    point_coords : (N, P, 2) tensor or None
        In model-input pixels (``SAM2Transforms.transform_coords(..., normalize=True)``).
    point_labels : (N, P) int tensor or None
    boxes : (N, 4) tensor or None
        ``(x0, y0, x1, y1)`` in model-input pixels.

    Returns
    -------
    (N, T, C) tensor
    """
    if point_coords is None and boxes is None:
        raise LfsamError("a prompt needs points, a box, or both")
    if point_coords is not None and point_labels is None:
        raise LfsamError("points need labels (1 = positive, 0 = negative, -1 = padding)")
    if point_labels is not None:
        point_labels = torch.where(point_labels == ABSENT_POINT, -1, point_labels)
    points = None if point_coords is None else (point_coords, point_labels)
    if boxes is not None and points is not None and points[0].shape[0] != boxes.shape[0]:
        raise LfsamError(
            f"got {points[0].shape[0]} point prompts but {boxes.shape[0]} boxes; "
            "give one box per prompt"
        )
    if boxes is not None and not getattr(model, "boxes_as_points", True):
        sparse, _dense = model.sam_prompt_encoder(points=points, boxes=boxes, masks=None)
        return sparse
    if boxes is not None:
        box_coords = boxes.reshape(-1, 2, 2)
        box_labels = torch.tensor([[2, 3]], dtype=torch.int, device=boxes.device)
        box_labels = box_labels.repeat(boxes.shape[0], 1)
        if points is not None:
            points = (
                torch.cat([box_coords, points[0]], dim=1),
                torch.cat([box_labels, points[1]], dim=1),
            )
        else:
            points = (box_coords, box_labels)
    sparse, _dense = model.sam_prompt_encoder(points=points, boxes=None, masks=None)
    return sparse


def _mask_logits(
    dec: nn.Module, st: ImageState, keys: torch.Tensor, hyper: torch.Tensor, tile_rows: int
) -> torch.Tensor:
    """Upscaling (+ high-resolution features) and the hypernetwork product: (B, K, 4H, 4W).

    ``output_upscaling`` maps every embedding pixel to its own 4 x 4 block of output pixels
    (transposed convolutions with kernel = stride = 2, channel-wise LayerNorm and GELU), so it
    runs on bands of ``tile_rows`` embedding rows at a time; the band's tensors stay small enough
    for the CPU caches and the allocator. Within a band, rows are ordered ``(y, x, di, dj,
    di2, dj2)`` for output pixel ``(4y+2di+di2, 4x+2dj+dj2)`` (:func:`_block_order`).
    """
    _dc1, ln1, act1, _dc2, act2 = dec.output_upscaling
    b, _, _ = keys.shape
    k = hyper.shape[1]
    hh, ww = st.grid
    c4, c8 = st.w1.shape[1] // 4, st.w2.shape[1] // 4
    w1, w2 = st.w1.expand(b, -1, -1), st.w2.expand(b, -1, -1)
    hyper_t = hyper.transpose(1, 2)
    out = None
    for y0 in range(0, hh, tile_rows):
        y1 = min(hh, y0 + tile_rows)
        p0, p1 = y0 * ww, y1 * ww
        up1, up2 = _band(st.up1, st.rows, p0, p1), _band(st.up2, st.rows, 4 * p0, 4 * p1)
        y = torch.baddbmm(up1, keys[:, p0:p1], w1).view(b, (p1 - p0) * 4, c4)
        y = act1(F.layer_norm(y, (c4,), ln1.weight, ln1.bias, ln1.eps))
        y = act2(torch.baddbmm(up2, y, w2).view(b, (p1 - p0) * 16, c8))
        logits = torch.bmm(y, hyper_t)  # (B, 16 pixels, K)
        if out is None:
            out = logits.new_empty((b, k, 4 * hh, 4 * ww))
        band = logits.view(b, y1 - y0, ww, 2, 2, 2, 2, k).permute(0, 7, 1, 3, 5, 2, 4, 6)
        out[:, :, 4 * y0 : 4 * y1] = band.reshape(b, k, 4 * (y1 - y0), 4 * ww)
    assert out is not None
    return out


def _band(up: torch.Tensor, rows: torch.Tensor | None, start: int, stop: int) -> torch.Tensor:
    """Rows ``start:stop`` of an upscaling term (one image, or each prompt's image of a stack
    indexed by ``rows``); a bias-only term (one row) applies to every pixel as it is."""
    if up.dim() == 2 and up.shape[0] == 1:
        return up
    return up[start:stop] if rows is None else up[rows, start:stop]


def stability_scores(decoder: nn.Module, mask_logits: torch.Tensor) -> torch.Tensor:
    """The stability score of each mask: the IoU of the mask thresholded at ``+delta`` with the
    mask thresholded at ``-delta`` (Kirillov et al. 2023, section 3), where ``delta`` is the
    decoder's ``dynamic_multimask_stability_delta``; 1 where nothing passes ``-delta``.

    What ``MaskDecoder`` scores its single-mask output with before falling back to a multimask
    token (tests/test_sam2_decoder.py compares the decoder's choice with Meta's).

    Parameters
    ----------
    decoder : MaskDecoder
        Only its ``dynamic_multimask_stability_delta`` is read.
    mask_logits : (..., H, W) tensor

    Returns
    -------
    (...) float32 tensor
    """
    delta = decoder.dynamic_multimask_stability_delta
    flat = mask_logits.flatten(-2)
    inner = torch.sum(flat > delta, dim=-1).float()
    outer = torch.sum(flat > -delta, dim=-1).float()
    return torch.where(outer > 0, inner / outer, 1.0)


def _decode_chunk(
    model: nn.Module,
    st: ImageState,
    sparse: torch.Tensor,
    multimask_output: bool,
    tile_rows: int = DEFAULT_TILE_ROWS,
    absent: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """``MaskDecoder.forward`` for a chunk of prompts: (B, K, 4H, 4W) logits and (B, K) IoU;
    ``absent`` (B, T) bool: prompt tokens masked out (:func:`absent_tokens`)."""
    dec = model.sam_mask_decoder
    b = sparse.shape[0]
    s = 1 if dec.pred_obj_scores else 0
    parts = [dec.iou_token.weight, dec.mask_tokens.weight]
    if s:
        parts.insert(0, dec.obj_score_token.weight)
    output_tokens = torch.cat(parts, dim=0).unsqueeze(0).expand(b, -1, -1)
    tokens = torch.cat((output_tokens, sparse.to(output_tokens.dtype)), dim=1)
    if absent is not None:
        if absent.shape != sparse.shape[:2]:
            raise LfsamError(
                f"absent-token mask of shape {tuple(absent.shape)} for prompts of "
                f"{tuple(sparse.shape[:2])} tokens; make it with absent_tokens"
            )
        absent = F.pad(absent, (output_tokens.shape[1], 0), value=False)

    dynamic = not multimask_output and dec.dynamic_multimask_via_stability and not dec.training
    if multimask_output:
        wanted = list(range(1, dec.num_mask_tokens))
    elif dynamic:
        wanted = list(range(dec.num_mask_tokens))
    else:
        wanted = [0]
    # token order of MaskDecoder.predict_masks: [obj_score,] iou, mask tokens, prompt tokens
    hs, keys = transformer(
        dec.transformer, st, tokens, [s] + [s + 1 + i for i in wanted], absent
    )
    iou_pred = dec.iou_prediction_head(hs[:, 0, :])
    hyper = torch.stack(
        [dec.output_hypernetworks_mlps[i](hs[:, 1 + j, :]) for j, i in enumerate(wanted)], dim=1
    )
    if dynamic:
        # MaskDecoder._dynamic_multimask_via_stability: token 0 unless its stability is low, then
        # the multimask token with the highest predicted IoU. Only these two masks are computed.
        best = torch.argmax(iou_pred[:, 1:], dim=-1) + 1
        rows = torch.arange(b, device=hyper.device)
        hyper = torch.stack([hyper[:, 0], hyper[rows, best]], dim=1)
    masks = _mask_logits(dec, st, keys, hyper, tile_rows)

    if multimask_output:
        return masks, iou_pred[:, 1:]
    if dynamic:
        single, best_mask = masks[:, 0:1], masks[:, 1:2]
        stable = stability_scores(dec, single) >= dec.dynamic_multimask_stability_thresh
        masks = torch.where(stable[..., None, None], single, best_mask)
        iou = torch.where(stable, iou_pred[:, 0:1], iou_pred[rows, best].unsqueeze(1))
        return masks, iou
    return masks, iou_pred[:, 0:1]


# --- public entry point ----------------------------------------------------------------------
def default_chunk_size(device: torch.device | str) -> int:
    """Prompts to decode together on ``device``: :data:`DEFAULT_CHUNK_SIZE` on a CPU, else
    :data:`ACCELERATOR_CHUNK_SIZE`."""
    return DEFAULT_CHUNK_SIZE if torch.device(device).type == "cpu" else ACCELERATOR_CHUNK_SIZE


def decode_prompts(
    model: nn.Module,
    image_embed: torch.Tensor,
    high_res_feats: list[torch.Tensor] | None,
    point_coords: torch.Tensor | None,
    point_labels: torch.Tensor | None,
    boxes: torch.Tensor | None,
    multimask_output: bool,
    chunk_size: int = DEFAULT_CHUNK_SIZE,
    *,
    mask_input: torch.Tensor | None = None,
    clamp: bool = True,
    state: ImageState | None = None,
    tile_rows: int = DEFAULT_TILE_ROWS,
    absent_points: bool = False,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Decode N prompts on one image: ``SAM2ImagePredictor._predict`` before post-processing.

    Same result as Meta's prompt encoder + ``MaskDecoder.forward`` (``repeat_image`` over the
    prompts) up to rounding, computed with the image side shared across prompts (module
    docstring). Run it under :func:`~lfsam.segmenters.sam2.build.inference_context` (or at least
    ``torch.no_grad``) like the rest of the backend.

    Parameters
    ----------
    model : SAM2Base
        In eval mode.
    image_embed : (1, C, H, W) tensor
        ``SAM2ImagePredictor._features["image_embed"]`` of the image.
    high_res_feats : list of two tensors or None
        ``_features["high_res_feats"]`` ((1, C/8, 4H, 4W) and (1, C/4, 2H, 2W)).
    point_coords : (N, P, 2) tensor or None
        Points in model-input pixels, as ``SAM2ImagePredictor._prep_prompts`` makes them.
    point_labels : (N, P) int tensor or None
        1 positive, 0 negative, -1 padding (not a point),
        :data:`~lfsam.segmenters.base.ABSENT_POINT` absent (with ``absent_points``).
    boxes : (N, 4) tensor or None
        Boxes in model-input pixels; merged before the points as box corners (labels 2, 3).
    multimask_output : bool
        Three masks (tokens 1..3) per prompt, else one (token 0, or with the model's
        ``dynamic_multimask_via_stability`` the fallback to the best multimask token).
    chunk_size : int
        Prompts decoded together (memory is about 14 MB per prompt in float32); a speed setting,
        the result does not depend on it (see :func:`default_chunk_size`).
    mask_input : None
        Mask prompts are not supported; passing one raises.
    clamp : bool
        Clamp the logits to [-32, 32] as ``_predict`` does for the low-resolution logits it
        returns (its full-resolution masks are made from the unclamped logits: pass False to
        post-process them the same way).
    state : ImageState, optional
        From :func:`prepare_image` for this image, to reuse it across calls.
    tile_rows : int
        Embedding rows upscaled together (a speed setting; the result does not depend on it).
    absent_points : bool
        Mask out the points labelled :data:`~lfsam.segmenters.base.ABSENT_POINT`
        (:func:`absent_tokens`): each prompt answers as without them, so prompts of different
        lengths share a call. False: such points are SAM 2's padding.

    Returns
    -------
    low_res_masks : (N, K, 4H, 4W) tensor
        Mask logits (K = 3 with ``multimask_output`` else 1).
    iou_predictions : (N, K) tensor
    """
    if mask_input is not None:
        raise LfsamError(
            "decode_prompts does not take mask prompts; use SAM2ImagePredictor for mask input"
        )
    if chunk_size < 1 or tile_rows < 1:
        raise LfsamError(
            f"chunk_size and tile_rows must be at least 1, got {chunk_size} and {tile_rows}"
        )
    with torch.no_grad():
        sparse = embed_prompts(model, point_coords, point_labels, boxes)
        absent = absent_tokens(model, point_labels, boxes) if absent_points else None
        if state is None:
            state = prepare_image(model, image_embed, high_res_feats)
        masks, ious = [], []
        for start in range(0, sparse.shape[0], chunk_size):
            chunk = slice(start, start + chunk_size)
            m, iou = _decode_chunk(
                model, state, sparse[chunk], multimask_output, tile_rows,
                None if absent is None else absent[chunk],
            )
            masks.append(m)
            ious.append(iou)
        if not masks:
            k = 3 if multimask_output else 1
            hh, ww = state.grid
            empty = image_embed.new_zeros((0, k, 4 * hh, 4 * ww))
            return empty, image_embed.new_zeros((0, k))
        low_res = torch.cat(masks) if len(masks) > 1 else masks[0]
        if clamp:
            low_res = torch.clamp(low_res, -LOGIT_CLAMP, LOGIT_CLAMP)
        return low_res, torch.cat(ious) if len(ious) > 1 else ious[0]
