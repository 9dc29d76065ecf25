"""The viewer's Qt-free glue: layer data <-> prompts, undo/redo history, label selection."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from lfsam.prompts import BoxPrompt, ObjectPrompts, PointPrompt
from lfsam.viewer.prompt_layers import (
    PromptHistory,
    layers_from_prompts,
    prompts_from_layers,
    select_labels,
)

GRID, CENTER = (5, 7), (2, 3)
coords = st.floats(0, 200, allow_nan=False, width=32)
views = st.tuples(st.integers(0, GRID[0] - 1), st.integers(0, GRID[1] - 1))
points = st.builds(PointPrompt, coords, coords, st.booleans(), views)
boxes = st.builds(
    lambda x0, y0, w, h, v: BoxPrompt(x0, y0, x0 + w, y0 + h, view=v), coords, coords, coords,
    coords, views,
)


@settings(max_examples=60, deadline=None)
@given(st.lists(points, max_size=6), st.none() | boxes)
def test_layers_and_prompts_round_trip(point_list, box):
    obj = ObjectPrompts(4, tuple(point_list), box)
    data, positive, rects = layers_from_prompts(obj, CENTER)
    # layer coordinates are (s, t, u, v): view row and column, then pixel row (y) and column (x)
    for row, p in zip(data, point_list, strict=True):
        assert tuple(row) == (*p.view, np.float32(p.y), np.float32(p.x))
    back = prompts_from_layers(4, data, positive, rects, GRID)
    if not point_list and box is None:
        assert back is None
    else:
        assert back == obj


def test_untagged_prompts_are_in_the_center_view_and_the_last_box_counts():
    obj = ObjectPrompts(1, (PointPrompt(5.0, 6.0),), BoxPrompt(1, 2, 3, 4))
    data, positive, rects = layers_from_prompts(obj, CENTER)
    assert data.tolist() == [[2, 3, 6, 5]] and positive.tolist() == [True]
    first = np.array([[0, 0, 0, 0], [0, 0, 9, 9]], float)
    back = prompts_from_layers(1, data, positive, [first, *rects], GRID)
    assert back.box == BoxPrompt(1, 2, 3, 4, view=CENTER)


def test_history_undo_redo_and_branching():
    history = PromptHistory()
    a, b, c = (ObjectPrompts(1, (PointPrompt(i, i),)) for i in range(3))
    assert not history.can_undo and history.undo() is None
    assert history.push(a) and history.push(b) and not history.push(b)
    assert history.undo() == a and history.undo() is None and not history.can_undo
    assert history.redo() == a and history.can_redo
    assert history.push(c) and not history.can_redo  # a new edit drops the redo branch
    assert history.undo() == a and history.redo() == c


def test_select_labels():
    labels = np.array([[0, 1, 2], [3, 2, 1]], np.int32)
    np.testing.assert_array_equal(select_labels(labels, {1, 3}), [[0, 1, 0], [3, 0, 1]])
    assert not select_labels(labels, set()).any()
