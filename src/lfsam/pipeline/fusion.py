"""Label fusion: N possibly overlapping masks of a view into one label image.

docs/design.md section 3.6: larger masks are written first and smaller ones on top, so a small
object in front of (or inside) a large one keeps its label; mask ``n`` gets label ``n + 1`` and 0
means unlabeled.
"""

from __future__ import annotations

import torch

__all__ = ["fuse_labels"]

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
