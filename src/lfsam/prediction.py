"""What a prediction of :class:`lfsam.predictor.LightFieldPredictor` returns.

:class:`LightFieldPrediction` holds the label field of the objects predicted so far and each
object's own masks, kept bit-packed and unpacked one object at a time on access
(:class:`PackedMaskMap`; docs/design.md section 8).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass

import numpy as np

__all__ = ["LightFieldPrediction", "PackedMaskMap"]

View = tuple[int, int]


class PackedMaskMap(Mapping):
    """``obj_id -> (S, T, U, V) bool`` unpacked on access (never all at once)."""

    def __init__(self, bits: dict[int, np.ndarray], shape: tuple[int, int, int, int]):
        self._bits = bits
        self._shape = shape

    def __getitem__(self, obj_id: int) -> np.ndarray:
        s, t, u, v = self._shape
        bits = np.unpackbits(self._bits[obj_id], axis=-1, count=u * v)
        return bits.reshape(s, t, u, v).astype(bool)

    def __iter__(self) -> Iterator[int]:
        return iter(self._bits)

    def __len__(self) -> int:
        return len(self._bits)


@dataclass
class LightFieldPrediction:
    """Masks of the objects over all views.

    Attributes
    ----------
    labels : (S, T, U, V) int32 ndarray
        Label field; an object's label value is its id, 0 = unlabeled.
    masks : mapping obj_id -> (S, T, U, V) bool ndarray
        Each object's own mask (overlaps kept), unpacked on access.
    scores : dict obj_id -> float
        The segmenter's score of the reference-view mask.
    reference_views : dict obj_id -> (s, t)
    stage : {"coarse", "refined"}
    """

    labels: np.ndarray
    masks: Mapping[int, np.ndarray]
    scores: dict[int, float]
    reference_views: dict[int, View]
    stage: str = "refined"
