"""View embeddings computed at most once: an in-memory LRU store and an on-disk cache.

Interactive segmentation (docs/design.md section 8) prompts the same views again and again; the
image encoder is by far the costliest step (paper section 4.3), so each view is encoded lazily,
at most once, and kept:

* in memory, least recently used first out, within a memory budget;
* optionally on disk (``cache_dir``), as micro-sam does: one ``.npz`` per view, keyed by a hash
  of the view's bytes (uint8 RGB as segmented, not its file path) together with the segmenter's
  identity (model name, a hash of its weights, input size, precision:
  :meth:`lfsam.segmenters.base.Segmenter.cache_identity`). Values are the encoder output exactly
  as the decoder uses it, so a cached run reproduces an uncached one bit for bit. Entries are
  written atomically; an unreadable, corrupt or foreign entry is recomputed with a warning.
"""

from __future__ import annotations

import hashlib
import json
import os
import warnings
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import fields, is_dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from lfsam.errors import LfsamError
from lfsam.fileutil import atomic_output
from lfsam.segmenters.base import Segmenter, ViewEmbedding

__all__ = ["EmbeddingStore", "embedding_nbytes", "view_digest"]

View = tuple[int, int]


def view_digest(image: np.ndarray) -> str:
    """SHA-256 of a view's shape and uint8 bytes: the content part of a cache key."""
    image = np.ascontiguousarray(image)
    digest = hashlib.sha256(repr((image.shape, str(image.dtype))).encode())
    digest.update(image.tobytes())
    return digest.hexdigest()


def embedding_nbytes(value: Any) -> int:
    """Bytes held by the tensors and arrays inside an embedding (for the memory budget)."""
    if isinstance(value, torch.Tensor):
        return value.numel() * value.element_size()
    if isinstance(value, np.ndarray):
        return value.nbytes
    if isinstance(value, ViewEmbedding):
        return embedding_nbytes(value.data)
    if isinstance(value, (list, tuple)):
        return sum(embedding_nbytes(v) for v in value)
    if isinstance(value, dict):
        return sum(embedding_nbytes(v) for v in value.values())
    if is_dataclass(value):
        return sum(embedding_nbytes(getattr(value, f.name)) for f in fields(value))
    return 0


class EmbeddingStore:
    """Embeddings of the views of one light field, each computed at most once.

    Parameters
    ----------
    segmenter : Segmenter
        Encodes the views (:meth:`~lfsam.segmenters.base.Segmenter.encode`).
    views : (S, T, U, V, 3) uint8 ndarray
        The light field's views.
    cache_dir : path, optional
        On-disk cache folder (created if needed); None keeps embeddings in memory only.
    memory_budget_mb : float
        In-memory budget; least recently used embeddings are dropped beyond it (at least one is
        always kept). They come back from the disk cache, or are encoded again without one.

    Attributes
    ----------
    views_encoded : int
        Image-encoder runs made by this store (0 when everything came from the disk cache).
    disk_hits : int
        Views read from the disk cache.
    """

    def __init__(
        self,
        segmenter: Segmenter,
        views: np.ndarray,
        *,
        cache_dir: str | os.PathLike | None = None,
        memory_budget_mb: float = 2048.0,
    ) -> None:
        self.segmenter = segmenter
        self.views = views
        self.budget = float(memory_budget_mb) * 2**20
        self._memory: OrderedDict[View, tuple[ViewEmbedding, int]] = OrderedDict()
        self._pinned: set[View] = set()
        self._bytes = 0
        self.views_encoded = 0
        self.disk_hits = 0
        self.cache_dir = None if cache_dir is None else Path(cache_dir)
        self._identity = None
        if self.cache_dir is not None:
            self._identity = segmenter.cache_identity()
            if self._identity is None:
                warnings.warn(
                    f"{segmenter.name} embeddings are not cached on disk (nothing to save: "
                    "it does not run an image encoder)",
                    stacklevel=2,
                )
                self.cache_dir = None
            else:
                self.cache_dir.mkdir(parents=True, exist_ok=True)

    # --- public -----------------------------------------------------------------------------
    def __contains__(self, view: View) -> bool:
        return tuple(view) in self._memory

    def get(self, view: View) -> ViewEmbedding:
        """The embedding of view ``(s, t)`` (encoded on first use)."""
        return self.get_many([view])[0]

    def get_many(self, views: Sequence[View]) -> list[ViewEmbedding]:
        """Embeddings of several views; the missing ones are encoded in one batch call."""
        keys = [(int(s), int(t)) for s, t in views]
        out: dict[View, ViewEmbedding] = {}
        missing = []
        for key in keys:
            if key in self._memory:
                self._memory.move_to_end(key)
                out[key] = self._memory[key][0]
            elif key not in missing:
                loaded = self._load(key)
                if loaded is None:
                    missing.append(key)
                else:
                    out[key] = loaded
                    self._remember(key, loaded)
        if missing:
            images = np.stack([self.views[key] for key in missing])
            embeddings = self.segmenter.encode(images, keys=missing)
            self.views_encoded += len(missing)
            for key, embedding in zip(missing, embeddings, strict=True):
                out[key] = embedding
                self._remember(key, embedding)
                self._save(key, embedding)
        return [out[key] for key in keys]

    def put(self, view: View, embedding: ViewEmbedding) -> None:
        """Take ``view``'s embedding from an encoder pass made elsewhere (the video memory's
        pass over a frame's center view, docs/design.md section 10): later :meth:`get` calls
        return it without encoding. Not counted in :attr:`views_encoded`; not written to the
        disk cache."""
        key = (int(view[0]), int(view[1]))
        if embedding.key != key:
            embedding = replace(embedding, key=key)
        if key in self._memory:
            self._bytes -= self._memory.pop(key)[1]
        self._remember(key, embedding)

    def in_memory(self, view: View) -> bool:
        """Whether ``view``'s embedding is held in memory now (a :meth:`get_many` hit)."""
        return (int(view[0]), int(view[1])) in self._memory

    def pin(self, view: View) -> None:
        """Never drop ``view`` from memory (e.g. a reference view that serves again)."""
        self._pinned.add((int(view[0]), int(view[1])))

    def forget(self) -> None:
        """Drop every in-memory embedding (the disk cache stays)."""
        self._memory.clear()
        self._bytes = 0

    # --- memory -----------------------------------------------------------------------------
    def _remember(self, key: View, embedding: ViewEmbedding) -> None:
        size = embedding_nbytes(embedding)
        self._memory[key] = (embedding, size)
        self._bytes += size
        for old in list(self._memory):
            if self._bytes <= self.budget or len(self._memory) <= 1:
                break
            if old in self._pinned or old == key:
                continue
            _, dropped = self._memory.pop(old)
            self._bytes -= dropped

    # --- disk -------------------------------------------------------------------------------
    def _path(self, key: View) -> tuple[Path, str]:
        assert self.cache_dir is not None and self._identity is not None
        entry = hashlib.sha256(
            (self._identity + "|" + view_digest(self.views[key])).encode()
        ).hexdigest()
        return self.cache_dir / f"{entry[:40]}.npz", entry

    def _load(self, key: View) -> ViewEmbedding | None:
        if self.cache_dir is None:
            return None
        path, entry = self._path(key)
        if not path.is_file():
            return None
        try:
            with np.load(path, allow_pickle=False) as npz:
                header = json.loads(str(npz["__lfsam_cache__"]))
                if header.get("entry") != entry:
                    raise LfsamError("the entry belongs to another view or model; it is recomputed")
                state = {name: npz[name] for name in npz.files if name != "__lfsam_cache__"}
            embedding = self.segmenter.embedding_from_state(
                state, tuple(self.views.shape[2:4]), key
            )
        except Exception as exc:  # any unreadable entry is a miss, never a wrong answer
            warnings.warn(
                f"embedding cache entry {path.name} is unreadable ({exc}); encoding view "
                f"{key[0]},{key[1]} again",
                stacklevel=3,
            )
            return None
        self.disk_hits += 1
        return embedding

    def _save(self, key: View, embedding: ViewEmbedding) -> None:
        if self.cache_dir is None:
            return
        path, entry = self._path(key)
        state = self.segmenter.embedding_state(embedding)
        header = json.dumps({"entry": entry, "identity": self._identity})
        try:
            with atomic_output(path) as tmp, open(tmp, "wb") as handle:
                np.savez(handle, __lfsam_cache__=np.array(header), **state)
        except OSError as exc:
            warnings.warn(f"cannot write embedding cache entry {path}: {exc}", stacklevel=3)
