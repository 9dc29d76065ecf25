"""Which views are encoded and refined: all of them (the paper), or a few spread over the grid.

The paper re-prompts SAM 2 in every view (section 3.4), one image-encoder pass per view, 95% of
a run's time. Neighbouring views are nearly the same image, so refining a few views spread
evenly over the grid and carrying their refined masks into the others
(:func:`lfsam.pipeline.fill.fill_from_sources`) keeps the accuracy at a fraction of the encoder
passes (docs/design.md section 3.7).

* :func:`check_refine_views` — parse and check ``all``, ``sparse`` or a count ``N``;
* :func:`sparse_view_count` — how many views ``sparse`` means for a grid (13 of 81, 9 of 25, all
  of 9);
* :func:`select_views` — ``N`` views spread evenly over the present views (farthest-point
  sampling seeded with the center and, from ``N >= 5``, the corners);
* :func:`refined_views` — the base set of a light field for a setting (None for ``all``);
* :func:`nearest_sources` — the refined views nearest to a view, the sources of its fill.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np

from lfsam.errors import LfsamError

__all__ = [
    "FILL_SOURCES",
    "REFINE_VIEW_MODES",
    "check_refine_views",
    "nearest_sources",
    "refined_views",
    "select_views",
    "sparse_view_count",
]

View = tuple[int, int]

#: The named settings of ``--refine-views``; a positive integer is the third form.
REFINE_VIEW_MODES = ("all", "sparse")

#: Refined views a filled view takes its masks from (the nearest ones), docs/design.md 3.7.
FILL_SOURCES = 4


def check_refine_views(value: str | int) -> str | int:
    """``value`` as a checked setting: ``"all"``, ``"sparse"`` or a positive int.

    Strings of digits become ints (``"9"`` -> ``9``), so the CLI and the Python options agree.

    Raises
    ------
    LfsamError
        For anything else, naming the three forms.
    """
    if isinstance(value, str) and value.strip().isdigit():
        value = int(value.strip())
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        if int(value) >= 1:
            return int(value)
    elif value in REFINE_VIEW_MODES:
        return str(value)
    raise LfsamError(
        f"refine_views must be 'all', 'sparse' or a number of views N >= 1, got {value!r}; "
        "e.g. --refine-views sparse (13 of 9x9 views) or --refine-views 9"
    )


def sparse_view_count(num_views: int) -> int:
    """Views refined by ``sparse`` out of ``num_views`` present: about one in six, at least 9.

    ``ceil(13 num_views / 81)``, at least 9 and at most ``num_views``: 13 of 81 (9 x 9: the
    center, the corners, the edge midpoints and the four views two steps in from the corners),
    9 of 25 (5 x 5, the center, the corners and the edge midpoints), all of 9 (3 x 3); 9 of 49
    (7 x 7). On 9 x 9 views every view is within two steps of a refined one, as with 17, and
    ``benchmarks/bench_sparse.py`` measured the same accuracy as 17 for a quarter fewer
    encoder passes (docs/performance.md, "Refining a few views").

    >>> [sparse_view_count(n) for n in (9, 25, 49, 81, 169)]
    [9, 9, 9, 13, 28]
    """
    return min(num_views, max(9, math.ceil(13 * num_views / 81)))


def select_views(
    present: np.ndarray, count: int, seeds: Sequence[View] = ()
) -> list[View]:
    """``count`` present views spread evenly over the grid (farthest-point sampling).

    The ``seeds`` come first (the reference views), then, from ``count >= 5``, the four corners
    of the grid's bounding box of present views that are present; then, repeatedly, the present
    view farthest (Euclidean, in view steps) from every view chosen so far, ties broken by the
    distance to the grid's middle, then row-major. Deterministic.

    Parameters
    ----------
    present : (S, T) bool array
        The views the light field has.
    count : int
        How many views; more than present gives every present view.
    seeds : sequence of (s, t)
        Views always chosen (present or not: a reference view is kept as given).

    Returns
    -------
    list of (s, t)
        In the order chosen (seeds first); ``max(count, len(seeds))`` views at most.

    Examples
    --------
    >>> grid = np.ones((5, 5), dtype=bool)
    >>> sorted(select_views(grid, 9, [(2, 2)]))  # center, corners, edge midpoints
    [(0, 0), (0, 2), (0, 4), (2, 0), (2, 2), (2, 4), (4, 0), (4, 2), (4, 4)]
    """
    present = np.asarray(present, dtype=bool)
    coords = np.argwhere(present)
    chosen: list[View] = []

    def take(view: View) -> None:
        if view not in chosen:
            chosen.append(view)

    for seed in seeds:
        take((int(seed[0]), int(seed[1])))
    if len(coords) == 0:
        return chosen
    if count >= 5:
        (s0, t0), (s1, t1) = coords.min(0), coords.max(0)
        for corner in ((s0, t0), (s0, t1), (s1, t0), (s1, t1)):
            if present[corner]:
                take((int(corner[0]), int(corner[1])))
    middle = (coords.min(0) + coords.max(0)) / 2.0
    to_middle = np.hypot(*(coords - middle).T)
    if chosen:
        picked = np.array(chosen, dtype=float)
        nearest = np.min(np.hypot(*(coords[:, None] - picked[None]).transpose(2, 0, 1)), axis=1)
    else:
        nearest = np.full(len(coords), np.inf)
    while len(chosen) < count and np.max(nearest) > 0:
        # largest distance to the chosen views; then nearest the middle; then row-major
        order = np.lexsort((coords[:, 1], coords[:, 0], to_middle, -np.round(nearest, 9)))
        view = (int(coords[order[0], 0]), int(coords[order[0], 1]))
        take(view)
        nearest = np.minimum(nearest, np.hypot(*(coords - np.array(view)).T))
    return chosen


def refined_views(
    setting: str | int, present: np.ndarray, center: View
) -> frozenset[View] | None:
    """The views refined for every object under ``setting`` (None: every view, the paper).

    ``sparse`` and ``N`` select with :func:`select_views` seeded with the ``center`` (the default
    reference view); an object prompted elsewhere is also refined in its own reference view,
    which the caller adds (docs/design.md section 3.7).
    """
    setting = check_refine_views(setting)
    num_views = int(np.count_nonzero(present))
    if setting == "all":
        return None
    count = sparse_view_count(num_views) if setting == "sparse" else int(setting)
    if count >= num_views:
        return None
    seeds = [center] if present[center] else []
    return frozenset(select_views(present, count, seeds))


def nearest_sources(
    view: View, sources: Iterable[View], count: int = FILL_SOURCES
) -> list[View]:
    """The ``count`` views of ``sources`` nearest to ``view`` (Euclidean in view steps), nearest
    first, ties row-major; ``view`` itself is not a source of itself."""
    ranked = sorted(
        (v for v in sources if v != view),
        key=lambda v: (math.hypot(v[0] - view[0], v[1] - view[1]), v),
    )
    return ranked[:count]
