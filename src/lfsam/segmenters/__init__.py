"""Promptable segmenters behind one interface: SAM 2 and a ground-truth oracle."""

from lfsam.segmenters.base import (
    ABSENT_POINT,
    AutoMasks,
    MaskPrediction,
    Prompts,
    Segmenter,
    ViewEmbedding,
)
from lfsam.segmenters.factory import available_models, load_segmenter
from lfsam.segmenters.registry import DEFAULT_MODEL, MODELS, ORACLE, TINY_TEST_MODEL, ModelSpec

__all__ = [
    "ABSENT_POINT",
    "DEFAULT_MODEL",
    "MODELS",
    "ORACLE",
    "TINY_TEST_MODEL",
    "AutoMasks",
    "MaskPrediction",
    "ModelSpec",
    "Prompts",
    "Segmenter",
    "ViewEmbedding",
    "available_models",
    "load_segmenter",
]
