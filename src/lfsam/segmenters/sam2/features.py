"""The SAM 2 backend's features for semantic occluding (paper section 3.3): the image embedding
sampled at pixels (:meth:`FeatureSampling.sample_features`), summed over masks
(:meth:`FeatureSampling.feature_sums`) and compared with each mask's source feature
(:meth:`FeatureSampling.feature_similarity`), exactly on the embedding grid
(:mod:`lfsam.segmenters.feature_grid`). :class:`FeatureSampling` is a base of
:class:`lfsam.segmenters.sam2.backend.Sam2Segmenter`.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from lfsam.segmenters.base import ViewEmbedding
from lfsam.segmenters.feature_grid import (
    grid_cosine_similarity,
    grid_feature_sums,
    pixel_feature_norms,
)

__all__ = ["FeatureSampling"]


class FeatureSampling:
    """The feature side of :class:`~lfsam.segmenters.sam2.backend.Sam2Segmenter` (module
    docstring). A base of the segmenter: it reads the segmenter's ``device`` and
    ``_view_features``; a backend whose embedding is padded overrides :meth:`_feature_grid`."""

    def _feature_grid(self, embedding: ViewEmbedding) -> torch.Tensor:
        """The ``(1, C, h, w)`` embedding cells that span the view, which semantic occluding
        samples (:mod:`lfsam.segmenters.feature_grid`): the whole embedding, as the view is
        resized to the square input (a padded input keeps only the cells over the view)."""
        return self._view_features(embedding).image_embed

    def sample_features(self, embedding: ViewEmbedding, rows_cols: torch.Tensor) -> torch.Tensor:
        """Bilinearly sample the image embedding at pixel positions (paper section 3.3).

        The view is resized to the model's square input without padding (a padded input
        samples only the cells over the view, :meth:`_feature_grid`), so each axis maps
        separately: pixel row ``r`` of a ``U``-row view lies at normalised coordinate
        ``2 (r + 0.5) / U - 1`` of the embedding grid (half-pixel centres, as
        ``F.interpolate(..., mode="bilinear", align_corners=False)``). Positions beyond the
        outermost feature centres take the border value.

        Returns
        -------
        features : (P, C) float32 tensor on :attr:`device` (C = 256 for the real models)
        """
        u_size, v_size = embedding.image_size
        rc = torch.as_tensor(rows_cols, dtype=torch.float32, device=self.device).reshape(-1, 2)
        with torch.no_grad():
            emb = self._feature_grid(embedding).float()
            grid = torch.stack(
                [(rc[:, 1] + 0.5) * (2.0 / v_size) - 1.0, (rc[:, 0] + 0.5) * (2.0 / u_size) - 1.0],
                dim=-1,
            )
            sampled = F.grid_sample(
                emb,
                grid.view(1, 1, -1, 2),
                mode="bilinear",
                padding_mode="border",
                align_corners=False,
            )
        return sampled[0, :, 0, :].transpose(0, 1).contiguous()

    def feature_sums(
        self,
        embedding: ViewEmbedding,
        mask_index: torch.Tensor,
        pixel_index: torch.Tensor,
        num_masks: int,
    ) -> torch.Tensor:
        """Sum of the bilinearly upsampled embedding over each mask, computed on the embedding
        grid (exact; :func:`lfsam.segmenters.feature_grid.grid_feature_sums`)."""
        with torch.no_grad():
            grid = self._feature_grid(embedding)[0].float()
            return grid_feature_sums(
                grid, mask_index.to(self.device), pixel_index.to(self.device), num_masks,
                tuple(embedding.image_size),
            )

    def feature_similarity(
        self,
        embedding: ViewEmbedding,
        mask_index: torch.Tensor,
        pixel_index: torch.Tensor,
        sources: torch.Tensor,
    ) -> torch.Tensor:
        """Cosine similarity of the upsampled embedding at each pair's pixel to its mask's
        source, without sampling 256 channels per pixel (exact;
        :func:`lfsam.segmenters.feature_grid.grid_cosine_similarity`)."""
        with torch.no_grad():
            feats = self._view_features(embedding)
            grid = self._feature_grid(embedding)[0].float()
            if feats.pixel_norms is None:  # prompt-independent: once per view
                feats.pixel_norms = pixel_feature_norms(grid, tuple(embedding.image_size))
            sims = grid_cosine_similarity(
                grid, mask_index, pixel_index, sources.to(self.device),
                tuple(embedding.image_size), norms=feats.pixel_norms,
            )
        return sims.to(sources.device)

