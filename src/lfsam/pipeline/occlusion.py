"""Step 3 of the pipeline: removing occluded pixels from the coarse masks.

Semantic occluding (paper section 3.3): the source feature of a mask is the mean SAM 2 image
embedding over the center-view mask (the embedding brought to image resolution); in view
``(s, t)`` every coarse-mask pixel gets the cosine similarity of its own feature to the source
feature. Pixels below ``t_sim`` (0.7 in the paper, section 4) get weight 0 and are dropped; the
others keep their similarity as a weight, used later to place the refinement prompt.

Geometric occluding (docs/design.md section 3, beyond the paper) is a z-buffer test on the center
disparity, done during propagation (:func:`lfsam.pipeline.propagation.propagate_masks` with
``occlusion_tolerance``; :meth:`lfsam.warp.ForwardWarp.visible` and
:meth:`lfsam.warp.ForwardWarp.hides`).

Masks are handled as (mask index, pixel index) pairs so memory follows the masks' total area,
not N x U x V features; the features themselves are the segmenter's business
(:meth:`~lfsam.segmenters.base.Segmenter.feature_sums`,
:meth:`~lfsam.segmenters.base.Segmenter.feature_similarity`), which for SAM 2 never samples the
256-channel embedding at every pixel (:mod:`lfsam.segmenters.feature_grid`).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F

from lfsam.segmenters.base import Segmenter, ViewEmbedding

__all__ = [
    "OcclusionWeights",
    "semantic_occlusion",
    "source_features",
    "stack_source_features",
    "uniform_weights",
]



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
        # every pair written (each is one distinct pixel of one mask): no selection of the kept
        # ones, which would make a GPU wait for the host (docs/design.md section 3.5)
        out[self.mask_index, self.pixel_index] = self.weight > 0
        return out.reshape(self.num_masks, height, width)


def _pairs(masks: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    n = masks.shape[0]
    mask_index, pixel_index = torch.nonzero(masks.reshape(n, -1), as_tuple=True)
    return mask_index, pixel_index


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
    # The paper averages the upscaled embedding over the mask (not unit vectors), then the
    # cosine similarity normalises; the sum has the direction of the mean.
    mask_index, pixel_index = _pairs(masks)
    sums = segmenter.feature_sums(embedding, mask_index, pixel_index, masks.shape[0])
    return F.normalize(sums, dim=1)


def stack_source_features(features: list[torch.Tensor]) -> torch.Tensor:
    """The source features of masks from several reference views as one ``(N, C)`` tensor.

    An empty source mask has a zero feature of width 1
    (:meth:`~lfsam.segmenters.base.Segmenter.feature_sums`); it propagates nowhere, so it
    becomes a zero row of the others' width.
    """
    channels = max(f.shape[-1] for f in features)
    return torch.stack([f if f.shape[-1] == channels else f.new_zeros(channels)
                        for f in features])


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
    device = sources.device
    sims = segmenter.feature_similarity(embedding, mask_index, pixel_index, sources).to(device)
    weight = torch.where(sims >= t_sim, sims, torch.zeros_like(sims))
    return OcclusionWeights(
        mask_index=mask_index.to(device),
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
