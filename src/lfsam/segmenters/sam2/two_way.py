"""SAM 2's two-way transformer for many prompts, the image side shared until it depends on the
prompt, and absent prompt points masked out.

The attention layers of ``TwoWayTransformer`` (Kirillov et al. 2023, appendix A) rewritten by
the exact identities of :mod:`lfsam.segmenters.sam2.decoder` (its module docstring, points 1
and 2): projections of per-prompt image tensors moved to the token side, the first block's
image side computed once per image (:class:`~lfsam.segmenters.sam2.decoder.ImageState`).

Absent points (docs/design.md section 3.5, "one decoder call for prompts of different
lengths"): a token marked absent is a key no token and no pixel attends to (``attn_mask`` of the
tokens' self-attention, ``-inf`` image-to-token scores); its own query still runs and is never
read. Attention ignores the order of its keys, so a prompt padded with absent points answers as
the prompt alone, up to rounding (tests/test_absent_points.py).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from lfsam.segmenters.base import ABSENT_POINT
from lfsam.segmenters.sam2.image_state import ImageState

__all__ = ["absent_tokens", "transformer"]


def _heads(attn: nn.Module) -> tuple[int, int]:
    """Number of heads and width per head of a SAM ``Attention`` layer."""
    h = int(attn.num_heads)
    return h, int(attn.internal_dim) // h


def absent_tokens(
    model: nn.Module, point_labels: torch.Tensor | None, boxes: torch.Tensor | None
) -> torch.Tensor | None:
    """Which of :func:`embed_prompts`' tokens are absent points (label
    :data:`~lfsam.segmenters.base.ABSENT_POINT`): ``(N, T)`` bool, or None without points.

    The tokens are laid out as :func:`embed_prompts` merges them: box corners, the points and
    the prompt encoder's padding point; for a model that takes boxes as boxes, the points then
    either the padding point or the box corners. The decoder masks these tokens as keys in
    every attention (docs/design.md section 3.5), so the prompt answers as without them.
    """
    if point_labels is None:
        return None
    corners_first = boxes is not None and getattr(model, "boxes_as_points", True)
    before = 2 if corners_first else 0
    after = 1 if boxes is None or corners_first else 2
    return F.pad(point_labels == ABSENT_POINT, (before, after), value=False)


def _self_attention(
    attn: nn.Module, q: torch.Tensor, k: torch.Tensor, v: torch.Tensor, keep: torch.Tensor
) -> torch.Tensor:
    """SAM's ``Attention.forward`` among the tokens, the keys ``keep`` (B, 1, 1, T) only."""
    h, d = _heads(attn)
    b, t, _ = q.shape

    def heads(x: torch.Tensor, proj: nn.Linear) -> torch.Tensor:
        return proj(x).view(b, t, h, d).transpose(1, 2)

    out = F.scaled_dot_product_attention(
        heads(q, attn.q_proj), heads(k, attn.k_proj), heads(v, attn.v_proj), attn_mask=keep
    )
    return attn.out_proj(out.transpose(1, 2).reshape(b, t, h * d))


# --- the attention layers, image side shared or per prompt ----------------------------------
def _value_rows(attn: nn.Module, v_tokens: torch.Tensor) -> torch.Tensor:
    """Rows ``W_o,h (W_v,h v_j + b_v,h) + b_o / heads`` of image-to-token attention, (B, hT, C).

    With attention weights ``a`` (pixels, heads x tokens) whose rows sum to 1 within each head,
    ``a @ rows`` is the attention layer's output including ``out_proj`` and its bias.
    """
    h, d = _heads(attn)
    b, t, _ = v_tokens.shape
    vh = attn.v_proj(v_tokens).view(b, t, h, d)
    wo = attn.out_proj.weight.view(-1, h, d)  # (C, h, d)
    rows = torch.einsum("bthd,chd->bhtc", vh, wo) + attn.out_proj.bias / h
    return rows.reshape(b, h * t, -1)


def _image_to_token_first(
    attn: nn.Module, st: ImageState, k_tokens: torch.Tensor, v_tokens: torch.Tensor,
    absent: torch.Tensor | None = None,
) -> torch.Tensor:
    """First block: shared image queries attend to each prompt's tokens; returns src + attn_out.

    Output (B, HW, C) is the residual sum before ``norm4``. Scores are laid out
    (heads, prompts, tokens, pixels) so that the softmax over the few tokens runs along a
    non-contiguous axis with the pixels contiguous (much faster than a softmax over a last axis of
    about 10 entries). ``absent`` (B, T) bool: tokens no pixel attends to.
    """
    h, d = _heads(attn)
    b, t, _ = k_tokens.shape
    hw = st.src.shape[-2]
    kh = attn.k_proj(k_tokens) * d**-0.5  # softmax scale of scaled_dot_product_attention
    if st.rows is not None:  # each prompt its own image's queries (B, h, d, HW)
        scores = torch.matmul(kh.view(b, t, h, d).transpose(1, 2), st.first_q)
        if absent is not None:
            scores = scores.masked_fill(absent[:, None, :, None], float("-inf"))
        weights = torch.softmax(scores, dim=2).reshape(b, h * t, hw)
    else:
        kh = kh.view(b * t, h, d).transpose(0, 1)  # (h, B T, d)
        scores = torch.bmm(kh, st.first_q).view(h, b, t, hw)
        if absent is not None:
            scores = scores.masked_fill(absent[None, :, :, None], float("-inf"))
        weights = torch.softmax(scores, dim=2).transpose(0, 1).reshape(b, h * t, hw)
    return torch.baddbmm(st.src, weights.transpose(1, 2), _value_rows(attn, v_tokens))


def _token_scores(
    tokens: torch.Tensor, weight: torch.Tensor, keys: torch.Tensor, pe: torch.Tensor
) -> torch.Tensor:
    """Attention scores between per-head token rows ``tokens`` (B, T, h, d) and per-prompt image
    rows ``keys`` (B, HW, C) projected by the other side's ``weight`` (h d, C), plus the
    positional term ``tokens . pe`` (``pe`` (h, d, HW)): (B, h, T, HW) (module docstring of
    :mod:`lfsam.segmenters.sam2.decoder`, point 2; projecting the tokens, not the image)."""
    b, t, h, d = tokens.shape
    c, hw = keys.shape[2], keys.shape[1]
    rows = torch.einsum("bthd,hdc->bhtc", tokens, weight.view(h, d, c)).reshape(b, h * t, c)
    scores = torch.bmm(rows, keys.transpose(1, 2)).view(b, h, t, hw)
    pe_term = torch.bmm(tokens.permute(2, 0, 1, 3).reshape(h, b * t, d), pe)  # (h, B T, HW)
    scores += pe_term.view(h, b, t, hw).transpose(0, 1)
    return scores


def _image_to_token(
    attn: nn.Module,
    keys: torch.Tensor,
    pe_q: torch.Tensor,
    k_tokens: torch.Tensor,
    v_tokens: torch.Tensor,
    absent: torch.Tensor | None = None,
) -> torch.Tensor:
    """Image-to-token attention on per-prompt image keys (B, HW, C); returns keys + attn_out.

    Scores ``x . (W_q,h^T k_h) + (W_q,h pe + b_q,h) . k_h`` (decoder module docstring,
    point 2), laid out (prompts, heads, tokens, pixels) as in :func:`_image_to_token_first`;
    ``absent`` as there.
    """
    h, d = _heads(attn)
    b, t, _ = k_tokens.shape
    hw = keys.shape[1]
    kh = (attn.k_proj(k_tokens) * d**-0.5).view(b, t, h, d)
    scores = _token_scores(kh, attn.q_proj.weight, keys, pe_q)
    if absent is not None:
        scores.masked_fill_(absent[:, None, :, None], float("-inf"))
    weights = torch.softmax(scores, dim=2).view(b, h * t, hw)
    return torch.baddbmm(keys, weights.transpose(1, 2), _value_rows(attn, v_tokens))


def _token_to_image_first(attn: nn.Module, st: ImageState, q_tokens: torch.Tensor) -> torch.Tensor:
    """First block: every prompt's tokens attend to the shared keys/values (batched queries)."""
    h, d = _heads(attn)
    b, t, _ = q_tokens.shape
    q = attn.q_proj(q_tokens)
    if st.rows is not None:  # each prompt its own image's keys and values (B, h, HW, d)
        q = q.view(b, t, h, d).transpose(1, 2)
        out = F.scaled_dot_product_attention(q, st.first_k, st.first_v).transpose(1, 2)
        return attn.out_proj(out.reshape(b, t, h * d))
    q = q.view(b * t, h, d).transpose(0, 1)  # (h, B T, d)
    out = F.scaled_dot_product_attention(q, st.first_k, st.first_v)  # (h, B T, d)
    out = out.transpose(0, 1).reshape(b, t, h * d)
    return attn.out_proj(out)


def _token_to_image(
    attn: nn.Module, q_tokens: torch.Tensor, keys: torch.Tensor, pe_k: torch.Tensor
) -> torch.Tensor:
    """Token-to-image attention on per-prompt image keys (B, HW, C) (decoder module docstring,
    point 2).

    Scores ``(q_h W_k,h) . x + q_h . (W_k,h pe)`` (the key bias only shifts each row of scores);
    output ``W_o concat_h(W_v,h (a_h @ x) + b_v,h) + b_o``.
    """
    h, d = _heads(attn)
    b, t, c = q_tokens.shape
    hw = keys.shape[1]
    qh = (attn.q_proj(q_tokens) * d**-0.5).view(b, t, h, d)
    scores = _token_scores(qh, attn.k_proj.weight, keys, pe_k)
    weights = torch.softmax(scores.view(b, h * t, hw), dim=-1)
    pooled = torch.bmm(weights, keys).view(b, h, t, c)
    wv = attn.v_proj.weight.view(h, d, c)
    out = torch.einsum("bhtc,hdc->bthd", pooled, wv) + attn.v_proj.bias.view(h, d)
    return attn.out_proj(out.reshape(b, t, h * d))


def transformer(
    tr: nn.Module, st: ImageState, tokens: torch.Tensor, rows: list[int],
    absent: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """``TwoWayTransformer.forward`` with the image side shared until it depends on the prompt.

    Returns the processed tokens (B, len(rows), C) and image keys (B, HW, C), as the original.
    The final token-to-image attention and norm act on each token separately, so they are
    computed only for the token ``rows`` the decoder reads (IoU and wanted mask tokens).
    ``absent`` (B, T) bool marks tokens that are not there: no token and no pixel attends to
    them (their own queries still run, and are never read), so each prompt's output is that
    of its prompt without them.
    """
    queries, query_pe = tokens, tokens
    keys: torch.Tensor | None = None  # None: still the shared st.src
    keep = None if absent is None else ~absent[:, None, None, :]

    def self_attn(attn: nn.Module, q: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
        return attn(q=q, k=q, v=v) if keep is None else _self_attention(attn, q, q, v, keep)

    for i, layer in enumerate(tr.layers):
        if layer.skip_first_layer_pe:
            queries = self_attn(layer.self_attn, queries, queries)
        else:
            q = queries + query_pe
            queries = queries + self_attn(layer.self_attn, q, queries)
        queries = layer.norm1(queries)

        q = queries + query_pe
        if keys is None:
            attn_out = _token_to_image_first(layer.cross_attn_token_to_image, st, q)
        else:
            attn_out = _token_to_image(layer.cross_attn_token_to_image, q, keys, st.pe_k[i - 1])
        queries = layer.norm2(queries + attn_out)
        queries = layer.norm3(queries + layer.mlp(queries))

        q = queries + query_pe
        if keys is None:
            keys = _image_to_token_first(
                layer.cross_attn_image_to_token, st, q, queries, absent
            )
        else:
            keys = _image_to_token(
                layer.cross_attn_image_to_token, keys, st.pe_q[i - 1], q, queries, absent
            )
        keys = layer.norm4(keys)

    queries, query_pe = queries[:, rows], query_pe[:, rows]
    q = queries + query_pe
    attn_out = _token_to_image(tr.final_attn_token_to_image, q, keys, st.pe_k[-1])
    queries = tr.norm_final_attn(queries + attn_out)
    return queries, keys
