"""Per-mask reductions over (mask, pixel) pairs sorted by mask: sums, minima, maxima.

Semantic occluding and refinement (paper sections 3.3-3.4) handle the masks of a view as
(mask index, pixel index) pairs, sorted by mask index (``torch.nonzero`` of ``(N, U * V)``).
On a CPU the reductions are ``index_add_`` / ``scatter_reduce_``; on CUDA those serialise on
atomics (every pair of a mask adds into the same slot: 100 masks of a 480 x 640 view spent most
of refinement there on an H100), so contiguous segment reductions are used instead (same values
up to the order of floating-point additions).
"""

from __future__ import annotations

import torch

__all__ = ["segment_lengths", "segment_reduce"]


def segment_lengths(mask_index: torch.Tensor, num_masks: int) -> torch.Tensor:
    """Pairs per mask of a sorted ``mask_index``, ``(num_masks,)`` int64 (no atomics)."""
    bounds = torch.arange(num_masks + 1, device=mask_index.device, dtype=mask_index.dtype)
    edges = torch.searchsorted(mask_index, bounds)
    return edges[1:] - edges[:-1]


def segment_reduce(
    values: torch.Tensor,
    mask_index: torch.Tensor,
    num_masks: int,
    how: str,
    lengths: torch.Tensor | None = None,
) -> torch.Tensor:
    """Reduce ``values`` per mask: ``how`` in ``sum``, ``min``, ``max``.

    Parameters
    ----------
    values : (P,) float tensor
    mask_index : (P,) int64 tensor, sorted ascending
    num_masks : int
    how : {"sum", "min", "max"}
    lengths : (num_masks,) int64 tensor, optional
        :func:`segment_lengths`, when already computed.

    Returns
    -------
    (num_masks,) tensor of ``values``' dtype: 0 / +inf / -inf for masks without pairs.

    Examples
    --------
    >>> index = torch.tensor([0, 0, 2])
    >>> segment_reduce(torch.tensor([1.0, 2.0, 5.0]), index, 3, "sum").tolist()
    [3.0, 0.0, 5.0]
    """
    initial = {"sum": 0.0, "min": float("inf"), "max": float("-inf")}[how]
    if values.device.type != "cuda":
        out = torch.full((num_masks,), initial, dtype=values.dtype, device=values.device)
        if how == "sum":
            return out.index_add_(0, mask_index, values)
        return out.scatter_reduce_(0, mask_index, values, reduce="a" + how, include_self=True)
    if lengths is None:
        lengths = segment_lengths(mask_index, num_masks)
    return torch.segment_reduce(values, how, lengths=lengths, unsafe=True, initial=initial)
