"""One entry point for every backend: ``load_segmenter(model=...)`` (the CLI's ``--model``).

SAM 2 models are built by :mod:`lfsam.segmenters.sam2.build` and wrapped by
:class:`~lfsam.segmenters.sam2.backend.Sam2Segmenter`; EdgeTAM and any transformers-format folder
(``checkpoint`` a directory) by :mod:`lfsam.segmenters.transformers.build` and wrapped by
:class:`~lfsam.segmenters.transformers.backend.TransformersSegmenter` (docs/design.md section 3.8);
``"oracle"`` gives an :class:`~lfsam.segmenters.oracle.OracleSegmenter` on a light field's
ground-truth labels.
"""

from __future__ import annotations

import os
from typing import Any

import torch

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.segmenters.base import Segmenter
from lfsam.segmenters.registry import (
    DEFAULT_MODEL,
    MODELS,
    ORACLE,
    TRANSFORMERS_FOLDER,
    TRANSFORMERS_MODELS,
    get_model_spec,
)

__all__ = ["available_models", "load_segmenter"]


def available_models() -> list[str]:
    """Every name ``load_segmenter`` accepts: the SAM 2 models, the transformers models
    (EdgeTAM), ``"transformers"`` (a folder given as ``checkpoint``), then ``"oracle"``."""
    return [*MODELS, *TRANSFORMERS_MODELS, TRANSFORMERS_FOLDER, ORACLE]


def load_segmenter(
    model: str = DEFAULT_MODEL,
    *,
    checkpoint: str | os.PathLike | None = None,
    random_weights: bool = False,
    device: str | torch.device | None = None,
    lightfield: LightField | None = None,
    amg_options: dict[str, Any] | None = None,
    seed: int = 0,
    oracle_options: dict[str, Any] | None = None,
    keep_decoder_state: bool = True,
    precision: str = "auto",
    **sam2_options: Any,
) -> Segmenter:
    """Build the segmenter called ``model``.

    Parameters
    ----------
    model : str
        A SAM 2 model name (default the paper's ``sam2.1-hiera-small``), ``"edgetam"``,
        ``"transformers"`` (the folder given as ``checkpoint``) or ``"oracle"``; see
        :func:`available_models`.
    checkpoint : path, optional
        SAM 2 weights file (``.pt``), or a transformers-format folder (``config.json`` +
        ``*.safetensors`` of model type ``sam2`` or ``edgetam``: loaded by the transformers
        backend whatever ``model`` says, which only has to be of the same family); default: the
        hub cache, downloaded once.
    random_weights : bool
        SAM 2 architecture without trained weights (tests and speed measurements only).
    device : str or torch.device, optional
        Default ``auto``: CUDA, then MPS, then CPU (:func:`lfsam.devices.resolve_device`).
    lightfield : LightField, optional
        Required for ``"oracle"`` (it must carry ground-truth labels).
    amg_options : dict, optional
        Overrides of the paper's automatic-mask-generation settings (SAM 2 only).
    seed : int
        Seed of random weights (SAM 2) or of the oracle's imperfections.
    oracle_options : dict, optional
        ``min_area``, ``boundary_jitter``, ``merge_prob`` of
        :class:`~lfsam.segmenters.oracle.OracleSegmenter`.
    keep_decoder_state : bool
        SAM 2: keep the decoder's image side with each embedding (interactive edits decode a
        view again; about three times the memory per view). Batch runs, which decode each view
        once, turn it off. The oracle has no such state.
    **sam2_options
        Further keywords of :class:`~lfsam.segmenters.sam2.backend.Sam2Segmenter`
        (``max_prompts_per_batch``, ``encode_batch_size``, ``mask_threshold``,
        ``cross_view_decode``, ``cross_view_rows``, ``compile_decoder``).

    Raises
    ------
    LfsamError
        Unknown model, oracle without a labelled light field, options that do not apply to the
        backend, or SAM 2 weights that cannot be had (one line that says how to provide them).
    """
    if model == ORACLE:
        if (checkpoint is not None or random_weights or amg_options or sam2_options
                or precision != "auto"):
            raise LfsamError(
                "--checkpoint, --random-weights, --precision and SAM 2 options do not apply to "
                "the oracle; drop them or choose a SAM 2 --model"
            )
        if lightfield is None or lightfield.labels is None:
            raise LfsamError(
                "--model oracle needs a light field with ground-truth labels (e.g. made by "
                "`lfsam synth`); give one or choose a SAM 2 --model"
            )
        from lfsam.segmenters.oracle import OracleSegmenter

        return OracleSegmenter(lightfield, seed=seed, device=device, **(oracle_options or {}))
    if oracle_options:
        raise LfsamError("oracle options apply only to --model oracle; drop them")
    from lfsam.segmenters.transformers.build import is_transformers_folder

    transformers = model in TRANSFORMERS_MODELS or model == TRANSFORMERS_FOLDER
    if not transformers:
        get_model_spec(model)  # unknown names fail before anything is imported or downloaded
    if transformers or is_transformers_folder(checkpoint):
        from lfsam.segmenters.transformers.backend import TransformersSegmenter as backend
    else:
        from lfsam.segmenters.sam2.backend import Sam2Segmenter as backend
    return backend.from_name(
        model,
        checkpoint=checkpoint,
        random_weights=random_weights,
        device=device,
        seed=seed,
        amg_options=amg_options,
        keep_decoder_state=keep_decoder_state,
        precision=precision,
        **sam2_options,
    )
