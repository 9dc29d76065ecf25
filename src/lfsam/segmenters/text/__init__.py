"""Text detectors: a phrase and one view in, instance masks with scores out (docs/design.md
section 9).

The detectors are SAM 3's concept detector through Hugging Face ``transformers``
(:mod:`lfsam.segmenters.text.sam3`; ``sam3`` and the tiny ``sam3-tiny-test``) and the
ground-truth oracle (:mod:`lfsam.segmenters.text.oracle`); :func:`load_text_detector` builds
either by name. Nothing here imports ``transformers`` until a SAM 3 detector is built.
"""

from lfsam.segmenters.text.base import Detections, TextDetector, phrase_matches
from lfsam.segmenters.text.factory import available_text_models, load_text_detector
from lfsam.segmenters.text.registry import (
    DEFAULT_TEXT_MODEL,
    DEFAULT_TEXT_THRESHOLD,
    TEXT_MODELS,
    TEXT_ORACLE,
    TINY_TEXT_TEST_MODEL,
    TextModelSpec,
)

__all__ = [
    "DEFAULT_TEXT_MODEL",
    "DEFAULT_TEXT_THRESHOLD",
    "TEXT_MODELS",
    "TEXT_ORACLE",
    "TINY_TEXT_TEST_MODEL",
    "Detections",
    "TextDetector",
    "TextModelSpec",
    "available_text_models",
    "load_text_detector",
    "phrase_matches",
]
