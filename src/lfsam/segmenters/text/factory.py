"""One entry point for every text detector: :func:`load_text_detector` (``--text-model``)."""

from __future__ import annotations

import os

import torch

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.segmenters.text.base import TextDetector
from lfsam.segmenters.text.registry import TEXT_MODELS, TEXT_ORACLE, get_text_model_spec

__all__ = ["available_text_models", "load_text_detector"]


def available_text_models() -> list[str]:
    """Every name :func:`load_text_detector` accepts: the SAM 3 models, then ``"oracle"``."""
    return [*TEXT_MODELS, TEXT_ORACLE]


def load_text_detector(
    name: str,
    *,
    checkpoint: str | os.PathLike | None = None,
    random_weights: bool = False,
    device: str | torch.device | None = None,
    lightfield: LightField | None = None,
    seed: int = 0,
) -> TextDetector:
    """Build the text detector called ``name`` (docs/design.md section 9).

    Parameters
    ----------
    name : str
        ``sam3`` (``facebook/sam3``), ``sam3-tiny-test`` or ``oracle``.
    checkpoint : path, optional
        SAM 3: a local copy of the hub repository (a folder).
    random_weights : bool
        SAM 3: the architecture untrained (tests and speed checks only). Ignored by the oracle.
    device : str or torch.device, optional
        SAM 3's device (default ``auto``).
    lightfield : LightField, optional
        Required for the oracle (labels with categories).
    seed : int
        Seed of random weights.

    Raises
    ------
    LfsamError
        Unknown name, an oracle without categories, SAM 3 without ``transformers`` or without
        weights (one line that says how to get them), a checkpoint given to the oracle.
    """
    if name == TEXT_ORACLE:
        if checkpoint is not None:
            raise LfsamError("--text-checkpoint does not apply to the text oracle; drop it")
        from lfsam.segmenters.text.oracle import OracleTextDetector

        return OracleTextDetector(lightfield)
    get_text_model_spec(name)  # unknown names fail before anything is imported or downloaded
    from lfsam.segmenters.text.sam3 import Sam3TextDetector

    return Sam3TextDetector(
        name, checkpoint=checkpoint, random_weights=random_weights, device=device, seed=seed
    )
