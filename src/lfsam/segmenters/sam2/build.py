"""Building SAM 2 models: architecture, weights and device, separated from inference.

This mirrors Meta's ``sam2.build_sam`` (hydra config -> model classes -> checkpoint -> device) and
uses it for the architecture, adding what lfsam needs around it:

- model names from :mod:`lfsam.segmenters.registry` instead of config paths;
- weights from a checkpoint file, or from the model hub (``facebook/<name>``) downloaded once into
  the standard Hugging Face cache; offline or unreachable hub -> one-line :class:`LfsamError` that
  says how to provide the file, raised at once (no 20-second retry loop, no partial files);
- ``random_weights=True``: the same architecture untrained, seeded (tests and speed benchmarks);
- the tiny test model (``sam2-tiny-test``, docs/design.md section 6);
- the device (:func:`lfsam.devices.resolve_device`, re-exported here) and bf16 autocast on CUDA
  (:func:`inference_context`).

:func:`build_sam2` gives the image model (``SAM2Base``) used by
:class:`lfsam.segmenters.sam2.backend.Sam2Segmenter`; :func:`build_sam2_video` gives Meta's
``SAM2VideoPredictor`` for the video-tracking baseline (paper section 4).
"""

from __future__ import annotations

import contextlib
import os
import pickle
import warnings
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import torch

from lfsam.devices import resolve_device
from lfsam.errors import LfsamError
from lfsam.segmenters.hub import HUB_TIMEOUT_S, hub_cache_dir, hub_offline, hub_reachable
from lfsam.segmenters.registry import DEFAULT_MODEL, ModelSpec, get_model_spec

__all__ = [
    "PRECISIONS",
    "build_sam2",
    "build_sam2_video",
    "cached_checkpoint",
    "inference_context",
    "load_checkpoint",
    "make_image_predictor",
    "precision_dtype",
    "resolve_checkpoint",
    "resolve_device",
]



# --- device ---------------------------------------------------------------------------------
def autocast_dtype(device: torch.device) -> torch.dtype | None:
    """The autocast dtype used on ``device``: bfloat16 on CUDA GPUs that support it, else None.

    SAM 2's own examples run under ``torch.autocast("cuda", dtype=torch.bfloat16)``; on CPU and MPS
    lfsam runs in float32.
    """
    if device.type == "cuda" and torch.cuda.is_bf16_supported():
        return torch.bfloat16
    return None


PRECISIONS = ("auto", "float32", "bfloat16")
"""``--precision``: ``auto`` (bfloat16 autocast on CUDA GPUs that have it, else float32),
``float32``, or ``bfloat16`` autocast anywhere (on a CPU with native bfloat16, e.g. AVX512-BF16
or AMX, about twice as fast for EdgeTAM's encoder; docs/performance.md)."""


def precision_dtype(device: torch.device, precision: str = "auto") -> torch.dtype | None:
    """The autocast dtype of ``precision`` on ``device`` (None: float32, no autocast).

    Raises
    ------
    LfsamError
        An unknown precision.
    """
    if precision == "auto":
        return autocast_dtype(device)
    if precision == "float32":
        return None
    if precision == "bfloat16":
        return torch.bfloat16
    raise LfsamError(f"--precision {precision}: unknown; use one of {', '.join(PRECISIONS)}")


@contextlib.contextmanager
def inference_context(
    device: torch.device, *, inference_mode: bool = True, precision: str = "auto"
) -> Iterator[None]:
    """No autograd, plus bf16 autocast on CUDA (as in SAM 2's examples), or as ``precision``
    says (:func:`precision_dtype`).

    Parameters
    ----------
    device : torch.device
        The model's device.
    inference_mode : bool
        Use ``torch.inference_mode`` (fastest; tensors made inside cannot be modified in place
        outside it) or ``torch.no_grad`` (for tensors handed back to callers).
    precision : {"auto", "float32", "bfloat16"}
        The arithmetic (:data:`PRECISIONS`).
    """
    grad_off = torch.inference_mode() if inference_mode else torch.no_grad()
    dtype = precision_dtype(device, precision)
    with grad_off:
        if dtype is None:
            yield
        else:
            with torch.autocast(device.type, dtype=dtype):
                yield


# --- weights --------------------------------------------------------------------------------
def cached_checkpoint(name: str) -> Path | None:
    """The cached checkpoint of model ``name`` in the hub cache, or None (never uses the network).

    Raises
    ------
    LfsamError
        If ``name`` is unknown.
    """
    spec = get_model_spec(name)
    if spec.hub_id is None or spec.checkpoint_file is None:
        return None
    from huggingface_hub import try_to_load_from_cache

    found = try_to_load_from_cache(
        spec.hub_id, spec.checkpoint_file, cache_dir=str(hub_cache_dir())
    )
    return Path(found) if isinstance(found, str) and Path(found).is_file() else None


def _how_to_provide(spec: ModelSpec) -> str:
    return (
        f"download {spec.checkpoint_file} from https://huggingface.co/{spec.hub_id} and pass "
        "--checkpoint FILE, or run once with network access"
    )


def resolve_checkpoint(
    name: str, checkpoint: str | os.PathLike | None = None, *, timeout: float = HUB_TIMEOUT_S
) -> Path:
    """The checkpoint file to load for model ``name``: the given file, the cache, or a download.

    Parameters
    ----------
    name : str
        Model name (see :data:`lfsam.segmenters.registry.MODELS`).
    checkpoint : path, optional
        A local checkpoint file; used as is (only checked to exist).
    timeout : float
        Seconds to wait for the model hub before giving up.

    Returns
    -------
    path : Path
        An existing file.

    Raises
    ------
    LfsamError
        If the file does not exist, the model has no published weights, or the weights are not
        cached and cannot be downloaded (offline, hub unreachable, download failed). Fails within
        about ``timeout`` seconds; a failed download leaves no file where lfsam looks for it.
    """
    spec = get_model_spec(name)
    if checkpoint is not None:
        path = Path(checkpoint).expanduser()
        if not path.is_file():
            raise LfsamError(
                f"checkpoint file {str(path)!r} not found; pass the path of a SAM 2 .pt file "
                f"(for {name}: {spec.checkpoint_file or 'a state dict saved by lfsam'})"
            )
        return path
    if spec.random_only:
        raise LfsamError(
            f"model {name} has no published weights; use random weights (--random-weights) "
            "or pass --checkpoint FILE"
        )
    cached = cached_checkpoint(name)
    if cached is not None:
        return cached
    if hub_offline():
        raise LfsamError(
            f"no cached weights for {name} and downloads are off (HF_HUB_OFFLINE is set); "
            + _how_to_provide(spec)
        )
    if not hub_reachable(timeout):
        raise LfsamError(
            f"no cached weights for {name} and the model hub cannot be reached; "
            + _how_to_provide(spec)
        )
    from huggingface_hub import hf_hub_download

    try:
        found = hf_hub_download(
            spec.hub_id,
            spec.checkpoint_file,
            cache_dir=str(hub_cache_dir()),
            etag_timeout=timeout,
        )
    except Exception as exc:  # any hub or network failure is the user's environment
        reason = " ".join(str(exc).split())[:160] or type(exc).__name__
        raise LfsamError(
            f"downloading {spec.checkpoint_file} for {name} failed ({reason}); "
            + _how_to_provide(spec)
        ) from None
    return Path(found)


def load_checkpoint(model: torch.nn.Module, path: str | os.PathLike, name: str = "") -> None:
    """Load a SAM 2 checkpoint (``{"model": state_dict}``, as Meta ships them) into ``model``.

    Parameters
    ----------
    model : torch.nn.Module
        A freshly built SAM 2 model (on CPU).
    path : path
        The checkpoint file.
    name : str
        The model's name, for messages.

    Raises
    ------
    LfsamError
        If the file is missing, unreadable or corrupt, is not a SAM 2 checkpoint, or does not fit
        the model (missing, unexpected or differently shaped parameters).
    """
    path = Path(path)
    label = name or "this model"
    if not path.is_file():
        raise LfsamError(f"checkpoint file {str(path)!r} not found; pass an existing .pt file")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except (
        OSError,
        EOFError,
        RuntimeError,
        ValueError,
        pickle.UnpicklingError,
        zipfile.BadZipFile,
    ) as exc:
        reason = " ".join(str(exc).split())[:120] or type(exc).__name__
        raise LfsamError(
            f"checkpoint {str(path)!r} cannot be read ({reason}); it is corrupt or not a "
            "PyTorch file: download it again"
        ) from None
    state = payload.get("model") if isinstance(payload, dict) else None
    if not isinstance(state, dict):
        raise LfsamError(
            f"checkpoint {str(path)!r} is not a SAM 2 checkpoint (no 'model' state dict); "
            "pass a file from https://huggingface.co/facebook (e.g. sam2.1_hiera_small.pt)"
        )
    expected = model.state_dict()
    missing = [k for k in expected if k not in state]
    unexpected = [k for k in state if k not in expected]
    shape_diff = [
        k
        for k in expected
        if k in state
        and isinstance(state[k], torch.Tensor)
        and tuple(state[k].shape) != tuple(expected[k].shape)
    ]
    if missing or unexpected or shape_diff:
        example = (missing or unexpected or shape_diff)[0]
        raise LfsamError(
            f"checkpoint {str(path)!r} does not fit {label} ({len(missing)} missing, "
            f"{len(unexpected)} unexpected, {len(shape_diff)} differently shaped parameters, "
            f"e.g. {example!r}); pass the checkpoint made for {label} or choose the --model "
            "this checkpoint belongs to"
        )
    model.load_state_dict(state, strict=True)


# --- construction ---------------------------------------------------------------------------
def _compose(spec: ModelSpec, extra: list[str]) -> Any:
    """Compose the hydra config of ``spec`` (with its overrides) from the ``sam2`` package."""
    import sam2  # noqa: F401  (initialises hydra with sam2's config module)
    from hydra import compose, initialize_config_module
    from hydra.core.global_hydra import GlobalHydra
    from omegaconf import OmegaConf

    if not GlobalHydra.instance().is_initialized():
        initialize_config_module("sam2", version_base="1.2")
    cfg = compose(config_name=spec.config, overrides=[*spec.overrides, *extra])
    OmegaConf.resolve(cfg)
    return cfg


# Post-processing switches of sam2.build_sam (dynamic multimask fallback; for video also
# binarised click masks in memory and hole filling), applied as there.
_IMAGE_POSTPROCESSING = [
    "++model.sam_mask_decoder_extra_args.dynamic_multimask_via_stability=true",
    "++model.sam_mask_decoder_extra_args.dynamic_multimask_stability_delta=0.05",
    "++model.sam_mask_decoder_extra_args.dynamic_multimask_stability_thresh=0.98",
]
_VIDEO_EXTRA = [
    "++model._target_=sam2.sam2_video_predictor.SAM2VideoPredictor",
    *_IMAGE_POSTPROCESSING,
    "++model.binarize_mask_from_pts_for_mem_enc=true",
    "++model.fill_hole_area=8",
]


def _build(
    name: str,
    extra: list[str],
    checkpoint: str | os.PathLike | None,
    random_weights: bool,
    device: str | torch.device | None,
    seed: int,
) -> torch.nn.Module:
    from hydra.utils import instantiate

    spec = get_model_spec(name)
    dev = resolve_device(device)
    random_weights = bool(random_weights) or (spec.random_only and checkpoint is None)
    if random_weights and checkpoint is not None:
        raise LfsamError("give either --checkpoint or --random-weights, not both")
    path = None if random_weights else resolve_checkpoint(name, checkpoint)
    cfg = _compose(spec, extra)
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        model = instantiate(cfg.model, _recursive_=True)
    if path is not None:
        load_checkpoint(model, path, name)
    model = model.to(dev).eval()
    model.lfsam_info = {
        "name": name,
        "hub_id": spec.hub_id,
        "checkpoint": None if path is None else str(path),
        "random_weights": random_weights,
        "seed": seed if random_weights else None,
        "params": sum(p.numel() for p in model.parameters()),
        "image_size": int(model.image_size),
    }
    return model


def build_sam2(
    name: str = DEFAULT_MODEL,
    checkpoint: str | os.PathLike | None = None,
    random_weights: bool = False,
    device: str | torch.device | None = None,
    *,
    seed: int = 0,
) -> torch.nn.Module:
    """Build a SAM 2 image model (``sam2.modeling.sam2_base.SAM2Base``) in eval mode.

    Parameters
    ----------
    name : str
        A name from :data:`lfsam.segmenters.registry.MODELS`; default the paper's
        ``sam2.1-hiera-small``.
    checkpoint : path, optional
        Weights file in SAM 2's format (``{"model": state_dict}``). Without it the weights come
        from the hub cache, downloaded once if needed.
    random_weights : bool
        Build the architecture untrained (for tests and speed benchmarks only; the masks are
        meaningless). Implied for models without published weights (``sam2-tiny-test``) when no
        checkpoint is given.
    device : str or torch.device, optional
        Default ``auto``: CUDA, then MPS, then CPU (:func:`lfsam.devices.resolve_device`).
    seed : int
        Seed of the random initialisation (the result is deterministic per seed).

    Returns
    -------
    model : SAM2Base
        With ``model.lfsam_info``, a dict: name, hub_id, checkpoint, random_weights, seed, params,
        image_size.

    Raises
    ------
    LfsamError
        Unknown name or device, or no weights can be had (see :func:`resolve_checkpoint` and
        :func:`load_checkpoint`).
    """
    return _build(name, list(_IMAGE_POSTPROCESSING), checkpoint, random_weights, device, seed)


def build_sam2_video(
    name: str = DEFAULT_MODEL,
    checkpoint: str | os.PathLike | None = None,
    random_weights: bool = False,
    device: str | torch.device | None = None,
    *,
    seed: int = 0,
) -> torch.nn.Module:
    """Build Meta's ``SAM2VideoPredictor`` (video tracking; the paper's baseline, section 4).

    Same arguments, weights and errors as :func:`build_sam2`, with the post-processing settings of
    ``sam2.build_sam.build_sam2_video_predictor``. Use it under :func:`inference_context` as
    ``init_state`` / ``add_new_points_or_box`` / ``propagate_in_video``.
    """
    return _build(name, list(_VIDEO_EXTRA), checkpoint, random_weights, device, seed)


def make_image_predictor(
    model: torch.nn.Module, predictor_class: type | None = None, **kwargs: Any
) -> Any:
    """A ``SAM2ImagePredictor`` for ``model`` whose backbone feature sizes fit its input size.

    ``SAM2ImagePredictor`` hard-codes the feature sizes of a 1024-pixel input; they are
    image_size / 4, / 8 and / 16 (docs/design.md section 6).

    Parameters
    ----------
    model : SAM2Base
    predictor_class : type, optional
        ``SAM2ImagePredictor`` or a subclass (default the former).
    **kwargs
        Passed to the predictor (``mask_threshold``, ``max_hole_area``, ...).
    """
    from sam2.sam2_image_predictor import SAM2ImagePredictor

    from lfsam.segmenters.sam2.adapter import fit_feature_sizes

    with warnings.catch_warnings():  # SAM2Transforms uses torch.jit.script (deprecated)
        warnings.filterwarnings("ignore", message=".*torch.jit.script.*", category=FutureWarning)
        predictor = (predictor_class or SAM2ImagePredictor)(model, **kwargs)
    fit_feature_sizes(predictor, int(model.image_size))
    return predictor
