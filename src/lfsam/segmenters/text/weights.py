"""Where SAM 3's weights come from, with SAM 2's offline-safe rules (docs/design.md sections 6
and 9).

A local copy (``--text-checkpoint DIR``: a folder with the hub repository's ``config.json``, its
``*.safetensors`` weights and the processor's files), else the Hugging Face cache, else one
download of ``facebook/sam3``. The weights are gated: where they cannot be had (downloads off,
hub unreachable, access not granted) the error is one line that says to request access on the
model page, log in with ``hf auth login`` or pass a local copy, raised at once (no retry loop).
"""

from __future__ import annotations

import os
from pathlib import Path

from lfsam.errors import LfsamError
from lfsam.segmenters.hub import (
    HUB_TIMEOUT_S,
    cached_hub_folder,
    download_hub_folder,
    is_weights_folder,
)
from lfsam.segmenters.text.registry import TextModelSpec, get_text_model_spec

__all__ = ["cached_text_weights", "how_to_get", "resolve_text_weights"]


def how_to_get(spec: TextModelSpec) -> str:
    """The fix for weights that are not here (one clause)."""
    page = f"https://huggingface.co/{spec.hub_id}"
    gated = "the weights are gated: request access on " if spec.gated else "get the weights at "
    return (
        f"{gated}{page}, log in with `hf auth login` and run once with network access, or pass "
        "a local copy of that repository with --text-checkpoint DIR"
    )


def cached_text_weights(name: str) -> Path | None:
    """The cached snapshot folder of text model ``name``, or None (never uses the network)."""
    spec = get_text_model_spec(name)
    return None if spec.hub_id is None else cached_hub_folder(spec.hub_id)


def resolve_text_weights(
    name: str, checkpoint: str | os.PathLike | None = None, *, timeout: float = HUB_TIMEOUT_S
) -> Path:
    """The folder to load text model ``name`` from: the given copy, the cache, or a download.

    Raises
    ------
    LfsamError
        A ``checkpoint`` that is not such a folder; a model without published weights; weights
        neither cached nor downloadable (offline, hub unreachable, gated and not granted).
        Fails within about ``timeout`` seconds.
    """
    spec = get_text_model_spec(name)
    if checkpoint is not None:
        folder = Path(checkpoint).expanduser()
        if not is_weights_folder(folder):
            raise LfsamError(
                f"--text-checkpoint {str(folder)!r} is not a folder with config.json and "
                f"*.safetensors weights; pass a local copy of "
                f"https://huggingface.co/{spec.hub_id or 'facebook/sam3'}"
            )
        return folder
    if spec.random_only:
        raise LfsamError(
            f"text model {name} has no published weights; add --random-weights (tests and speed "
            "checks only) or pass --text-checkpoint DIR"
        )
    return download_hub_folder(
        spec.hub_id, f"text model {name}", how_to_get(spec), timeout=timeout
    )
