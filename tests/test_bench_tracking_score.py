"""The tracking benchmark's return bookkeeping (issue 47; benchmarks/bench_tracking.py): the
target covers objects hidden for up to five frames, so each return records the frames the
object was hidden before it, and ``late_in_target`` counts only the returns after such gaps
found late or never. Hand-made label sequences with known answers."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import SimpleNamespace

import numpy as np

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_tracking.py"
_spec = importlib.util.spec_from_file_location("bench_tracking_for_score", SCRIPT)
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)

GRID, SIZE = (1, 1), (8, 8)


def _frame(shown: bool) -> SimpleNamespace:
    """One frame of one view: the object (label 2) a 4x4 square where it shows."""
    labels = np.ones((*GRID, *SIZE), np.int64)
    if shown:
        labels[..., 2:6, 2:6] = 2
    return SimpleNamespace(labels=labels)


def _score(shown: list[bool], found: list[bool]) -> dict:
    frames = [_frame(s) for s in shown]
    predicted = [np.where(f.labels == 2, 1, 0) if hit else np.zeros_like(f.labels)
                 for f, hit in zip(frames, found, strict=True)]
    return bench.score(frames, predicted, {1: 2}, min_pixels=10)


def test_a_return_after_a_short_gap_found_a_frame_late_is_in_the_targets_count():
    # shown, hidden 2 frames, shown again: missed in its first frame back, found in the next
    row = _score([True, False, False, True, True], [True, False, False, False, True])
    assert row["returns"] == 1
    assert row["latencies"] == [1] and row["gaps"] == [2]
    assert row["late_in_target"] == 1 and row["never"] == 0


def test_a_return_after_a_long_gap_is_recorded_but_outside_the_target():
    # hidden 7 frames (more than TARGET_GAP = 5), then found a frame late
    shown = [True] + [False] * 7 + [True, True]
    found = [True] + [False] * 8 + [True]
    row = _score(shown, found)
    assert row["latencies"] == [1] and row["gaps"] == [7]
    assert bench.TARGET_GAP == 5 and row["late_in_target"] == 0


def test_a_return_never_found_keeps_the_gap_it_came_back_from():
    # back after 1 frame hidden, missed; hidden again for 3 frames; back and never found
    shown = [True, False, True, False, False, False, True]
    found = [True] + [False] * 6
    row = _score(shown, found)
    assert row["returns"] == 1 and row["never"] == 1
    assert row["never_gaps"] == [1] and row["late_in_target"] == 1
    assert row["latencies"] == [] and row["gaps"] == []


def test_on_time_returns_count_nothing():
    shown = [True, False, True, False, False, False, False, False, False, True]
    row = _score(shown, shown)
    assert row["returns"] == 2 and row["latencies"] == [0, 0] and row["gaps"] == [1, 6]
    assert row["late_in_target"] == 0 and row["never"] == 0
