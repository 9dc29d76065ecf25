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
    charged to the stage that launched it. A stage timed inside another is charged to the inner
    stage only (the outer one pauses meanwhile), so the stages never count a second twice: the
    center view's disparity estimate, made on first use while the initial segmentation carries
    clicks into the reference view, is ``disparity``, not ``initial`` (issue 46).

    Attributes
    ----------
    seconds : dict of str to float
        Each stage's own seconds.
    outermost : dict of str to float
        Each stage's seconds timed outside any other stage (nested stages included).

    Examples
    --------
    >>> timer = StageTimer(torch.device("cpu"))
    >>> with timer("initial"):
    ...     with timer("disparity"):
    ...         time.sleep(0.02)
    >>> sorted(timer.seconds), timer.seconds["initial"] < timer.seconds["disparity"]
    (['disparity', 'initial'], True)
    >>> sorted(timer.outermost)
    ['initial']
    """

    def __init__(self, device: torch.device) -> None:
        self.seconds: dict[str, float] = defaultdict(float)
        self.outermost: dict[str, float] = defaultdict(float)
        self._cuda = device.type == "cuda"
        self._open: list[list] = []  # [stage, when its own time last (re)started]

    @contextmanager
    def __call__(self, stage: str) -> Iterator[None]:
        """Time the ``with`` block and add it to ``stage`` (less the stages nested in it)."""
        if self._cuda:
            torch.cuda.synchronize()
        start = time.perf_counter()
        if self._open:  # the outer stage pauses
            outer = self._open[-1]
            self.seconds[outer[0]] += start - outer[1]
        entry = [stage, start]
        self._open.append(entry)
        try:
            yield
        finally:
            if self._cuda:
                torch.cuda.synchronize()
            now = time.perf_counter()
            self._open.pop()
            self.seconds[stage] += now - entry[1]
            if self._open:
                self._open[-1][1] = now  # the outer stage goes on
            else:
                self.outermost[stage] += now - start
