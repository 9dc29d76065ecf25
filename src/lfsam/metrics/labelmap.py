"""Compact label ids: map arbitrary non-negative label ids onto ``0 .. K-1`` with 0 kept as 0.

Label ids in a result or a ground truth are arbitrary (a relabelling must not change any metric),
so the metrics first renumber them densely; every per-label count is then one ``bincount``.
"""

from __future__ import annotations

import numpy as np
import torch

from lfsam.errors import LfsamError

__all__ = ["compact_labels", "to_tensor"]

# Below this largest id a lookup table (one bincount) is cheaper than sorting every pixel.
_LUT_LIMIT = 1 << 24
_CHUNK = 1 << 22


def to_tensor(array: np.ndarray | torch.Tensor, device: torch.device) -> torch.Tensor:
    """``array`` as a tensor on ``device`` (no copy when it already is one there)."""
    if isinstance(array, torch.Tensor):
        return array.to(device)
    return torch.from_numpy(np.ascontiguousarray(array)).to(device)


def compact_labels(labels: torch.Tensor, name: str = "labels") -> tuple[torch.Tensor, torch.Tensor]:
    """Renumber labels densely, keeping 0 (unlabeled) as 0.

    Parameters
    ----------
    labels : integer tensor, any shape
        Label ids, ``>= 0``.
    name : str
        What the labels are, for the error message.

    Returns
    -------
    compact : int32 tensor, same shape
        ``compact == 0`` exactly where ``labels == 0``; other ids become ``1 .. K-1`` in
        increasing order of the original id.
    ids : (K,) int64 tensor
        ``ids[k]`` is the original id of compact label ``k``; ``ids[0] == 0``.

    Raises
    ------
    LfsamError
        If the labels are not integers or are negative.
    """
    if labels.dtype.is_floating_point or labels.dtype == torch.bool or labels.is_complex():
        raise LfsamError(f"{name} must be integers (0 = unlabeled), got dtype {labels.dtype}")
    flat = labels.reshape(-1)
    if flat.numel() == 0:
        zero = torch.zeros(1, dtype=torch.long, device=labels.device)
        return flat.to(torch.int32).reshape(labels.shape), zero
    low, high = int(flat.min()), int(flat.max())
    if low < 0:
        raise LfsamError(f"{name} must be >= 0 (0 = unlabeled), found {low}")
    if high < _LUT_LIMIT:
        present = torch.zeros(high + 1, dtype=torch.bool, device=flat.device)
        for chunk in torch.split(flat, _CHUNK):  # bincount widens to int64: keep that small
            present |= torch.bincount(chunk, minlength=high + 1) > 0
        present[0] = True
        ids = torch.nonzero(present).squeeze(1)
        lut = (torch.cumsum(present, 0) - 1).to(torch.int32)
        compact = torch.empty(flat.shape, dtype=torch.int32, device=flat.device)
        chunks = zip(torch.split(flat, _CHUNK), torch.split(compact, _CHUNK), strict=True)
        for source, target in chunks:
            target.copy_(lut[source.long()])  # indexing widens to int64: chunk by chunk
    else:
        ids = torch.unique(torch.cat([flat.new_zeros(1), flat])).long()
        compact = torch.searchsorted(ids, flat.long()).to(torch.int32)
    return compact.reshape(labels.shape), ids
