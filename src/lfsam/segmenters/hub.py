"""The model hub: its cache folder, whether downloads are allowed and the hub answers, and model
folders in ``transformers`` format (``config.json`` + ``*.safetensors``) from it, with SAM 2's
offline-safe rules (docs/design.md section 6). Shared by every model family's weights.

A local copy of a repository, else the Hugging Face cache, else one download; where the weights
cannot be had (downloads off, hub unreachable, access not granted) the error is one line with
the fix, raised at once (no retry loop). Used by the text detectors (SAM 3) and by the
``transformers`` segmenters (EdgeTAM).
"""

from __future__ import annotations

import os
import socket
from pathlib import Path
from urllib.parse import urlparse

from lfsam.errors import LfsamError

__all__ = [
    "HUB_TIMEOUT_S",
    "cached_hub_folder",
    "download_hub_folder",
    "hub_cache_dir",
    "hub_offline",
    "hub_reachable",
    "is_weights_folder",
]

HUB_TIMEOUT_S = 3.0
"""Seconds to wait for the model hub before declaring it unreachable."""

_TRUE = {"1", "on", "yes", "true"}

_PATTERNS = ["*.json", "*.safetensors", "*.txt", "*.model"]


def hub_cache_dir() -> Path:
    """The Hugging Face hub cache folder, read from the environment at call time.

    Same rule as ``huggingface_hub.constants``: ``HF_HUB_CACHE``, else ``HUGGINGFACE_HUB_CACHE``,
    else ``$HF_HOME/hub``, else ``$XDG_CACHE_HOME/huggingface/hub``, else
    ``~/.cache/huggingface/hub``. Read here rather than from ``huggingface_hub.constants``, which
    freezes the environment at import time.
    """
    explicit = os.environ.get("HF_HUB_CACHE") or os.environ.get("HUGGINGFACE_HUB_CACHE")
    if explicit:
        return Path(os.path.expandvars(os.path.expanduser(explicit)))
    home = os.environ.get("HF_HOME") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"),
        "huggingface",
    )
    return Path(os.path.expandvars(os.path.expanduser(home))) / "hub"


def hub_offline() -> bool:
    """Whether downloads are switched off (``HF_HUB_OFFLINE`` or ``TRANSFORMERS_OFFLINE``)."""
    flags = (os.environ.get("HF_HUB_OFFLINE"), os.environ.get("TRANSFORMERS_OFFLINE"))
    return any((flag or "").strip().lower() in _TRUE for flag in flags)


def hub_reachable(timeout: float = HUB_TIMEOUT_S) -> bool:
    """A quick TCP check that the hub (or the HTTPS proxy in use) answers within ``timeout``."""
    proxy = os.environ.get("HTTPS_PROXY") or os.environ.get("https_proxy")
    url = urlparse(proxy or os.environ.get("HF_ENDPOINT") or "https://huggingface.co")
    host = url.hostname
    if not host:
        return False
    port = url.port or (443 if url.scheme == "https" else 80)
    try:
        with socket.create_connection((host, port), timeout=timeout):
            return True
    except OSError:
        return False


def is_weights_folder(folder: str | os.PathLike) -> bool:
    """Whether ``folder`` holds a ``transformers`` model: ``config.json`` and safetensors."""
    path = Path(folder)
    return (path / "config.json").is_file() and any(path.glob("*.safetensors"))


def cached_hub_folder(hub_id: str) -> Path | None:
    """The cached snapshot folder of hub repository ``hub_id``, or None (never uses the network)."""
    from huggingface_hub import try_to_load_from_cache

    found = try_to_load_from_cache(hub_id, "config.json", cache_dir=str(hub_cache_dir()))
    if not isinstance(found, str):
        return None
    folder = Path(found).parent
    return folder if is_weights_folder(folder) else None


def download_hub_folder(
    hub_id: str, label: str, how_to_get: str, *, timeout: float = HUB_TIMEOUT_S
) -> Path:
    """The snapshot folder of ``hub_id``: cached, else downloaded once.

    Parameters
    ----------
    hub_id : str
        The repository.
    label : str
        What the weights are, for messages (e.g. ``"model edgetam"``).
    how_to_get : str
        The fix, appended to every error (one clause).
    timeout : float
        Seconds to wait for the hub before giving up.

    Raises
    ------
    LfsamError
        Not cached and downloads are off, the hub cannot be reached, or the download failed.
    """
    cached = cached_hub_folder(hub_id)
    if cached is not None:
        return cached
    if hub_offline():
        raise LfsamError(
            f"no cached weights for {label} and downloads are off (HF_HUB_OFFLINE is set); "
            + how_to_get
        )
    if not hub_reachable(timeout):
        raise LfsamError(
            f"no cached weights for {label} and the model hub cannot be reached; " + how_to_get
        )
    from huggingface_hub import snapshot_download

    try:
        found = snapshot_download(
            hub_id, cache_dir=str(hub_cache_dir()), allow_patterns=_PATTERNS, etag_timeout=timeout,
        )
    except Exception as exc:  # gated, unauthorised or a network failure: the user's environment
        reason = " ".join(str(exc).split())[:160] or type(exc).__name__
        raise LfsamError(f"downloading the weights of {label} failed ({reason}); " + how_to_get
                         ) from None
    return Path(found)
