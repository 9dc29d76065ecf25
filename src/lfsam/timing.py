"""Wall-clock timing of pipeline stages, for the paper's metric T (section 4.1)."""

from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Iterator
from contextlib import contextmanager

import torch

__all__ = ["StageTimer"]


class StageTimer:
    """Accumulates wall-clock seconds per named stage.

    On CUDA the device is synchronised at both ends of a stage, so asynchronous GPU work is
    charged to the stage that launched it.

    Examples
    --------
    >>> timer = StageTimer(torch.device("cpu"))
    >>> with timer("encode"):
    ...     pass
    >>> sorted(timer.seconds)
    ['encode']
    """

    def __init__(self, device: torch.device) -> None:
        self.seconds: dict[str, float] = defaultdict(float)
        self._cuda = device.type == "cuda"

    @contextmanager
    def __call__(self, stage: str) -> Iterator[None]:
        """Time the ``with`` block and add it to ``stage``."""
        if self._cuda:
            torch.cuda.synchronize()
        start = time.perf_counter()
        try:
            yield
        finally:
            if self._cuda:
                torch.cuda.synchronize()
            self.seconds[stage] += time.perf_counter() - start
