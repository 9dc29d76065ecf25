"""The video model (memory) of a ``transformers`` SAM 2 / EdgeTAM segmenter (docs/design.md
section 10).

:func:`video_model_for` builds ``transformers``' ``EdgeTamVideoModel`` (or ``Sam2VideoModel``) for
an image model of :func:`lfsam.segmenters.transformers.build.build_transformers_sam`: its memory
modules
(memory attention, memory encoder, EdgeTAM's spatial perceiver, object-pointer heads, temporal
encodings) come from the same checkpoint folder, and its vision encoder, prompt encoder, mask
decoder, Fourier matrix and no-memory embedding *are* the image model's modules (shared, not
copied), so the memory's masks and the light-field pipeline's embeddings come from the same
weights and one encoder pass serves both.

- a folder whose ``config.json`` has ``model_type`` ``edgetam_video`` / ``sam2_video`` (the hub's
  ``yonigozlan/EdgeTAM-hf`` is one): its memory weights are loaded (all of them, and only them);
- an image-only folder (``edgetam`` / ``sam2``) has none: one line naming the folder and the fix;
- random weights (``edgetam-tiny-test``, ``--random-weights``): the memory of
  :func:`tiny_edgetam_video_config` / :func:`edgetam_video_config`, seeded with the image model's
  seed;
- SAM v1 (``sam``) has no memory.
"""

from __future__ import annotations

import weakref
from pathlib import Path
from typing import Any

import torch
from torch import nn

from lfsam.errors import LfsamError
from lfsam.segmenters.registry import TRANSFORMERS_MODELS
from lfsam.segmenters.transformers.build import (
    _read_config,
    check_state_fits,
    edgetam_config,
    tiny_edgetam_config,
)

__all__ = [
    "SHARED_MODULES",
    "VIDEO_MODEL_TYPES",
    "edgetam_video_config",
    "session_class",
    "tiny_edgetam_video_config",
    "video_memory_problem",
    "video_model_for",
]

VIDEO_MODEL_TYPES: dict[str, str] = {"edgetam": "edgetam_video", "sam2": "sam2_video"}
"""The ``model_type`` of the video checkpoint of each family that has a memory."""

SHARED_MODULES = ("vision_encoder", "prompt_encoder", "mask_decoder", "shared_image_embedding",
                  "no_memory_embedding")
"""Attributes of the video model that are the image model's own modules (same weights)."""

_BUILT: weakref.WeakKeyDictionary[nn.Module, nn.Module] = weakref.WeakKeyDictionary()


def _video_classes(family: str) -> tuple[type, type]:
    if family == "edgetam":
        from transformers import EdgeTamVideoConfig, EdgeTamVideoModel

        return EdgeTamVideoConfig, EdgeTamVideoModel
    from transformers import Sam2VideoConfig, Sam2VideoModel

    return Sam2VideoConfig, Sam2VideoModel


def session_class(video_model: nn.Module) -> type:
    """The inference-session class of a video model (``EdgeTamVideoInferenceSession`` or
    ``Sam2VideoInferenceSession``)."""
    if video_model.config.model_type == "edgetam_video":
        from transformers.models.edgetam_video.modeling_edgetam_video import (
            EdgeTamVideoInferenceSession,
        )

        return EdgeTamVideoInferenceSession
    from transformers.models.sam2_video.modeling_sam2_video import Sam2VideoInferenceSession

    return Sam2VideoInferenceSession


def _video_config(image_config: Any, **memory: Any) -> Any:
    """An ``EdgeTamVideoConfig`` whose image parts are ``image_config``'s."""
    from transformers import EdgeTamVideoConfig

    return EdgeTamVideoConfig(
        vision_config=image_config.vision_config,
        prompt_encoder_config=image_config.prompt_encoder_config.to_dict(),
        mask_decoder_config=image_config.mask_decoder_config.to_dict(),
        image_size=int(image_config.prompt_encoder_config.image_size),
        **memory,
    )


def edgetam_video_config() -> Any:
    """EdgeTAM's published video architecture (``EdgeTamVideoConfig``): the image model of
    :func:`~lfsam.segmenters.transformers.build.edgetam_config` and ``transformers``' default
    memory (7
    memory frames, 16 object pointers, 2 memory-attention layers, a spatial perceiver of 256 + 256
    latents, 64-channel memories)."""
    return _video_config(edgetam_config())


def tiny_edgetam_video_config(width: int = 32) -> Any:
    """A tiny EdgeTAM video model: the image model of
    :func:`~lfsam.segmenters.transformers.build.tiny_edgetam_config` (``width`` wide, 256-pixel
    input,
    16 x 16 feature map) and a memory: one memory-attention layer ``width`` wide,
    ``width / 2``-channel memories (``transformers`` splits each object pointer into memory-wide
    tokens: the memories must be narrower than the heads), a perceiver of 16 + 16 latents (a
    4 x 4 grid), the published frame counts (7 memory frames, 16 object pointers).
    ``width=32`` is ``edgetam-tiny-test``'s memory. ``transformers`` fixes the memory attention's
    key width at 64, so at any other width :func:`video_model_for` rebuilds those projections for
    the narrower memories; a checkpoint written with ``save_pretrained`` loads back only at
    ``width=128`` (64-channel memories)."""
    memory = width // 2
    return _video_config(
        tiny_edgetam_config(width),
        memory_attention_hidden_size=width, memory_attention_num_layers=1,
        memory_attention_mlp_hidden_size=2 * width, memory_attention_rope_feat_sizes=[16, 16],
        memory_attention_rope_k_sizes=[4, 4],
        perceiver_resampler_num_latents=16, perceiver_resampler_num_latents_2d=16,
        perceiver_resampler_hidden_size=memory, perceiver_resampler_mlp_intermediate_size=width,
        perceiver_resampler_attention_head_dim=memory, perceiver_resampler_num_layers=1,
        memory_encoder_hidden_size=width, memory_encoder_output_channels=memory,
        mask_downsampler_embed_dim=width, memory_fuser_embed_dim=width,
        memory_fuser_intermediate_dim=2 * width, memory_fuser_num_layers=1,
    )


_KEY_WIDTH = 64
"""The memory attention's key (memory) width ``transformers`` builds whatever the config says."""


def _fit_key_width(video: nn.Module) -> None:
    """Rebuild the memory attention's cross-attention for the config's memory width where it
    differs from the fixed 64 (the tiny memory; seeded by the caller)."""
    width = int(video.config.memory_encoder_output_channels)
    if width == _KEY_WIDTH:
        return
    for layer in video.memory_attention.layers:
        layer.cross_attn_image = type(layer.cross_attn_image)(video.config, kv_in_dim=width)


def _folder(info: dict[str, Any]) -> Path | None:
    checkpoint = info.get("checkpoint")
    return None if checkpoint is None else Path(checkpoint).expanduser()


def video_memory_problem(image_model: nn.Module) -> str | None:
    """Why lfsam cannot build a video memory for ``image_model`` (one line with the fix), or None.

    Parameters
    ----------
    image_model : TransformersImageModel
        From :func:`~lfsam.segmenters.transformers.build.build_transformers_sam` (its
        ``lfsam_info`` names
        the family, the checkpoint folder and whether the weights are random).
    """
    info = dict(getattr(image_model, "lfsam_info", {}) or {})
    family, name = info.get("model_type"), info.get("name")
    if family not in VIDEO_MODEL_TYPES:
        return (f"the {name!r} model ({family}) has no video memory; track with --tracking "
                "prompts, or use a SAM 2 or EdgeTAM model")
    folder = _folder(info)
    if folder is None:
        if family != "edgetam" or name not in TRANSFORMERS_MODELS:
            return (f"lfsam knows no random-weights video architecture for {name!r}; give a "
                    "video checkpoint folder with --checkpoint DIR, or use --tracking prompts")
        return None
    try:
        model_type = str(_read_config(folder).get("model_type", ""))
    except LfsamError as exc:
        return str(exc)
    video_type = VIDEO_MODEL_TYPES[family]
    if model_type != video_type:
        return (f"--checkpoint {str(folder)!r} is an image-only {family} model (model type "
                f"{model_type!r}) without memory weights; --tracking memory needs a video "
                f"checkpoint (model type {video_type!r}), or use --tracking prompts")
    return None


def _load_memory_weights(video: nn.Module, folder: Path) -> None:
    """Load every memory weight (all but :data:`SHARED_MODULES`) from the folder's
    safetensors; the shared modules already hold the image model's weights."""
    from safetensors import SafetensorError, safe_open

    wanted = {k: v for k, v in video.state_dict().items()
              if not k.startswith(SHARED_MODULES)}
    found: dict[str, torch.Tensor] = {}
    unexpected: list[str] = []
    for path in sorted(folder.glob("*.safetensors")):
        try:
            with safe_open(str(path), framework="pt") as handle:
                for key in handle.keys():
                    if key in wanted:
                        found[key] = handle.get_tensor(key)
                    elif not key.startswith(SHARED_MODULES):
                        unexpected.append(key)
        except (OSError, SafetensorError) as exc:
            raise LfsamError(
                f"{str(path)!r} cannot be read ({' '.join(str(exc).split())[:100]}); it is "
                "corrupt or incomplete: download it again"
            ) from None
    check_state_fits(found, wanted, unexpected,
                     f"the memory weights in {str(folder)!r} do not fit its config.json")
    video.load_state_dict(found, strict=False)


def _score_shape_fix(video: nn.Module) -> None:
    """Give the object score of a mask-conditioned object the shape of a tracked one.

    ``EdgeTamVideoModel._use_mask_as_output`` returns it one dimension short (``(1, 1)``;
    ``Sam2VideoModel``'s adds the dimension: ``(1, 1, 1)``), so a frame where one object is
    conditioned on a mask (``add_mask``) while another is tracked fails to concatenate the two.
    Wrapped on this instance; a no-op where the shapes already agree.
    """
    original = video._use_mask_as_output

    def use_mask_as_output(*args: Any, **kwargs: Any) -> Any:
        out = original(*args, **kwargs)
        if out.object_score_logits.dim() == 2:
            out.object_score_logits = out.object_score_logits.unsqueeze(-1)
        return out

    video._use_mask_as_output = use_mask_as_output


def _new_video_model(image_model: nn.Module, info: dict[str, Any]) -> nn.Module:
    family = str(info["model_type"])
    folder = _folder(info)
    config_class, model_class = _video_classes(family)
    if folder is None:
        spec = TRANSFORMERS_MODELS[str(info["name"])]
        config = tiny_edgetam_video_config() if spec.random_only else edgetam_video_config()
    else:
        try:
            config = config_class.from_pretrained(str(folder))
        except (OSError, TypeError, ValueError, KeyError) as exc:
            raise LfsamError(f"{str(folder / 'config.json')!r} does not describe a "
                             f"{family} video model ({' '.join(str(exc).split())[:120]})"
                             ) from None
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(int(info.get("seed") or 0))
        video = model_class(config)
        if folder is None:
            _fit_key_width(video)
    hf_model = image_model.hf_model
    for name in SHARED_MODULES:  # the image model's modules themselves: same weights, no copy
        setattr(video, name, getattr(hf_model, name))
    if folder is not None:
        _load_memory_weights(video, folder)
    _score_shape_fix(video)
    return video.to(image_model.device).eval()


def video_model_for(image_model: nn.Module) -> nn.Module:
    """The ``EdgeTamVideoModel`` / ``Sam2VideoModel`` of a transformers image model, built once
    per image model (cached) and sharing its image-side modules (:data:`SHARED_MODULES`).

    Parameters
    ----------
    image_model : TransformersImageModel
        A SAM 2-family image model of
        :func:`~lfsam.segmenters.transformers.build.build_transformers_sam`.

    Returns
    -------
    nn.Module
        In eval mode on the image model's device.

    Raises
    ------
    LfsamError
        :func:`video_memory_problem`'s line, or memory weights that cannot be read or do not
        fit.
    """
    cached = _BUILT.get(image_model)
    if cached is not None:
        return cached
    problem = video_memory_problem(image_model)
    if problem is not None:
        raise LfsamError(problem)
    video = _new_video_model(image_model, dict(image_model.lfsam_info))
    _BUILT[image_model] = video
    return video

