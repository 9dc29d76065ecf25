"""Segmentation accuracy against ground-truth labels: AA and UE (paper section 4.1).

Both are read off one contingency table ``N[p, g]``: the number of light-field pixels (all views)
with predicted label ``p`` and ground-truth label ``g``, computed with a single ``bincount`` over
pixel label pairs. Predicted label 0 is "unlabeled" and never a segment; ground-truth label 0 is
"no ground truth here".

AA (achievable accuracy; Liu et al., "Entropy rate superpixel segmentation", CVPR 2011): each
predicted label ``p`` is mapped to the ground-truth label it shares most pixels with (over all
views, ground-truth label 0 excluded), and AA is the fraction of pixels whose mapped label equals
their ground-truth label. The pixels counted are those that carry both a predicted label and a
ground-truth label: pixels the prediction leaves unlabeled are measured by coverage, not accuracy
(paper Table 1 reports AA 0.97 at coverage 0.33, which only this reading allows, and the authors'
code counted predicted pixels), and pixels without ground truth cannot be judged. NaN when no
pixel carries both.

UE (undersegmentation error; Neubert & Protzel, "Superpixel benchmark and comparison", Forum
Bildverarbeitung 2012): for each ground-truth region ``g`` (label >= 1, over all views),
``sum over predicted labels p touching g of min(|p ∩ g|, |p \\ g|)``, divided by ``|g|``; UE is the
mean over regions. ``|p \\ g|`` counts every pixel of ``p`` outside ``g``, including pixels without
ground truth (a mask spilling onto them has crossed ``g``'s border). NaN when there is no region.
"""

from __future__ import annotations

import math

import torch

from lfsam.precision import wide_float

__all__ = ["achievable_accuracy", "contingency_table", "undersegmentation_error"]

_CHUNK = 1 << 22


def contingency_table(
    predicted: torch.Tensor, truth: torch.Tensor, num_predicted: int, num_truth: int
) -> torch.Tensor:
    """Pixel counts of every (predicted label, ground-truth label) pair.

    Parameters
    ----------
    predicted, truth : integer tensors of the same shape
        Compact labels ``0 .. num_predicted - 1`` and ``0 .. num_truth - 1``. Counted in chunks
        to keep the int64 temporaries small.
    num_predicted, num_truth : int
        Number of compact labels of each.

    Returns
    -------
    table : (num_predicted, num_truth) int64 tensor
        ``table[p, g] = |{pixels with predicted p and truth g}|``.
    """
    size = num_predicted * num_truth
    counts = torch.zeros(size, dtype=torch.long, device=predicted.device)
    for chunk_pred, chunk_truth in zip(
        torch.split(predicted.reshape(-1), _CHUNK),
        torch.split(truth.reshape(-1), _CHUNK),
        strict=True,
    ):
        counts += torch.bincount(chunk_pred.long() * num_truth + chunk_truth, minlength=size)
    return counts.reshape(num_predicted, num_truth)


def achievable_accuracy(table: torch.Tensor) -> float:
    """AA from a contingency table (definition in the module docstring).

    Parameters
    ----------
    table : (P, G) integer tensor
        Output of :func:`contingency_table`; row 0 and column 0 are "unlabeled".

    Returns
    -------
    float
        Achievable accuracy in ``[0, 1]``, NaN when no pixel has both labels.
    """
    judged = table[1:, 1:]
    total = int(judged.sum())
    if total == 0:
        return math.nan
    return float(judged.max(dim=1).values.sum()) / total


def undersegmentation_error(table: torch.Tensor) -> float:
    """UE from a contingency table (definition in the module docstring).

    Parameters
    ----------
    table : (P, G) integer tensor
        Output of :func:`contingency_table`; row 0 and column 0 are "unlabeled".

    Returns
    -------
    float
        Mean over ground-truth regions of the leak penalty, ``>= 0``; NaN without regions.
    """
    region_size = table[:, 1:].sum(dim=0)  # |g|, every pixel of the region
    segments = table[1:]  # predicted label 0 is never a segment
    inside = segments[:, 1:]  # |p ∩ g|
    outside = segments.sum(dim=1, keepdim=True) - inside  # |p \ g|
    penalty = torch.minimum(inside, outside).sum(dim=0)  # untouched p contribute min(0, .) = 0
    present = region_size > 0
    if not bool(present.any()):
        return math.nan
    wide = wide_float(table.device)
    return float((penalty[present].to(wide) / region_size[present].to(wide)).mean())
