"""Promptable segmenters behind one interface: SAM 2 and a ground-truth oracle."""

from lfsam.segmenters.base import AutoMasks, MaskPrediction, Prompts, Segmenter, ViewEmbedding

__all__ = ["AutoMasks", "MaskPrediction", "Prompts", "Segmenter", "ViewEmbedding"]
