"""Where each source pixel lands in a target view (:mod:`lfsam.warp`): :func:`landing_pixels`,
the nearest target pixel of every source pixel at offset ``(ds, dt)`` by the convention of
:func:`lfsam.geometry.project_pixels`, batched, with the rounding of exact halves explicit
(:data:`HALVES`: the pipeline's round-half-to-even, the metrics' round-half-up).
"""

from __future__ import annotations

import torch

from lfsam.geometry import project_pixels

__all__ = ["HALVES", "landing_pixels"]

HALVES = ("even", "up")


def _nearest(x: torch.Tensor, halves: str) -> torch.Tensor:
    """``x`` rounded to the nearest integer, halves to even or up.

    Raises
    ------
    ValueError
        For a ``halves`` not in :data:`HALVES` (the caller's code is at fault).
    """
    if halves == "even":
        return torch.round(x)
    if halves == "up":
        return torch.floor(x + 0.5)
    raise ValueError(f"unknown rounding of halves {halves!r}; use one of {HALVES}")


def landing_pixels(
    disparity: torch.Tensor,
    ds: float | torch.Tensor,
    dt: float | torch.Tensor,
    *,
    halves: str = "even",
) -> tuple[torch.Tensor, torch.Tensor]:
    """The nearest target pixel of every source pixel (forward warping without a z-buffer).

    Source pixel ``(u, v)`` with disparity ``d`` lands at ``(u - d ds, v - d dt)``
    (:func:`lfsam.geometry.project_pixels`), rounded to the nearest pixel.

    Parameters
    ----------
    disparity : (..., U, V) float tensor
        Disparity of the source view(s). Non-finite values never land.
    ds, dt : float or tensor
        Offsets of the target view from the source view; tensors broadcast against
        ``disparity`` (e.g. ``(B, 1, 1)`` for a batch of views).
    halves : {"even", "up"}
        How exact halves round: to even (``torch.round``) or up (``floor(x + 0.5)``).

    Returns
    -------
    target : (..., U * V) int64 tensor
        Flat index ``u' * V + v'`` of the landing pixel; ``-1`` where not valid.
    valid : (..., U * V) bool tensor
        The pixel lands inside the target view.

    Examples
    --------
    >>> import torch
    >>> target, valid = landing_pixels(torch.full((2, 3), 1.0), 0, 1)
    >>> target.tolist(), valid.tolist()
    ([-1, 0, 1, -1, 3, 4], [False, True, True, False, True, True])
    """
    height, width = disparity.shape[-2:]
    dtype = disparity.dtype if disparity.is_floating_point() else torch.float32
    disparity = disparity.to(dtype)
    rows = torch.arange(height, device=disparity.device, dtype=dtype)[:, None]
    cols = torch.arange(width, device=disparity.device, dtype=dtype)[None, :]
    target_u, target_v = project_pixels(rows, cols, disparity, ds, dt)
    target_u = _nearest(target_u, halves)
    target_v = _nearest(target_v, halves)
    # NaN and infinite disparities fail these comparisons (or give NaN), so they drop out.
    valid = (target_u >= 0) & (target_u <= height - 1) & (target_v >= 0)
    valid &= target_v <= width - 1
    # Invalid entries (possibly NaN converted to an arbitrary integer) are overwritten with -1.
    index = target_u.long() * width + target_v.long()
    target = torch.where(valid, index, torch.full_like(index, -1))
    lead = target.shape[:-2]
    return target.reshape(*lead, -1), valid.reshape(*lead, -1)
