"""Performance metrics of paper section 4.1: coverage C and time per mask per view T."""

from __future__ import annotations

from collections.abc import Mapping

import torch

__all__ = ["coverage", "ms_per_mask_view"]


def coverage(labels: torch.Tensor) -> float:
    """C: the fraction of all light-field pixels (every view) that carry a label.

    Paper section 4.1 words it as "the ratio of unsegmented pixels", but its Table 1 marks
    higher as better (C↑) and reports 0.31 to 0.33; we follow the table: labeled pixels / all.

    Parameters
    ----------
    labels : (S, T, U, V) integer tensor
        0 = unlabeled.

    Returns
    -------
    float
        In ``[0, 1]``.
    """
    if labels.numel() == 0:
        return 0.0
    return float(torch.count_nonzero(labels)) / labels.numel()


def ms_per_mask_view(
    timings: Mapping[str, float] | None, num_masks: int, grid_shape: tuple[int, int]
) -> float | None:
    """T: wall-clock milliseconds per mask per view, ``1000 total / (N S T)``.

    Defined in docs/design.md section 5.

    Parameters
    ----------
    timings : mapping or None
        Seconds per stage with the whole run under ``"total"``.
    num_masks : int
        N, the number of masks segmented.
    grid_shape : (S, T)
        View grid.

    Returns
    -------
    float or None
        None without a total time or without masks.
    """
    if not timings or timings.get("total") is None or num_masks <= 0:
        return None
    s_count, t_count = grid_shape
    return 1000.0 * float(timings["total"]) / (num_masks * s_count * t_count)
