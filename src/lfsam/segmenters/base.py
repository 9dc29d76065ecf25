"""The promptable-segmenter interface the pipeline talks to.

Its life cycle follows Meta's ``SAM2ImagePredictor`` (``set_image`` then ``predict``), split so a
view is encoded once and its embedding serves every later step (docs/design.md section 3,
"efficiency facts"): :meth:`Segmenter.encode` a batch of views once, then for each
:class:`ViewEmbedding` :meth:`Segmenter.predict` a batch of N prompts in one call,
:meth:`Segmenter.generate` masks automatically, or :meth:`Segmenter.sample_features` per-pixel
features for semantic occluding (paper section 3.3).

Coordinates: prompt points and boxes are ``(x, y)`` = (pixel column, pixel row) in the view's own
pixels, as in ``sam2``; boxes are ``(x0, y0, x1, y1)``. Masks are ``(..., U, V)`` boolean tensors.
"""

from __future__ import annotations

import abc
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from lfsam.errors import LfsamError

__all__ = [
    "ABSENT_POINT",
    "AutoMasks",
    "MaskPrediction",
    "Prompts",
    "Segmenter",
    "ViewEmbedding",
]


ABSENT_POINT = -2
"""Point label of a point that is not there (docs/design.md section 3.5, "one decoder call for
prompts of different lengths"): a segmenter whose :attr:`Segmenter.skips_absent_points` is True
answers a prompt padded with such points exactly as the prompt without them. Unlike SAM 2's
own padding label -1, which the decoder attends to like any token."""


@dataclass
class Prompts:
    """A batch of N prompts for one view; each prompt asks for one object.

    Parameters
    ----------
    points : (N, P, 2) float array or tensor, optional
        Point coordinates ``(x, y)`` in view pixels.
    point_labels : (N, P) int array or tensor, optional
        1 = positive (object), 0 = negative (background), -1 = SAM 2's padding point (a token
        the decoder attends to), :data:`ABSENT_POINT` = no point at all (prompts of different
        lengths in one batch); required with ``points``.
    boxes : (N, 4) float array or tensor, optional
        Boxes ``(x0, y0, x1, y1)`` in view pixels.
    absent_points : bool, optional
        Whether some labels are :data:`ABSENT_POINT`. Found from the labels when not given
        (for labels on a GPU that reads them back: give it where the prompts are made).

    Arrays are kept as NumPy arrays (float32 / int64); torch tensors stay tensors on their
    device, cast once to the same dtypes, so prompts made on the device (refinement,
    docs/design.md section 3.5) reach the decoder without a trip through the host.

    Raises
    ------
    LfsamError
        Neither points nor boxes, points without labels, or different numbers of point and box
        prompts.
    """

    points: np.ndarray | torch.Tensor | None = None
    point_labels: np.ndarray | torch.Tensor | None = None
    boxes: np.ndarray | torch.Tensor | None = None
    absent_points: bool | None = None

    def __post_init__(self) -> None:
        if self.points is None and self.boxes is None:
            raise LfsamError("a prompt needs points, a box, or both; give at least one")
        if self.points is not None:
            self.points = _as(self.points, torch.float32).reshape(len(self.points), -1, 2)
            if self.point_labels is None:
                raise LfsamError(
                    "points need point_labels (1 = positive, 0 = negative); give one per point"
                )
            self.point_labels = _as(self.point_labels, torch.int64).reshape(
                tuple(self.points.shape[:2])
            )
            if self.absent_points is None:
                self.absent_points = bool((self.point_labels == ABSENT_POINT).any())
        else:
            self.absent_points = False
        if self.boxes is not None:
            self.boxes = _as(self.boxes, torch.float32).reshape(-1, 4)
        if self.points is not None and self.boxes is not None:
            if len(self.points) != len(self.boxes):
                raise LfsamError(
                    f"{len(self.points)} point prompts but {len(self.boxes)} boxes; give as many "
                    "of each (prompt i = point i + box i) or only one kind"
                )

    def __len__(self) -> int:
        return len(self.points) if self.points is not None else len(self.boxes)

    def subset(self, index: slice | np.ndarray) -> Prompts:
        """The prompts selected by ``index`` (for chunked decoding)."""
        return Prompts(
            points=None if self.points is None else self.points[index],
            point_labels=None if self.point_labels is None else self.point_labels[index],
            boxes=None if self.boxes is None else self.boxes[index],
            absent_points=(
                self.absent_points if isinstance(self.point_labels, torch.Tensor) else None
            ),
        )


def _as(values: Any, dtype: torch.dtype) -> np.ndarray | torch.Tensor:
    """A tensor cast to ``dtype`` on its own device, anything else a NumPy array of it."""
    if isinstance(values, torch.Tensor):
        return values.to(dtype)
    return np.asarray(values, dtype=_NUMPY_DTYPES[dtype])


_NUMPY_DTYPES = {torch.float32: np.float32, torch.int64: np.int64}


@dataclass
class ViewEmbedding:
    """One encoded view: what a backend needs to answer prompts without re-encoding.

    Parameters
    ----------
    image_size : (U, V)
        The view's size in pixels.
    key : (s, t) or None
        Which view of the light field this is (the oracle needs it; SAM 2 ignores it).
    data : Any
        Backend-specific state (for SAM 2: the image embedding and high-resolution features).
    """

    image_size: tuple[int, int]
    key: tuple[int, int] | None = None
    data: Any = field(default=None, repr=False)


@dataclass
class MaskPrediction:
    """Masks for a batch of N prompts, K candidates each (K = 3 multimask, 1 single).

    Parameters
    ----------
    masks : (N, K, U, V) bool tensor
    iou_predictions : (N, K) float tensor
        The model's own quality estimate of each mask.
    low_res_logits : (N, K, h, w) float tensor
        Mask logits at the decoder's resolution (256 x 256 for SAM 2), or an empty tensor.
    """

    masks: torch.Tensor
    iou_predictions: torch.Tensor
    low_res_logits: torch.Tensor


@dataclass
class AutoMasks:
    """Masks from automatic generation on one view.

    Parameters
    ----------
    masks : (M, U, V) bool ndarray
    scores : (M,) float ndarray
        Predicted IoU (SAM 2) or 1.0 (oracle).
    """

    masks: np.ndarray
    scores: np.ndarray


class Segmenter(abc.ABC):
    """A promptable segmenter: encode views once, then prompt, generate and probe features.

    Subclasses set :attr:`name` and :attr:`device` and implement the abstract methods.
    :attr:`encode_calls` counts views encoded, so tests can check each view is encoded once.
    """

    name: str = "segmenter"
    device: torch.device = torch.device("cpu")
    random_weights: bool = False
    points_per_side: int = 32
    """Density of the automatic mode's point grid (points per image side); the extra reference
    views of :class:`lfsam.generator.LightFieldMaskGenerator` ask at half of it."""
    skips_absent_points: bool = False
    """Whether :meth:`predict` answers a prompt padded with :data:`ABSENT_POINT` points exactly
    as the prompt without them (up to rounding), so prompts of different lengths can share one
    call; refinement decodes them apart otherwise (docs/design.md section 3.5)."""

    def __init__(self) -> None:
        self.encode_calls = 0

    def describe(self) -> dict[str, Any]:
        """JSON-ready facts for result metadata (backends add their own)."""
        return {
            "name": self.name,
            "device": str(self.device),
            "random_weights": self.random_weights,
        }

    @abc.abstractmethod
    def encode(
        self, images: np.ndarray, keys: list[tuple[int, int]] | None = None
    ) -> list[ViewEmbedding]:
        """Encode a batch of views once.

        Parameters
        ----------
        images : (B, U, V, 3) uint8 ndarray
            The views (all the same size).
        keys : list of (s, t), optional
            Which views these are (required by the oracle).

        Returns
        -------
        embeddings : list of ViewEmbedding, length B
        """

    @abc.abstractmethod
    def predict(
        self, embedding: ViewEmbedding, prompts: Prompts, multimask_output: bool = True
    ) -> MaskPrediction:
        """Decode N prompts on one encoded view in one batch.

        Parameters
        ----------
        embedding : ViewEmbedding
            From :meth:`encode`.
        prompts : Prompts
            N prompts (points and/or boxes).
        multimask_output : bool
            Return three candidate masks per prompt (True) or one (False).

        Returns
        -------
        MaskPrediction
        """

    def predict_many(
        self,
        embeddings: Sequence[ViewEmbedding],
        prompts: Sequence[Prompts],
        multimask_output: bool = True,
    ) -> list[MaskPrediction]:
        """Decode the prompts of several views: ``prompts[i]`` on ``embeddings[i]``.

        The batched form of :meth:`predict` (docs/design.md section 3.5, "batched decoder"):
        a backend that can put prompts of different views through one decoder call overrides it
        (:meth:`lfsam.segmenters.sam2.backend.Sam2Segmenter.predict_many`); this default
        decodes view by view, so every backend answers it, with the same masks as
        :meth:`predict`.

        Returns
        -------
        list of MaskPrediction
            One per view, as :meth:`predict` returns it.
        """
        if len(embeddings) != len(prompts):
            raise LfsamError(
                f"got {len(embeddings)} views but {len(prompts)} prompt batches; give one "
                "Prompts per view"
            )
        return [
            self.predict(embedding, batch, multimask_output=multimask_output)
            for embedding, batch in zip(embeddings, prompts, strict=True)
        ]

    @abc.abstractmethod
    def generate(
        self, embedding: ViewEmbedding, image: np.ndarray, points: np.ndarray | None = None
    ) -> AutoMasks:
        """Automatic mask generation on one encoded view (paper section 4, implementation details).

        ``points`` ``(P, 2)`` (x, y pixels) replaces the generator's regular point grid (the
        multi-reference automatic mode asks only where no mask lands yet; docs/design.md
        section 8); None = the backend's own grid.

        Parameters
        ----------
        embedding : ViewEmbedding
            From :meth:`encode`; backends reuse it instead of encoding the view again.
        image : (U, V, 3) uint8 ndarray
            The same view (some backends need the pixels, e.g. for crops).
        """

    @abc.abstractmethod
    def sample_features(self, embedding: ViewEmbedding, rows_cols: torch.Tensor) -> torch.Tensor:
        """Per-pixel features at given pixel positions, for semantic occluding (paper 3.3).

        The backend's feature map (for SAM 2 the 256-channel image embedding at 1/16 resolution)
        is brought to image resolution only at the requested pixels, by bilinear interpolation,
        never stored at full size.

        Parameters
        ----------
        embedding : ViewEmbedding
        rows_cols : (P, 2) float tensor
            Pixel ``(row, column)`` positions in the view.

        Returns
        -------
        features : (P, C) float32 tensor on :attr:`device`
        """

    # --- the on-disk embedding cache (lfsam.embeddings; docs/design.md section 8) -----------------
    def cache_identity(self) -> str | None:
        """What, besides a view's bytes, determines its embedding: model name, a hash of the
        weights, input size, precision. None (the default) means embeddings are not worth
        caching on disk (e.g. the oracle, which runs no encoder)."""
        return None

    def embedding_state(self, embedding: ViewEmbedding) -> dict[str, np.ndarray]:
        """The embedding as plain arrays for the disk cache (lossless)."""
        raise NotImplementedError(f"{type(self).__name__} does not cache embeddings on disk")

    def embedding_from_state(
        self, state: dict[str, np.ndarray], image_size: tuple[int, int], key: tuple[int, int]
    ) -> ViewEmbedding:
        """Rebuild an embedding from :meth:`embedding_state`'s arrays."""
        raise NotImplementedError(f"{type(self).__name__} does not cache embeddings on disk")

    # --- what semantic occluding needs of the features (defaults: via sample_features) ----------
    #: Pixels whose features are sampled at once by the default implementations below.
    feature_chunk: int = 65536

    def _feature_chunks(
        self, embedding: ViewEmbedding, pixel_index: torch.Tensor, width: int
    ) -> Any:
        """Features at flat pixel indices, a chunk at a time: ``(start, (P_c, C) float32)``."""
        for start in range(0, pixel_index.numel(), self.feature_chunk):
            flat = pixel_index[start : start + self.feature_chunk]
            rows_cols = torch.stack([flat // width, flat % width], dim=1).to(torch.float32)
            yield start, self.sample_features(embedding, rows_cols.to(self.device)).float()

    def feature_sums(
        self,
        embedding: ViewEmbedding,
        mask_index: torch.Tensor,
        pixel_index: torch.Tensor,
        num_masks: int,
    ) -> torch.Tensor:
        """Sum of the per-pixel features over each mask (paper 3.3: the source feature is their
        mean; its direction is all the cosine similarity uses).

        Parameters
        ----------
        embedding : ViewEmbedding
        mask_index, pixel_index : (P,) int64 tensors
            The masks as (mask, flat pixel ``u * V + v``) pairs.
        num_masks : int

        Returns
        -------
        (num_masks, C) float32 tensor on :attr:`device`

        The default samples :meth:`sample_features` a chunk of pixels at a time; backends with a
        feature grid override it with an exact shortcut (:mod:`lfsam.segmenters.feature_grid`).
        """
        width = embedding.image_size[1]
        sums = None
        for start, feats in self._feature_chunks(embedding, pixel_index, width):
            if sums is None:
                sums = torch.zeros((num_masks, feats.shape[1]), device=feats.device)
            chunk = mask_index[start : start + len(feats)].to(feats.device)
            sums.index_add_(0, chunk, feats)
        if sums is None:
            return torch.zeros((num_masks, 1), device=self.device)
        return sums

    def feature_similarity(
        self,
        embedding: ViewEmbedding,
        mask_index: torch.Tensor,
        pixel_index: torch.Tensor,
        sources: torch.Tensor,
    ) -> torch.Tensor:
        """Cosine similarity of each pair's pixel feature to its mask's source feature (paper 3.3).

        Parameters
        ----------
        embedding : ViewEmbedding
            The encoded view.
        mask_index, pixel_index : (P,) int64 tensors
            (mask, flat pixel ``u * V + v``) pairs.
        sources : (N, C) float tensor
            Unit-norm source features (:meth:`feature_sums`, normalised).

        Returns
        -------
        (P,) float32 tensor on the device of ``sources``
        """
        width = embedding.image_size[1]
        device = sources.device
        sims = torch.zeros(pixel_index.numel(), device=device, dtype=torch.float32)
        for start, feats in self._feature_chunks(embedding, pixel_index, width):
            feats = F.normalize(feats.to(device), dim=1, eps=1e-12)
            chunk = mask_index[start : start + len(feats)].to(device)
            sims[start : start + len(feats)] = (feats * sources[chunk].float()).sum(1)
        return sims
