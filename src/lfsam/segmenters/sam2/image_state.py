"""The prompt-independent side of SAM 2's mask decoder for one image (or a stack of views):
what :func:`lfsam.segmenters.sam2.decoder.prepare_image` computes once and every prompt reads."""

from __future__ import annotations

from dataclasses import dataclass

import torch

__all__ = ["ImageState"]


@dataclass
class ImageState:
    """Prompt-independent tensors of one image, computed once by :func:`prepare_image`.

    ``HW`` is the number of embedding pixels (64 x 64 for a 1024 input), ``C`` the decoder width,
    ``h`` the number of attention heads and ``d`` the width per head.

    Parameters
    ----------
    grid : (H, W)
        Size of the image embedding.
    src : (HW, C)
        ``image_embed + no_mask_embed``, pixels as rows (the transformer's initial keys).
    first_k, first_v : (h, HW, d)
        First block, token-to-image attention: ``k_proj(src + pe)`` and ``v_proj(src)``.
    first_q : (h, d, HW)
        First block, image-to-token attention: ``q_proj(src + pe)`` (transposed per head).
    pe_k : list of (h, d, HW)
        For each later block and then the final attention: ``W_k pe`` (no bias) of its
        token-to-image attention.
    pe_q : list of (h, d, HW)
        For each later block: ``W_q pe + b_q`` of its image-to-token attention.
    up1 : (HW, 4 C/4)
        Additive term of the first upscaling step in block order ``(pixel, di, dj, channel)``:
        ``conv_s1`` features (when used) plus the transposed convolution's bias.
    up2 : (4 HW, 4 C/8)
        Same for the second step, rows ``(pixel, di, dj)``, columns ``(di2, dj2, channel)``.
    w1, w2 : (C, 4 C/4), (C/4, 4 C/8)
        The two transposed convolutions as matrices with the same column order.
    rows : (B,) int64 tensor, optional
        Set on the state of a chunk of prompts from several images
        (:func:`lfsam.segmenters.sam2.multiview.decode_views`): the image of each prompt. Then
        ``src``, ``first_k``, ``first_v`` and ``first_q`` have a leading prompt axis (that
        prompt's image), and ``up1``, ``up2`` a leading image axis that ``rows`` indexes.
    """

    grid: tuple[int, int]
    src: torch.Tensor
    first_k: torch.Tensor
    first_v: torch.Tensor
    first_q: torch.Tensor
    pe_k: list[torch.Tensor]
    pe_q: list[torch.Tensor]
    up1: torch.Tensor
    up2: torch.Tensor
    w1: torch.Tensor
    w2: torch.Tensor
    rows: torch.Tensor | None = None
