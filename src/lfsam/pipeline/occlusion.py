"""Step 3 of the pipeline: removing occluded pixels from the coarse masks.

Semantic occluding (paper section 3.3): the source feature of a mask is the mean SAM 2 image
embedding over the center-view mask (the embedding brought to image resolution); in view
``(s, t)`` every coarse-mask pixel gets the cosine similarity of its own feature to the source
feature. Pixels below ``t_sim`` (0.7 in the paper, section 4) get weight 0 and are dropped; the
others keep their similarity as a weight, used later to place the refinement prompt.

Geometric occluding (DESIGN.md section 3, beyond the paper) is a z-buffer test on the center
disparity: see :meth:`lfsam.pipeline.propagation.ForwardWarp.visible`.

Masks are handled as (mask index, pixel index) pairs so memory follows the masks' total area,
not N x U x V features.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import torch
import torch.nn.functional as F

from lfsam.segmenters.base import Segmenter, ViewEmbedding

__all__ = ["OcclusionWeights", "semantic_occlusion", "source_features", "uniform_weights"]

_PIXEL_CHUNK = 65536


@dataclass
class OcclusionWeights:
    """Per-pixel weights of the coarse masks of one view, as sparse pairs.

    Attributes
    ----------
    mask_index : (P,) int64 tensor
        Which mask each pair belongs to.
    pixel_index : (P,) int64 tensor
        Flat pixel index ``u * V + v`` of each pair.
    weight : (P,) float tensor
        Cosine similarity to the source feature (or 1), 0 where dropped as occluded.
    num_masks : int
    view_size : (U, V)
    """

    mask_index: torch.Tensor
    pixel_index: torch.Tensor
    weight: torch.Tensor
    num_masks: int
    view_size: tuple[int, int]

    def surviving_masks(self) -> torch.Tensor:
        """The coarse masks without dropped pixels, ``(N, U, V)`` bool."""
        height, width = self.view_size
        out = torch.zeros(
            (self.num_masks, height * width), dtype=torch.bool, device=self.weight.device
        )
        keep = self.weight > 0
        out[self.mask_index[keep], self.pixel_index[keep]] = True
        return out.reshape(self.num_masks, height, width)


def _pairs(masks: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    n = masks.shape[0]
    mask_index, pixel_index = torch.nonzero(masks.reshape(n, -1), as_tuple=True)
    return mask_index, pixel_index


def _covered_pixels(
    masks: torch.Tensor, pixel_index: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Pixels covered by any mask, and each pair's position among them (a sort-free unique)."""
    covered = masks.reshape(masks.shape[0], -1).any(dim=0)
    position = torch.cumsum(covered, dim=0) - 1
    return torch.nonzero(covered, as_tuple=True)[0], position[pixel_index]


def _feature_chunks(
    segmenter: Segmenter, embedding: ViewEmbedding, pixel_index: torch.Tensor, width: int
) -> Iterator[tuple[int, torch.Tensor]]:
    """Features (float32) at flat pixel indices, a chunk at a time: ``(start, (P_c, C))``."""
    for start in range(0, pixel_index.numel(), _PIXEL_CHUNK):
        flat = pixel_index[start : start + _PIXEL_CHUNK]
        rows_cols = torch.stack([flat // width, flat % width], dim=1).to(torch.float32)
        yield start, segmenter.sample_features(embedding, rows_cols.to(segmenter.device)).float()


def source_features(
    segmenter: Segmenter, embedding: ViewEmbedding, masks: torch.Tensor
) -> torch.Tensor:
    """Mean feature over each source mask, ``F(M[s_c, t_c])`` of paper section 3.3.

    Parameters
    ----------
    segmenter : Segmenter
    embedding : ViewEmbedding
        The encoded center view.
    masks : (N, U, V) bool tensor
        Source masks.

    Returns
    -------
    (N, C) float tensor, L2-normalised (zero for an empty mask)
    """
    n, _, width = masks.shape
    mask_index, pixel_index = _pairs(masks)
    unique_pixels, inverse = _covered_pixels(masks, pixel_index)
    # The paper averages the upscaled embedding over the mask (not unit vectors), then the
    # cosine similarity normalises; the sum has the direction of the mean. Features are sampled
    # a chunk of pixels at a time, so the full pixels x channels matrix never exists.
    sums = None
    for start, feats in _feature_chunks(segmenter, embedding, unique_pixels, width):
        in_chunk = (inverse >= start) & (inverse < start + len(feats))
        chosen = torch.nonzero(in_chunk, as_tuple=True)[0]
        if sums is None:
            sums = torch.zeros((n, feats.shape[1]), device=feats.device, dtype=feats.dtype)
        sums.index_add_(0, mask_index[chosen].to(feats.device), feats[inverse[chosen] - start])
    if sums is None:
        return torch.zeros((n, 1), device=segmenter.device)
    return F.normalize(sums, dim=1)


def semantic_occlusion(
    segmenter: Segmenter,
    embedding: ViewEmbedding,
    coarse: torch.Tensor,
    sources: torch.Tensor,
    t_sim: float = 0.7,
) -> OcclusionWeights:
    """Weight the coarse masks of one view by feature similarity to their source (paper 3.3).

    Parameters
    ----------
    segmenter : Segmenter
    embedding : ViewEmbedding
        The encoded view ``(s, t)`` (the same embedding later serves refinement).
    coarse : (N, U, V) bool tensor
        Coarse masks from disparity propagation.
    sources : (N, C) float tensor
        Normalised source features from :func:`source_features`.
    t_sim : float
        Similarity threshold; pixels below it are dropped (weight 0).

    Returns
    -------
    OcclusionWeights
    """
    n, height, width = coarse.shape
    mask_index, pixel_index = _pairs(coarse)
    unique_pixels, inverse = _covered_pixels(coarse, pixel_index)
    device = sources.device
    mask_index_d, inverse_d = mask_index.to(device), inverse.to(device)
    # Cosine similarity of a chunk of covered pixels to every source by a matmul (chunk x N),
    # then each pair picks its own entry: far cheaper than a per-pair C-dimensional product,
    # and neither the pixels x channels features nor the pixels x masks table exists whole.
    sources_t = sources.T
    sims = torch.zeros(mask_index.numel(), device=device, dtype=sources.dtype)
    for start, feats in _feature_chunks(segmenter, embedding, unique_pixels, width):
        feats /= feats.norm(dim=1, keepdim=True).clamp(min=1e-12)
        table = feats.to(device=device, dtype=sources.dtype) @ sources_t
        chosen = torch.nonzero(
            (inverse_d >= start) & (inverse_d < start + len(feats)), as_tuple=True
        )[0]
        sims[chosen] = table[inverse_d[chosen] - start, mask_index_d[chosen]]
    weight = torch.where(sims >= t_sim, sims, torch.zeros_like(sims))
    return OcclusionWeights(
        mask_index=mask_index_d,
        pixel_index=pixel_index.to(device),
        weight=weight,
        num_masks=n,
        view_size=(height, width),
    )


def uniform_weights(coarse: torch.Tensor) -> OcclusionWeights:
    """Weight 1 for every coarse pixel: refinement without semantic occluding."""
    n, height, width = coarse.shape
    mask_index, pixel_index = _pairs(coarse)
    return OcclusionWeights(
        mask_index=mask_index,
        pixel_index=pixel_index,
        weight=torch.ones(mask_index.numel(), device=coarse.device),
        num_masks=n,
        view_size=(height, width),
    )
