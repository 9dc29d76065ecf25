"""Prompts of many views through one call of SAM 2's mask decoder (docs/design.md section 3.5,
"batched decoder"; lfsam issue 44).

:func:`lfsam.segmenters.sam2.decoder.decode_prompts` shares one image's prompt-independent side
(:class:`~lfsam.segmenters.sam2.decoder.ImageState`) across that image's prompts. Refinement
decodes about as many prompts per view as there are objects, in every view: on a GPU, one
decoder call per view is launch-bound (docs/performance.md, "GPU (H100)"). Here the states of
several views are stacked and every chunk of prompts, whichever views they come from, goes
through the decoder at once: each prompt reads its own view's tensors (``ImageState.rows``), the
positional-encoding terms and the weights are shared by all views (they depend on the model
only). The arithmetic per prompt is the same as :func:`decode_prompts`'; only the batching of
the first block's attention and of the upscaling's additive terms differs, so the logits agree
up to floating-point rounding (tests/test_batched_decoder.py).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import torch
from torch import nn

from lfsam.errors import LfsamError
from lfsam.segmenters.base import Prompts
from lfsam.segmenters.sam2.decoder import (
    DEFAULT_TILE_ROWS,
    LOGIT_CLAMP,
    ImageState,
    _decode_chunk,
    absent_tokens,
    embed_prompts,
)

__all__ = [
    "compile_pass",
    "decode_prompt_batches",
    "decode_views",
    "prompt_shape",
    "stack_states",
]


def prompt_shape(prompts: Prompts) -> tuple[int, bool]:
    """Points per prompt and whether there is a box: prompts of one shape have the same
    number of tokens, so they can share a decoder pass."""
    points = 0 if prompts.points is None else int(prompts.points.shape[1])
    return points, prompts.boxes is not None


def compile_pass(mode: str) -> Callable[..., tuple[torch.Tensor, torch.Tensor]]:
    """The decoder pass compiled by ``torch.compile`` with static shapes: ``mode`` one of its
    modes (``"reduce-overhead"``: CUDA graphs), or ``"eager"`` (traced by TorchDynamo and run
    eagerly: checks the pass compiles, in seconds, on any device)."""
    options: dict[str, str] = {"backend": "eager"} if mode == "eager" else {"mode": mode}
    return torch.compile(_decode_chunk, dynamic=False, **options)


def _per_image(term: torch.Tensor) -> bool:
    """Whether an upscaling term differs between images (a bias-only term is one row)."""
    return not (term.dim() == 2 and term.shape[0] == 1)


def stack_states(states: Sequence[ImageState]) -> ImageState:
    """The image sides of several views of one size, stacked along a leading view axis.

    Parameters
    ----------
    states : sequence of ImageState
        From :func:`lfsam.segmenters.sam2.decoder.prepare_image`, same model, same grid.

    Returns
    -------
    ImageState
        ``src`` (V, HW, C), ``first_k``/``first_v`` (V, h, HW, d), ``first_q`` (V, h, d, HW),
        ``up1``/``up2`` (V, ...) where they depend on the image; ``pe_k``, ``pe_q``, ``w1``,
        ``w2`` of the first state (the model's, the same for all). ``rows`` is each view's
        index, so the stack can be given to the decoder as it is (one prompt per view).
    """
    if not states:
        raise LfsamError("no image states to stack; decode at least one view")
    first = states[0]
    if any(st.grid != first.grid for st in states):
        raise LfsamError(
            "views of different embedding sizes cannot share a decoder call; decode them apart"
        )

    def stack(name: str) -> torch.Tensor:
        return torch.stack([getattr(st, name) for st in states])

    return replace(
        first,
        src=stack("src"),
        first_k=stack("first_k"),
        first_v=stack("first_v"),
        first_q=stack("first_q"),
        up1=stack("up1") if _per_image(first.up1) else first.up1,
        up2=stack("up2") if _per_image(first.up2) else first.up2,
        rows=torch.arange(len(states), device=first.src.device),
    )


def _chunk_state(stacked: ImageState, rows: torch.Tensor) -> ImageState:
    """The stack as one chunk of prompts sees it: the first block's tensors of each prompt's
    view (gathered: the attention runs per prompt), the upscaling terms indexed per band."""
    return replace(
        stacked,
        src=stacked.src[rows],
        first_k=stacked.first_k[rows],
        first_v=stacked.first_v[rows],
        first_q=stacked.first_q[rows],
        rows=rows,
    )


def decode_views(
    model: nn.Module,
    states: Sequence[ImageState] | ImageState,
    sparse: torch.Tensor,
    views: torch.Tensor,
    multimask_output: bool,
    chunk_size: int,
    *,
    clamp: bool = True,
    tile_rows: int = DEFAULT_TILE_ROWS,
    compiled: Callable[..., tuple[torch.Tensor, torch.Tensor]] | None = None,
    absent: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Decode N prompts of several views, ``chunk_size`` prompts per decoder pass, whatever
    their views: what :func:`~lfsam.segmenters.sam2.decoder.decode_prompts` computes for each
    view's prompts (module docstring).

    Parameters
    ----------
    model : SAM2Base
        In eval mode; run under ``torch.no_grad`` (the backend's inference context).
    states : sequence of ImageState, or their :func:`stack_states`
        One per view.
    sparse : (N, T, C) tensor
        Prompt embeddings (:func:`~lfsam.segmenters.sam2.decoder.embed_prompts`); every prompt
        the same number of tokens T.
    views : (N,) int64 tensor
        The view (index into ``states``) of each prompt, on the model's device.
    multimask_output : bool
        Three masks per prompt, else one (as ``decode_prompts``).
    chunk_size : int
        Prompts per decoder pass (a speed and memory setting; about 4 MB more per prompt
        than ``decode_prompts`` for the gathered first-block tensors in float32).
    clamp : bool
        Clamp the logits to [-32, 32].
    tile_rows : int
        Embedding rows upscaled together.
    compiled : callable, optional
        A compiled form of the decoder pass (``torch.compile`` of
        :func:`~lfsam.segmenters.sam2.decoder._decode_chunk` with static shapes, e.g. CUDA
        graphs): every pass is then padded to ``chunk_size`` prompts (the last prompt
        repeated; prompts do not see each other, the padding is dropped), so one shape serves
        all passes, and each pass's output is copied out of the graph's memory.
    absent : (N, T) bool tensor, optional
        Tokens that are absent points, masked out
        (:func:`~lfsam.segmenters.sam2.decoder.absent_tokens`).

    Returns
    -------
    low_res_masks : (N, K, 4H, 4W) tensor
    iou_predictions : (N, K) tensor
    """
    if chunk_size < 1:
        raise LfsamError(f"chunk_size must be at least 1, got {chunk_size}")
    if sparse.shape[0] != views.shape[0]:
        raise LfsamError(f"{sparse.shape[0]} prompts but {views.shape[0]} view indices")
    stacked = states if isinstance(states, ImageState) else stack_states(states)
    masks, ious = [], []
    with torch.no_grad():
        for start in range(0, sparse.shape[0], chunk_size):
            chunk = slice(start, start + chunk_size)
            rows, tokens = views[chunk], sparse[chunk]
            skip = None if absent is None else absent[chunk]
            if compiled is None:
                m, iou = _decode_chunk(
                    model, _chunk_state(stacked, rows), tokens, multimask_output, tile_rows,
                    skip,
                )
            else:
                count, pad = len(rows), chunk_size - len(rows)
                rows = torch.cat([rows, rows[-1:].expand(pad)])
                tokens = torch.cat([tokens, tokens[-1:].expand(pad, -1, -1)])
                if skip is not None:
                    skip = torch.cat([skip, skip[-1:].expand(pad, -1)])
                m, iou = compiled(
                    model, _chunk_state(stacked, rows), tokens, multimask_output, tile_rows,
                    skip,
                )
                m, iou = m[:count].clone(), iou[:count].clone()
            masks.append(m)
            ious.append(iou)
    if not masks:
        k = 3 if multimask_output else 1
        hh, ww = stacked.grid
        return stacked.src.new_zeros((0, k, 4 * hh, 4 * ww)), stacked.src.new_zeros((0, k))
    low_res = torch.cat(masks)
    if clamp:
        low_res = torch.clamp(low_res, -LOGIT_CLAMP, LOGIT_CLAMP)
    return low_res, torch.cat(ious)


PromptTensors = tuple[torch.Tensor | None, torch.Tensor | None, torch.Tensor | None]


def decode_prompt_batches(
    model: nn.Module,
    stacked: ImageState,
    prompts: Sequence[PromptTensors],
    multimask_output: bool,
    rows_per_call: int,
    chunk_size: int,
    transforms: Any,
    image_size: tuple[int, int],
    mask_threshold: float,
    *,
    compiled: Callable[..., tuple[torch.Tensor, torch.Tensor]] | None = None,
    absent_points: bool = False,
) -> tuple[list[tuple[torch.Tensor, torch.Tensor, torch.Tensor]], int]:
    """Masks of each view's prompts, every ``rows_per_call`` prompts of all views decoded
    together (:meth:`lfsam.segmenters.sam2.backend.Sam2Segmenter.predict_many`).

    Parameters
    ----------
    model : SAM2Base
    stacked : ImageState
        :func:`stack_states` of the views.
    prompts : sequence of (coords, labels, boxes)
        Each view's prompts in model-input pixels (``_prep_prompts``), all of one shape.
    multimask_output : bool
    rows_per_call, chunk_size : int
        Prompts per call (post-processed together) and per decoder pass.
    transforms : SAM2Transforms
        Post-processing of the logits (upsampling to ``image_size``).
    image_size : (U, V)
    mask_threshold : float
    absent_points : bool
        Mask out the points labelled :data:`~lfsam.segmenters.base.ABSENT_POINT`.

    Returns
    -------
    per_view : list of (masks, iou_predictions, low_res_logits)
        As :class:`~lfsam.segmenters.base.MaskPrediction` holds them (float32 IoUs and logits
        clamped to [-32, 32]).
    calls : int
        Decoder calls made.
    """
    device = stacked.src.device
    counts = [len(c if c is not None else b) for c, _, b in prompts]
    coords, labels, boxes = (
        None if prompts[0][j] is None else torch.cat([p[j] for p in prompts]) for j in range(3)
    )
    views = torch.repeat_interleave(
        torch.arange(len(counts), device=device), torch.as_tensor(counts, device=device),
        output_size=sum(counts),
    )
    masks, ious, low_res = [], [], []
    for start in range(0, len(views), rows_per_call):
        rows = slice(start, start + rows_per_call)
        chunk = [None if x is None else x[rows] for x in (coords, labels, boxes)]
        sparse = embed_prompts(model, *chunk)
        absent = absent_tokens(model, chunk[1], chunk[2]) if absent_points else None
        lr, iou = decode_views(model, stacked, sparse, views[rows], multimask_output,
                               chunk_size, clamp=False, compiled=compiled, absent=absent)
        masks.append(transforms.postprocess_masks(lr, image_size) > mask_threshold)
        low_res.append(torch.clamp(lr, -LOGIT_CLAMP, LOGIT_CLAMP).float())
        ious.append(iou.float())
    split = [torch.cat(x).split(counts) for x in (masks, ious, low_res)]
    return list(zip(*split, strict=True)), len(masks)
