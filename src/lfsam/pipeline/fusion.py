"""Label fusion: N possibly overlapping masks of a view into one label image.

docs/design.md section 3.6: larger masks are written first and smaller ones on top, so a small
object in front of (or inside) a large one keeps its label; mask ``n`` gets label ``n + 1`` and 0
means unlabeled.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np
import torch

if TYPE_CHECKING:
    from lfsam.lightfield import LightField

__all__ = ["ViewLabels", "fuse_labels", "fuse_packed"]

_CHUNK = 32


def fuse_labels(masks: torch.Tensor, paint_order: torch.Tensor) -> torch.Tensor:
    """Paint masks in ``paint_order`` (later on top) into a label image.

    Parameters
    ----------
    masks : (N, U, V) bool tensor
    paint_order : (N,) int64 tensor
        A permutation of ``range(N)``; the last mask painted wins where masks overlap.

    Returns
    -------
    labels : (U, V) int32 tensor
        ``n + 1`` where mask ``n`` is the last painted mask covering the pixel, else 0.
    """
    n, height, width = masks.shape
    device = masks.device
    # rank[n] = position of mask n in the paint order; each pixel takes its highest rank + 1.
    rank = torch.empty(n, dtype=torch.int32, device=device)
    rank[paint_order.to(device)] = torch.arange(n, dtype=torch.int32, device=device)
    top = torch.zeros((height, width), dtype=torch.int32, device=device)
    for start in range(0, n, _CHUNK):
        chunk = masks[start : start + _CHUNK]
        ranked = chunk.to(torch.int32) * (rank[start : start + _CHUNK, None, None] + 1)
        top = torch.maximum(top, ranked.amax(dim=0))
    lookup = torch.zeros(n + 1, dtype=torch.int32, device=device)
    lookup[1:] = paint_order.to(device=device, dtype=torch.int32) + 1
    return lookup[top.long()]


class ViewLabels:
    """The label field of a run, fused view by view as each view's masks are all in.

    Each view's final masks are kept until every object has one there, then painted
    (:func:`fuse_labels`) on their device. On a CPU the labels go straight into the field; on a
    GPU they stay on the device until :meth:`field` reads them all back in one copy, so a view's
    labels never make the host wait mid-run (docs/design.md section 3.5).

    Parameters
    ----------
    grid_shape, view_shape : tuple of int
        The light field's ``(S, T)`` and ``(U, V)``.
    ids : list of int
        The objects of the run, in the order of ``rank``.
    paint_order : list of int
        ``ids`` in paint order (docs/design.md section 3.6).
    device : torch.device
        Where the masks are.
    """

    def __init__(self, grid_shape: tuple[int, int], view_shape: tuple[int, int], ids: list[int],
                 paint_order: list[int], device: torch.device) -> None:
        self.ids = list(ids)
        self._labels = np.zeros((*grid_shape, *view_shape), dtype=np.int32)
        rank = {i: k for k, i in enumerate(self.ids)}
        self._paint = torch.as_tensor([rank[i] for i in paint_order], device=device)
        self._lookup = torch.as_tensor([0, *self.ids], dtype=torch.int32, device=device)
        self._waiting: dict[tuple[int, int], dict[int, torch.Tensor]] = {}
        self._on_device: dict[tuple[int, int], torch.Tensor] = {}
        self._defer = device.type == "cuda"

    def add(self, view: tuple[int, int], final: dict[int, torch.Tensor]) -> bool:
        """Take some objects' final ``(U, V)`` masks in ``view``; fuse the view once every
        object has one there. Returns whether the view was fused."""
        masks = self._waiting.setdefault(view, {})
        masks.update(final)
        if len(masks) < len(self.ids):
            return False
        del self._waiting[view]
        fused = self._lookup[fuse_labels(torch.stack([masks[i] for i in self.ids]),
                                         self._paint).long()]
        if self._defer:
            self._on_device[view] = fused
        else:
            self._labels[view] = fused.cpu().numpy()
        return True

    def field(self) -> np.ndarray:
        """The ``(S, T, U, V)`` int32 label field (0 where no object, and in views not fused);
        the labels kept on a GPU come back in one copy."""
        if self._on_device:
            views = list(self._on_device)
            back = torch.stack([self._on_device[v] for v in views]).cpu().numpy()
            for view, labels in zip(views, back, strict=True):
                self._labels[view] = labels
            self._on_device.clear()
        return self._labels


def fuse_packed(
    lightfield: LightField, ids: list[int], bits: Mapping[int, np.ndarray], paint_order: list[int]
) -> np.ndarray:
    """Label field of the objects ``ids`` (values = ids) from their bit-packed masks
    (``bits[i]``: ``(S, T, ceil(U V / 8))`` uint8, :func:`lfsam.result.pack_masks` per view),
    painted in ``paint_order`` view by view; ``(S, T, U, V)`` int32, 0 where no object is."""
    height, width = lightfield.view_shape
    labels = np.zeros((*lightfield.grid_shape, height, width), dtype=np.int32)
    if not ids:
        return labels
    rank = {i: k for k, i in enumerate(ids)}
    paint = torch.as_tensor([rank[i] for i in paint_order])
    lookup = np.concatenate([[0], np.asarray(ids, dtype=np.int32)])
    for s, t in lightfield.view_indices(present_only=True):
        packed = np.stack([bits[i][s, t] for i in ids])
        masks = np.unpackbits(packed, axis=1, count=height * width).astype(bool)
        fused = fuse_labels(torch.from_numpy(masks.reshape(-1, height, width)), paint)
        labels[s, t] = lookup[fused.numpy()]
    return labels
