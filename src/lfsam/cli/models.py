"""``lfsam models``: which segmenters exist, how big they are, whether their weights are here.

Also the shared ``--model`` / ``--checkpoint`` / ``--random-weights`` / ``--device`` / ``--amg``
options of the commands that segment (:func:`add_model_arguments`) and the one call that turns
them into a segmenter (:func:`segmenter_from_args`), so every command reports missing weights the
same way.
"""

from __future__ import annotations

import argparse
import ast
import json
from typing import Any

from lfsam.cli.common import HelpFormatter, add_device_argument, bounded_int, probability
from lfsam.devices import resolve_device
from lfsam.errors import LfsamError
from lfsam.fileutil import check_writable
from lfsam.lightfield import LightField
from lfsam.segmenters.base import Segmenter
from lfsam.segmenters.factory import available_models
from lfsam.segmenters.registry import (
    DEFAULT_MODEL,
    MODELS,
    ORACLE,
    TRANSFORMERS_FOLDER,
    TRANSFORMERS_MODELS,
)
from lfsam.segmenters.sam2.build import PRECISIONS
from lfsam.segmenters.text.registry import TEXT_MODELS, TINY_SAM3_SIZES

__all__ = [
    "add_model_arguments",
    "list_models",
    "model_name_from_args",
    "parse_option",
    "register",
    "run",
    "segmenter_from_args",
]

DESCRIPTION = """\
List the segmenters lfsam can use with --model: the SAM 2 image models (SAM 2.1 and 2.0 in four
sizes; the paper uses sam2.1-hiera-small, the default), EdgeTAM (SAM 2 for devices: a 4x faster
image encoder, run through Hugging Face transformers), the tiny random-weight models for tests,
and the ground-truth oracle; and the text detectors of --text-model: SAM 3 (facebook/sam3, gated
weights) and its tiny random-weight test model. For each model: its parameter count, the size
of its float32 weights, and whether the weights are already in the Hugging Face cache (looked
up on disk, no network). Weights not cached are downloaded on first use; without network,
download the .pt file from the model hub by hand and pass it with --checkpoint FILE (EdgeTAM:
the repository's folder, --checkpoint DIR). Any transformers-format SAM 2, EdgeTAM or SAM folder
(config.json + *.safetensors) works with --checkpoint DIR; its config.json names the model.
"""

EPILOG = """\
examples:
  lfsam models                                  # table of models, cache state and device
  lfsam models --json                           # the same as JSON
  lfsam models --download sam2.1-hiera-small    # fetch the paper's weights into the cache now
  lfsam models --download edgetam               # fetch EdgeTAM (yonigozlan/EdgeTAM-hf)
"""


class ModelNotGiven(str):
    """The ``--model`` default as parsed: equal to the default name, but marks that the user
    did not name a model (a transformers folder given with ``--checkpoint DIR`` then names it)."""



def parse_option(text: str) -> tuple[str, Any]:
    """Parse ``KEY=VALUE`` (VALUE a Python literal such as ``32``, ``0.9`` or ``True``)."""
    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    try:
        parsed = ast.literal_eval(value.strip())
    except (ValueError, SyntaxError):
        parsed = value.strip()
    return key.strip(), parsed


def add_model_arguments(
    parser: argparse.ArgumentParser, default: str | None = DEFAULT_MODEL, model_help: str = ""
) -> None:
    """Add ``--model``, ``--checkpoint``, ``--random-weights``, ``--device``, ``--precision``
    and ``--amg``.

    The one set of model and device options of every command that segments (``segment``,
    ``evaluate``, ``demo``); ``model_help`` is appended to the help of ``--model`` (e.g. what
    a ``None`` default means).
    """
    group = parser.add_argument_group("segmenter")
    group.add_argument(
        "--model",
        default=None if default is None else ModelNotGiven(default),
        choices=available_models(),
        metavar="NAME",
        help="SAM 2 model, 'edgetam' (fast, on-device SAM 2) or 'oracle' (ground-truth labels); "
        "see `lfsam models`" + model_help,
    )
    group.add_argument(
        "--checkpoint",
        metavar="PATH",
        help="SAM 2 weights file (.pt), or a transformers-format folder (config.json + "
        "*.safetensors of a SAM 2, EdgeTAM or SAM model; its config names the model, so --model "
        "may be left out); default: the Hugging Face cache, downloaded once",
    )
    group.add_argument(
        "--random-weights",
        action="store_true",
        help="untrained SAM 2 of the same architecture (speed tests only: masks are meaningless)",
    )
    add_device_argument(group)
    group.add_argument(
        "--precision",
        choices=PRECISIONS,
        default="auto",
        help="arithmetic of SAM 2 / EdgeTAM: auto (bfloat16 autocast on CUDA, float32 "
        "elsewhere), float32, or bfloat16 (also on a CPU: about twice as fast where the CPU "
        "has native bfloat16, e.g. AVX512-BF16; the masks differ slightly from float32's)",
    )
    group.add_argument(
        "--amg",
        action="append",
        type=parse_option,
        default=[],
        metavar="KEY=VALUE",
        help="override an automatic-mask-generation setting of the paper, e.g. "
        "points_per_side=32 (repeatable)",
    )
    oracle = parser.add_argument_group("oracle imperfections (--model oracle)")
    oracle.add_argument(
        "--oracle-merge", type=probability, default=0.0, metavar="P",
        help="probability that an answer also takes the neighbour with the longest shared "
        "border (a negative click on it undoes that)",
    )
    oracle.add_argument(
        "--oracle-jitter", type=bounded_int(0), default=0, metavar="R",
        help="answers dilated or eroded by a random radius in [-R, R] pixels",
    )
    oracle.add_argument(
        "--oracle-seed", type=bounded_int(0), default=0, metavar="N",
        help="seed of the imperfections (each draw depends on the seed, view and prompt)",
    )


def oracle_options_from_args(args: argparse.Namespace) -> dict[str, Any] | None:
    """The oracle's imperfections asked for on the command line (None when none)."""
    options = {
        "merge_prob": float(getattr(args, "oracle_merge", 0.0) or 0.0),
        "boundary_jitter": int(getattr(args, "oracle_jitter", 0) or 0),
    }
    return options if any(options.values()) else None


def model_name_from_args(args: argparse.Namespace) -> str | None:
    """The model the options name: ``--model``; without it, ``transformers`` for a folder
    given with ``--checkpoint DIR`` (docs/design.md section 3.8), else the command's default
    (None where the command chooses itself, as ``lfsam demo`` does)."""
    from lfsam.segmenters.transformers.build import is_transformers_folder

    name = getattr(args, "model", None)
    given = name is not None and not isinstance(name, ModelNotGiven)
    if not given and is_transformers_folder(getattr(args, "checkpoint", None)):
        return TRANSFORMERS_FOLDER
    return None if name is None else str(name)


def model_options_from_args(args: argparse.Namespace) -> Any:
    """:class:`lfsam.api.ModelOptions` from the options of :func:`add_model_arguments`."""
    from lfsam.api import ModelOptions

    return ModelOptions(
        name=model_name_from_args(args) or DEFAULT_MODEL,
        checkpoint=getattr(args, "checkpoint", None),
        random_weights=bool(getattr(args, "random_weights", False)),
        device=getattr(args, "device", None),
        amg=dict(getattr(args, "amg", None) or []) or None,
        oracle=oracle_options_from_args(args),
        seed=int(getattr(args, "oracle_seed", 0) or getattr(args, "seed", 0) or 0),
        text_model=getattr(args, "text_model", None),
        text_checkpoint=getattr(args, "text_checkpoint", None),
        text_threshold=getattr(args, "text_threshold", None),
        precision=getattr(args, "precision", None) or "auto",
    )


def segmenter_from_args(
    args: argparse.Namespace, lightfield: LightField | None = None
) -> Segmenter:
    """The segmenter the options of :func:`add_model_arguments` ask for.

    Raises
    ------
    LfsamError
        With a one-line message, e.g. when weights are not cached and cannot be downloaded.
    """
    return model_options_from_args(args).build(lightfield)


def _row(spec: Any, cached: Any, kind: str, *, default: bool = False,
         checkpoint_file: str | None = None, image_size: int | None = None) -> dict[str, Any]:
    """One model's row of :func:`list_models` (``cached``: its file or folder in the cache)."""
    return {
        "name": spec.name,
        "default": default,
        "description": spec.description,
        "params": spec.params,
        "size_mb": round(spec.params * 4 / 1e6, 1),
        "image_size": spec.image_size if image_size is None else image_size,
        "hub_id": spec.hub_id,
        "checkpoint_file": checkpoint_file,
        "cached": None if cached is None else str(cached),
        "weights": "random only" if spec.random_only else ("cached" if cached else "not cached"),
        "kind": kind,
    }


def list_models() -> dict[str, Any]:
    """What ``lfsam models`` shows, as a JSON-ready dict (no network, no model built)."""
    from lfsam.segmenters.hub import cached_hub_folder, hub_cache_dir
    from lfsam.segmenters.sam2.build import autocast_dtype, cached_checkpoint
    from lfsam.segmenters.text.weights import cached_text_weights

    device = resolve_device(None)
    rows = []
    for spec in MODELS.values():
        cached = cached_checkpoint(spec.name)
        rows.append(_row(spec, cached, "sam2", default=spec.name == DEFAULT_MODEL,
                         checkpoint_file=spec.checkpoint_file))
    for hf_spec in TRANSFORMERS_MODELS.values():  # EdgeTAM (docs/design.md section 3.8)
        folder = None if hf_spec.hub_id is None else cached_hub_folder(hf_spec.hub_id)
        rows.append(_row(hf_spec, folder, "transformers"))
    for text_spec in TEXT_MODELS.values():  # --text-model (docs/design.md section 9)
        side = 1008 if text_spec.hub_id else TINY_SAM3_SIZES["image_size"]
        rows.append(_row(text_spec, cached_text_weights(text_spec.name), "text", image_size=side))
    rows.append(
        {
            "name": ORACLE,
            "default": False,
            "description": "ground-truth labels of the light field (upper bound)",
            "params": 0,
            "size_mb": 0.0,
            "image_size": None,
            "hub_id": None,
            "checkpoint_file": None,
            "cached": None,
            "weights": "needs labels",
            "kind": "oracle",
        }
    )
    dtype = autocast_dtype(device)
    return {
        "device": str(device),
        "precision": "bfloat16 autocast" if dtype is not None else "float32",
        "cache": str(hub_cache_dir()),
        "models": rows,
    }


def _table(info: dict[str, Any]) -> str:
    lines = [f"{'model':<24} {'params':>8} {'fp32':>8}  {'weights':<12} description"]
    for row in info["models"]:
        name = row["name"] + (" *" if row["default"] else "")
        params = f"{row['params'] / 1e6:.1f} M" if row["params"] else "-"
        mb = row["size_mb"]
        size = "-" if not mb else (f"{mb:.0f} MB" if mb >= 10 else f"{mb:.1f} MB")
        lines.append(f"{name:<24} {params:>8} {size:>8}  {row['weights']:<12} {row['description']}")
    lines += [
        "",
        f"* default (the paper's model). Device: {info['device']} ({info['precision']}).",
        f"Hugging Face cache: {info['cache']} (--json shows each cached file).",
        "Weights not cached download on first use or with `lfsam models --download NAME`;",
        "offline, fetch the .pt file from https://huggingface.co/facebook/NAME and pass "
        "--checkpoint FILE;",
        "edgetam: fetch https://huggingface.co/yonigozlan/EdgeTAM-hf and pass the folder with "
        "--checkpoint DIR.",
        "sam3 (--text-model) is gated: request access on https://huggingface.co/facebook/sam3",
        "and `hf auth login`, or pass a local copy with --text-checkpoint DIR.",
    ]
    return "\n".join(lines)


def check_download_target(name: str) -> None:
    """Before ``--download NAME`` fetches anything: weights not cached yet go into the
    Hugging Face cache, which must take files (one line naming it and ``HF_HUB_CACHE``).

    Raises
    ------
    LfsamError
        The cache folder cannot be created or written.
    """
    from lfsam.segmenters.hub import cached_hub_folder, hub_cache_dir
    from lfsam.segmenters.sam2.build import cached_checkpoint
    from lfsam.segmenters.text.weights import cached_text_weights

    if name in TRANSFORMERS_MODELS:
        cached = cached_hub_folder(TRANSFORMERS_MODELS[name].hub_id)
    elif name in TEXT_MODELS:
        cached = cached_text_weights(name)
    else:
        cached = cached_checkpoint(name)
    if cached is None:
        try:
            check_writable(hub_cache_dir(), folder=True, option="the Hugging Face cache",
                           inside=True)
        except LfsamError as exc:
            raise LfsamError(f"{exc}: the weights of {name} are downloaded there; set "
                             "HF_HUB_CACHE (or HF_HOME) to a folder you can write") from None


def run(args: argparse.Namespace) -> int:
    """Print the model table (or JSON), or download one model's weights (the cache checked
    for writing first)."""
    if args.download:
        from lfsam.segmenters.sam2.build import resolve_checkpoint

        if args.download != ORACLE:
            check_download_target(args.download)

        if args.download == ORACLE:
            raise LfsamError("the oracle has no weights; choose a SAM 2 model to download")
        if args.download in TRANSFORMERS_MODELS:
            from lfsam.segmenters.hub import download_hub_folder
            from lfsam.segmenters.transformers.build import how_to_provide

            spec = TRANSFORMERS_MODELS[args.download]
            folder = download_hub_folder(spec.hub_id, f"model {spec.name}", how_to_provide(spec))
            print(f"{args.download}: {folder}")
            return 0
        if args.download in TEXT_MODELS:
            from lfsam.segmenters.text.weights import resolve_text_weights

            print(f"{args.download}: {resolve_text_weights(args.download)}")
            return 0
        path = resolve_checkpoint(args.download)
        print(f"{args.download}: {path}")
        return 0
    info = list_models()
    print(json.dumps(info, indent=2) if args.json else _table(info))
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``models`` subcommand."""
    parser = subparsers.add_parser(
        "models",
        help="list segmenters, their sizes and cached weights",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=HelpFormatter,
    )
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.add_argument(
        "--download",
        metavar="NAME",
        choices=[
            *(name for name, spec in MODELS.items() if not spec.random_only),
            *(name for name, spec in TRANSFORMERS_MODELS.items() if not spec.random_only),
            *(name for name, spec in TEXT_MODELS.items() if not spec.random_only),
        ],
        help="download the weights of model NAME into the Hugging Face cache and print the path",
    )
    parser.set_defaults(func=run)
