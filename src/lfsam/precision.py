"""The widest floating-point type a torch device computes in.

Sums of many terms (areas, weighted centroids, Gram-matrix norms) are accumulated in float64,
but Apple's MPS backend has no float64: there the same code runs in float32 instead of failing.
"""

from __future__ import annotations

import torch

__all__ = ["wide_float"]


def wide_float(device: torch.device | str) -> torch.dtype:
    """``torch.float64``, or ``torch.float32`` on MPS (which has no float64)."""
    return torch.float32 if torch.device(device).type == "mps" else torch.float64
