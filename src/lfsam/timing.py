"""Wall-clock timing of pipeline stages, for the paper's metric T (section 4.1)."""

from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import torch

__all__ = ["StageTimer"]

#: Events read at the latest after this many timed intervals, so a long-lived timer whose
#: times are never read (an interactive session, a stream) keeps a bounded number of events.
MAX_PENDING = 4096


def _cuda_event() -> Any:
    """A recorded CUDA event that can be timed (a hook, so tests can stand in for CUDA)."""
    event = torch.cuda.Event(enable_timing=True)
    event.record()
    return event


class StageTimer:
    """Accumulates wall-clock seconds per named stage.

    On CUDA the stage boundaries are CUDA events recorded in the stream, not host
    synchronisations (docs/design.md section 3.5): a boundary costs no wait, asynchronous GPU
    work is still charged to the stage that launched it (the time between two events is the
    time the GPU took from one to the other, idle gaps included), and the events are read once,
    when :attr:`seconds` or :attr:`outermost` is first read after new stages (one wait for the
    last event), or after :data:`MAX_PENDING` intervals. A stage timed inside another is
    charged to the inner stage only (the outer one pauses meanwhile), so the stages never count
    a second twice: the center view's disparity
    estimate, made on first use while the initial segmentation carries clicks into the
    reference view, is ``disparity``, not ``initial`` (issue 46).

    Parameters
    ----------
    device : torch.device
        The device the timed work runs on.
    events : bool, optional
        Mark boundaries with CUDA events; default on CUDA. False marks them with the host
        clock (on CUDA after a synchronisation, as before issue 44's GPU run).

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

    def __init__(self, device: torch.device, *, events: bool | None = None) -> None:
        self._seconds: dict[str, float] = defaultdict(float)
        self._outermost: dict[str, float] = defaultdict(float)
        self._cuda = device.type == "cuda"
        self._events = self._cuda if events is None else events
        self._open: list[list] = []  # [stage, the mark its own time last (re)started at]
        # with events: (table, stage, start event, end event), read when the tables are read
        self._pending: list[tuple[dict[str, float], str, Any, Any]] = []

    @property
    def seconds(self) -> dict[str, float]:
        """Each stage's own seconds (reads the pending events: waits for the last one)."""
        self._resolve()
        return self._seconds

    @property
    def outermost(self) -> dict[str, float]:
        """Each stage's seconds timed outside any other stage (reads the pending events)."""
        self._resolve()
        return self._outermost

    @contextmanager
    def __call__(self, stage: str) -> Iterator[None]:
        """Time the ``with`` block and add it to ``stage`` (less the stages nested in it)."""
        start = self._mark()
        if self._open:  # the outer stage pauses
            outer = self._open[-1]
            self._add(self._seconds, outer[0], outer[1], start)
        entry = [stage, start]
        self._open.append(entry)
        try:
            yield
        finally:
            now = self._mark()
            self._open.pop()
            self._add(self._seconds, stage, entry[1], now)
            if self._open:
                self._open[-1][1] = now  # the outer stage goes on
            else:
                self._add(self._outermost, stage, start, now)

    def _mark(self) -> Any:
        if self._events:
            return _cuda_event()
        if self._cuda:
            torch.cuda.synchronize()
        return time.perf_counter()

    def _add(self, table: dict[str, float], stage: str, start: Any, end: Any) -> None:
        if self._events:
            self._pending.append((table, stage, start, end))
            if len(self._pending) >= MAX_PENDING:  # a long session whose times nobody reads
                self._resolve()
        else:
            table[stage] += end - start

    def _resolve(self) -> None:
        if not self._pending:
            return
        pending, self._pending = self._pending, []
        pending[-1][3].synchronize()  # events complete in order: the last one is the latest
        for table, stage, start, end in pending:
            table[stage] += start.elapsed_time(end) / 1000.0
