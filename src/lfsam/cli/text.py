"""Command-line text prompts: ``--text PHRASE[@S,T]`` and the text detector's options
(docs/design.md section 9), shared by ``segment``, ``evaluate`` and ``view``.

Each ``--text`` is one concept: every instance of the phrase the detector finds (in view
``S,T`` when tagged, else in the reference view and, with ``--references``, the extra reference
views) becomes an object whose category is the phrase. ``--text-model`` picks the detector
(default: the oracle with ``--model oracle``, else SAM 3), ``--text-checkpoint`` a local copy of
SAM 3's weights and ``--text-threshold`` the score an instance needs.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import Any

from lfsam.cli.common import unit_interval
from lfsam.prompts import TextPrompt
from lfsam.segmenters.registry import ORACLE
from lfsam.segmenters.text import (
    DEFAULT_TEXT_MODEL,
    DEFAULT_TEXT_THRESHOLD,
    TEXT_MODELS,
    TEXT_ORACLE,
    available_text_models,
)
from lfsam.segmenters.text.weights import resolve_text_weights

__all__ = ["add_text_arguments", "check_text_weights", "parse_text", "report_text"]


def parse_text(text: str) -> TextPrompt:
    """``"red cup"`` or ``"red cup@S,T"`` (the view after the last ``@``).

    Raises
    ------
    argparse.ArgumentTypeError
        An empty phrase or a tag that is not two whole numbers (one line).
    """
    phrase, at, tag = text.rpartition("@")
    if not at:
        phrase, tag = text, ""
    view = None
    if at:
        try:
            s, t = (int(x) for x in tag.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"the view after @ must be S,T (two whole numbers: view row, view column), got "
                f"{tag!r}; give PHRASE or PHRASE@S,T"
            ) from None
        view = (s, t)
    if not phrase.split():
        raise argparse.ArgumentTypeError(
            f"--text needs a phrase (e.g. --text 'red cup' or --text disc@0,0), got {text!r}"
        )
    return TextPrompt(" ".join(phrase.split()), view)


def add_text_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--text``, ``--text-model``, ``--text-checkpoint`` and ``--text-threshold``."""
    group = parser.add_argument_group("text prompts (SAM 3's concept detector; docs: Text prompts)")
    group.add_argument(
        "--text", action="append", type=parse_text, default=[], metavar="PHRASE[@S,T]",
        help="segment every instance of PHRASE found in the reference view (or in view S,T), "
        "each an object with the phrase as its category (repeatable; mixes with clicks)",
    )
    group.add_argument(
        "--text-model", choices=available_text_models(), default=None, metavar="NAME",
        help=f"text detector: {', '.join(available_text_models())}; default {TEXT_ORACLE} "
        f"with --model {ORACLE}, else {DEFAULT_TEXT_MODEL} (facebook/sam3, gated weights)",
    )
    group.add_argument(
        "--text-checkpoint", metavar="DIR",
        help="a local copy of https://huggingface.co/facebook/sam3 (config.json, "
        "*.safetensors, processor files); default: the Hugging Face cache, downloaded once",
    )
    group.add_argument(
        "--text-threshold", type=unit_interval, default=None, metavar="P",
        help=f"score an instance needs, in [0, 1] (default {DEFAULT_TEXT_THRESHOLD}, "
        "SAM 3's processor default)",
    )


def text_model_name(args: argparse.Namespace) -> str:
    """The detector ``--text-model`` (or its default) names."""
    chosen = getattr(args, "text_model", None)
    if chosen is not None:
        return chosen
    return TEXT_ORACLE if getattr(args, "model", None) == ORACLE else DEFAULT_TEXT_MODEL


def check_text_weights(args: argparse.Namespace) -> None:
    """With ``--text``, fail at once (before any light field is read) when SAM 3's weights
    cannot be had: one line saying how to get them.

    Raises
    ------
    LfsamError
        From :func:`lfsam.segmenters.text.weights.resolve_text_weights`.
    """
    if not getattr(args, "text", None):
        return
    name = text_model_name(args)
    if name not in TEXT_MODELS:
        return
    checkpoint = getattr(args, "text_checkpoint", None)
    if checkpoint is None and getattr(args, "random_weights", False):
        return
    resolve_text_weights(name, checkpoint)


def report_text(finds: Sequence[dict[str, Any]], threshold: Any) -> None:
    """One stderr line per phrase and view where nothing was found."""
    for find in finds:
        if not find["found"]:
            s, t = find["view"]
            extra = f", {find['dropped']} already found" if find.get("dropped") else ""
            print(
                f"lfsam: no instance of {find['phrase']!r} found in view {s},{t} "
                f"(score threshold {threshold}{extra})",
                file=sys.stderr,
            )
