"""The widest float type per device (MPS has no float64)."""

from __future__ import annotations

import torch

from lfsam.precision import wide_float


def test_wide_float_is_float64_except_on_mps():
    assert wide_float("cpu") is torch.float64
    assert wide_float(torch.device("cuda", 0)) is torch.float64
    assert wide_float("mps") is torch.float32
