"""Building SAM 2-family (and SAM) models from ``transformers`` checkpoints (docs/design.md
section 3.8).

The counterpart of :mod:`lfsam.segmenters.sam2.build` for models in Hugging Face format:
architecture, weights and device, separated from inference.

- ``edgetam``: the hub's transformers-format EdgeTAM, ``yonigozlan/EdgeTAM-hf``, downloaded once
  into the Hugging Face cache (offline: one line naming the model and how to provide it);
- ``edgetam-tiny-test``: EdgeTAM's classes (``EdgeTamModel``, a timm RepViT encoder) at a tiny
  size (:func:`tiny_edgetam_config`), random weights, for tests;
- any transformers-format folder (``config.json`` + ``*.safetensors``): its ``model_type``
  (``sam2``, ``edgetam``, or their ``_video`` checkpoints, whose image part is loaded; or
  ``sam``, SAM v1's ``SamModel``, also SlimSAM's and MedSAM's) picks the classes; memory weights
  of video checkpoints are not needed and not loaded.

``random_weights=True`` builds the architecture untrained and seeded (tests, speed). The model is
returned as :class:`lfsam.segmenters.transformers.model.TransformersImageModel`: the
``transformers`` image
encoder with SAM 2's heads in Meta's modules, the shape lfsam's SAM 2 code decodes with.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import torch

from lfsam.devices import resolve_device
from lfsam.errors import LfsamError
from lfsam.segmenters.hub import download_hub_folder, is_weights_folder
from lfsam.segmenters.registry import (
    MODELS,
    TRANSFORMERS_FOLDER,
    TRANSFORMERS_MODELS,
    TransformersModelSpec,
    model_family,
)

__all__ = [
    "MODEL_TYPES",
    "build_transformers_sam",
    "check_state_fits",
    "edgetam_config",
    "folder_family",
    "how_to_provide",
    "is_transformers_folder",
    "tiny_edgetam_config",
]

MODEL_TYPES: dict[str, str] = {
    "sam2": "sam2",
    "sam2_video": "sam2",
    "edgetam": "edgetam",
    "edgetam_video": "edgetam",
    "sam": "sam",
}
"""``config.json`` model types lfsam loads, and the family (classes) each one is built with."""

_HEAD_PREFIXES = ("vision_encoder.", "prompt_encoder.", "mask_decoder.", "shared_image_embedding.",
                  "no_memory_embedding")


def _repvit(architecture: str, **model_args: Any) -> Any:
    from transformers import TimmWrapperConfig

    args = {"in_chans": 3, "features_only": True, "out_indices": [0, 1, 2, 3], **model_args}
    return TimmWrapperConfig(architecture=architecture, model_args=args)


def edgetam_config() -> Any:
    """EdgeTAM's published image-model architecture (``EdgeTamConfig``): RepViT-M1 encoder
    (timm ``repvit_m1``, channels 48-384), FPN to 256 channels, SAM 2's heads, 1024-pixel input."""
    from transformers import EdgeTamConfig, EdgeTamVisionConfig

    return EdgeTamConfig(vision_config=EdgeTamVisionConfig(backbone_config=_repvit("repvit_m1")))


def tiny_edgetam_config(width: int = 32) -> Any:
    """A tiny EdgeTAM (0.1 M parameters at width 32, 256-pixel input) of the real classes
    (docs/design.md section 6): a RepViT of one block per stage (widths 8-64), FPN and SAM heads
    ``width`` wide (32: ``edgetam-tiny-test``; 128: a tiny video checkpoint ``transformers`` can
    save and load, :func:`lfsam.segmenters.transformers.video_build.tiny_edgetam_video_config`)."""
    from transformers import EdgeTamConfig, EdgeTamVisionConfig

    vision = EdgeTamVisionConfig(
        backbone_config=_repvit("repvit_m1", embed_dim=(8, 16, 32, 64), depth=(1, 1, 1, 1)),
        backbone_channel_list=[64, 32, 16, 8],
        backbone_feature_sizes=[[64, 64], [32, 32], [16, 16]],
        fpn_hidden_size=width,
    )
    return EdgeTamConfig(
        vision_config=vision,
        prompt_encoder_config={"hidden_size": width, "image_size": 256},
        mask_decoder_config={"hidden_size": width, "mlp_dim": 2 * width, "num_attention_heads": 2,
                             "iou_head_hidden_dim": width},
    )


def how_to_provide(spec: TransformersModelSpec) -> str:
    """The fix for weights that are not here (one clause)."""
    return (
        f"download https://huggingface.co/{spec.hub_id} (config.json and model.safetensors) "
        "and pass the folder with --checkpoint DIR, or run once with network access"
    )


def is_transformers_folder(checkpoint: str | os.PathLike | None) -> bool:
    """Whether ``checkpoint`` is a folder (a transformers-format checkpoint, not a .pt file)."""
    return checkpoint is not None and Path(checkpoint).expanduser().is_dir()


def _read_config(folder: Path) -> dict[str, Any]:
    if not is_weights_folder(folder):
        raise LfsamError(
            f"--checkpoint {str(folder)!r} is not a transformers-format model folder (config.json "
            "and *.safetensors); pass such a folder, or a SAM 2 .pt file"
        )
    try:
        config = json.loads((folder / "config.json").read_text())
    except (OSError, ValueError) as exc:
        raise LfsamError(
            f"{str(folder / 'config.json')!r} cannot be read ({exc}); download it again"
        ) from None
    if not isinstance(config, dict):
        raise LfsamError(f"{str(folder / 'config.json')!r} is not a model configuration")
    return config


def folder_family(folder: str | os.PathLike) -> str:
    """The family (``"sam2"``, ``"edgetam"`` or ``"sam"``) of a transformers-format folder, from the
    ``model_type`` of its ``config.json``.

    Raises
    ------
    LfsamError
        Not such a folder, or a model type lfsam does not segment with.
    """
    return _family_of(_read_config(Path(folder).expanduser()), folder)


def _family_of(config: dict[str, Any], folder: str | os.PathLike) -> str:
    """:func:`folder_family` of an already read ``config.json``."""
    model_type = str(config.get("model_type", ""))
    if model_type not in MODEL_TYPES:
        raise LfsamError(
            f"--checkpoint {str(folder)!r} holds a {model_type or 'untyped'!r} model; lfsam "
            f"segments with model types {', '.join(MODEL_TYPES)} (SAM 2, EdgeTAM and SAM)"
        )
    return MODEL_TYPES[model_type]


def _classes(family: str) -> tuple[type, type]:
    if family == "edgetam":
        from transformers import EdgeTamConfig, EdgeTamModel

        return EdgeTamConfig, EdgeTamModel
    if family == "sam":
        from transformers import SamConfig, SamModel

        return SamConfig, SamModel
    from transformers import Sam2Config, Sam2Model

    return Sam2Config, Sam2Model


def _image_config(family: str, config: dict[str, Any]) -> Any:
    """The image model's config from a folder's ``config.json`` (also of a video checkpoint)."""
    config_class, _ = _classes(family)
    parts = {key: config[key] for key in ("vision_config", "prompt_encoder_config",
                                           "mask_decoder_config") if key in config}
    try:
        return config_class(**parts)
    except (TypeError, ValueError, KeyError) as exc:
        raise LfsamError(f"the checkpoint's config.json does not describe a {family} model "
                         f"({' '.join(str(exc).split())[:120]})") from None


def _load_weights(model: torch.nn.Module, folder: Path, label: str) -> None:
    """Load the image model's weights from the folder's safetensors (memory weights ignored)."""
    from safetensors import SafetensorError
    from safetensors.torch import load_file

    state: dict[str, torch.Tensor] = {}
    for path in sorted(folder.glob("*.safetensors")):
        try:
            state.update(load_file(str(path)))
        except (OSError, SafetensorError) as exc:
            raise LfsamError(
                f"{str(path)!r} cannot be read ({' '.join(str(exc).split())[:100]}); it is "
                "corrupt or incomplete: download it again"
            ) from None
    expected = model.state_dict()
    state = {k: v for k, v in state.items() if k in expected or k.startswith(_HEAD_PREFIXES)}
    tied = getattr(model, "_tied_weights_keys", None)  # SamModel saves its tied matrix once
    for key, source in (tied.items() if isinstance(tied, dict) else ()):
        if key not in state and source in state:
            state[key] = state[source]
    check_state_fits(state, expected, [k for k in state if k not in expected],
                     f"the weights in {str(folder)!r} do not fit {label}")
    model.load_state_dict(state, strict=True)


def check_state_fits(found: dict, wanted: dict, unexpected: list[str], what: str) -> None:
    """Raise one line unless ``found`` holds every key of ``wanted`` with its shape and
    ``unexpected`` is empty; ``what`` opens the message ("the weights in 'DIR' do not fit X").

    Raises
    ------
    LfsamError
        Counting the missing, unexpected and differently shaped parameters, with an example.
    """
    missing = [k for k in wanted if k not in found]
    shaped = [k for k in wanted if k in found and found[k].shape != wanted[k].shape]
    if missing or unexpected or shaped:
        example = (missing or unexpected or shaped)[0]
        raise LfsamError(
            f"{what} ({len(missing)} missing, {len(unexpected)} unexpected, {len(shaped)} "
            f"differently shaped parameters, e.g. {example!r}); pass the folder a transformers "
            "save_pretrained wrote for this model"
        )


def _require_packages(name: str) -> None:
    """One line naming what to install when ``transformers`` or ``timm`` is missing."""
    import importlib.util

    missing = [p for p in ("transformers", "timm") if importlib.util.find_spec(p) is None]
    if missing:
        raise LfsamError(
            f"--model {name} runs on Hugging Face {' and '.join(missing)}, which this "
            "installation lacks; install them with `pip install 'lfsam[edgetam]'` (make install "
            "does)"
        )


def _random_model(family: str, config: Any, seed: int) -> torch.nn.Module:
    _, model_class = _classes(family)
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        model = model_class(config)
    with torch.no_grad():  # SAM has one positional matrix for the image and the prompts
        shared = model.shared_image_embedding.positional_embedding
        model.prompt_encoder.shared_embedding.positional_embedding.copy_(shared)
    return model


def build_transformers_sam(
    name: str,
    checkpoint: str | os.PathLike | None = None,
    random_weights: bool = False,
    device: str | torch.device | None = None,
    *,
    seed: int = 0,
) -> torch.nn.Module:
    """Build a SAM 2-family image model from ``transformers`` (eval mode, on ``device``).

    Parameters
    ----------
    name : str
        A name of :data:`lfsam.segmenters.registry.TRANSFORMERS_MODELS`, ``"transformers"``
        (any folder), or a Meta SAM 2 name together with a transformers-format SAM 2 folder.
    checkpoint : path, optional
        A transformers-format folder (``config.json`` + ``*.safetensors``); its model type must
        fit ``name``'s family. Default: the hub's copy (cached, or downloaded once).
    random_weights : bool
        The architecture untrained (tests and speed only); implied for models without published
        weights.
    device : str or torch.device, optional
        Default ``auto``.
    seed : int
        Seed of random weights.

    Returns
    -------
    TransformersImageModel
        With ``lfsam_info`` (name, hub_id, checkpoint, model_type, random_weights, seed, params,
        image_size).

    Raises
    ------
    LfsamError
        Unknown name, a folder of another family or model type, weights that do not fit, or no
        weights to be had (one line with the fix).
    """
    from lfsam.segmenters.transformers.model import TransformersImageModel

    _require_packages(name)
    dev = resolve_device(device)
    spec = TRANSFORMERS_MODELS.get(name)
    if spec is None and name != TRANSFORMERS_FOLDER and name not in MODELS:
        known = ", ".join([*TRANSFORMERS_MODELS, TRANSFORMERS_FOLDER])
        raise LfsamError(f"unknown transformers model {name!r}; choose one of: {known}")
    folder: Path | None = None
    if checkpoint is not None:
        folder = Path(checkpoint).expanduser()
        folder_config = _read_config(folder)
        family = _family_of(folder_config, folder)
        wanted = model_family(name)
        if wanted is not None and wanted != family:
            raise LfsamError(
                f"--checkpoint {str(folder)!r} holds a {family} model, not {name} ({wanted}); "
                "leave out --model (the folder's config.json names the model) or pass a "
                f"{wanted} folder"
            )
        config = _image_config(family, folder_config)
    elif spec is None:
        raise LfsamError(
            f"the model {name!r} takes its architecture and weights from a transformers-format "
            "folder (config.json + *.safetensors): give it with --checkpoint DIR (in the "
            "viewer: Weights > folder…)"
        )
    else:
        family = spec.model_type
        config = tiny_edgetam_config() if spec.random_only else edgetam_config()
        if not (random_weights or spec.random_only):
            folder = download_hub_folder(spec.hub_id, f"model {name}", how_to_provide(spec))
            config = _image_config(family, _read_config(folder))
    if folder is not None and random_weights:
        raise LfsamError("--random-weights builds an untrained model; drop it or --checkpoint")
    random = folder is None
    model = _random_model(family, config, seed)
    if folder is not None:
        _load_weights(model, folder, name)
    info = {
        "name": name if name != TRANSFORMERS_FOLDER or folder is None else folder.name,
        "hub_id": None if spec is None else spec.hub_id,
        "checkpoint": None if folder is None else str(folder),
        "model_type": family,
        "random_weights": random,
        "seed": seed if random else None,
    }
    return TransformersImageModel(model.eval(), info).to(dev).eval()
