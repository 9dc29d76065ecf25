"""Folders of sub-aperture images named by their position on the view grid.

Three naming schemes are recognised from the file names themselves (docs/design.md section 2):

``pair``
    ``[prefix_]ROW_COL.ext``: ``2067_05_09.png`` (prefix ``2067``), ``t_rex_00_04.png``,
    ``09_08.png``, ``1_1.png``. The separators may be ``_`` or ``-``.
``compact``
    ``[prefix]RRCC.ext`` with an even number of digits split in half: ``0203.png`` is row 02,
    column 03.
``linear``
    ``[prefix]N.ext`` numbered row-major from the top-left view, e.g. ``input_Cam040.png``; the
    grid must be square unless given.

Index bases and offsets are whatever the files use: the grid is the sorted unique row indices
times the sorted unique column indices (a 3x3 cut ``09..11 x 08..10`` of a larger grid is a 3x3
light field). The first index is taken as the view row ``s`` (growing downwards) and the second as
the view column ``t`` (growing rightwards); with no ground truth this cannot be verified, and the
reader says so in ``meta["orientation"]``.
"""

from __future__ import annotations

import math
import re
from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

from lfsam.errors import LfsamError
from lfsam.io.images import IMAGE_SUFFIXES, read_view_grid
from lfsam.lightfield import LightField

__all__ = [
    "GridLayout",
    "assemble_grid",
    "linear_layout",
    "list_images",
    "read_grid_folder",
    "scan_grid_folder",
]

_PAIR = re.compile(r"^(?:(?P<prefix>.*?)[_-])?(?P<r>\d+)[_-](?P<c>\d+)$")
_COMPACT = re.compile(r"^(?P<prefix>(?:.*\D)?)(?P<digits>(?:\d\d){2,3})$")
_LINEAR = re.compile(r"^(?P<prefix>(?:.*\D)?)(?P<i>\d+)$")


@dataclass
class GridLayout:
    """Where each view of a grid folder is.

    Attributes
    ----------
    paths : list of list of Path or None
        ``paths[s][t]`` is the image of view ``(s, t)``; None where the view is missing.
    rows, cols : list of int
        The row and column indices as written in the file names, in grid order.
    scheme : str
        ``"pair"``, ``"compact"`` or ``"linear"``.
    prefix : str
        The common file-name prefix (may be empty).
    ignored : list of str
        Image files in the folder that are not part of the grid.
    digits : (int, int)
        Zero-padded widths of the row and column indices in the names.
    """

    paths: list[list[Path]]
    rows: list[int]
    cols: list[int]
    scheme: str
    prefix: str
    ignored: list[str] = field(default_factory=list)
    digits: tuple[int, int] = (1, 1)

    @property
    def grid_shape(self) -> tuple[int, int]:
        """``(S, T)``."""
        return len(self.rows), len(self.cols)


def list_images(folder: Path) -> list[Path]:
    """Image files directly inside ``folder`` (not hidden), sorted by name."""
    return sorted(
        p
        for p in folder.iterdir()
        if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES and not p.name.startswith(".")
    )


def assemble_grid(
    entries: dict[tuple[int, int], Path], folder: Path, example_name, allow_missing: bool = False
) -> tuple[list[list[Path | None]], list[int], list[int]]:
    """Arrange ``{(row index, col index): path}`` on the sorted grid, checking completeness.

    Parameters
    ----------
    entries : dict
        One path per (row index, column index) as named.
    folder : Path
        The folder (for messages).
    example_name : callable (row, col) -> str
        The file name a missing view would have (for the message).
    allow_missing : bool
        Accept a partial grid (docs/design.md section 8): missing views get None. The center
        view must still be there.

    Returns
    -------
    paths, rows, cols
        ``paths[s][t]`` (None for a missing view) and the sorted unique indices.

    Raises
    ------
    LfsamError
        If a view of the grid is missing (the center view, with ``allow_missing``).
    """
    rows = sorted({r for r, _ in entries})
    cols = sorted({c for _, c in entries})
    missing = [(r, c) for r in rows for c in cols if (r, c) not in entries]
    center = (rows[len(rows) // 2], cols[len(cols) // 2])
    if allow_missing and missing and center in missing:
        raise LfsamError(
            f"the center view {example_name(*center)} of the {len(rows)}x{len(cols)} grid in "
            f"{folder} is missing; lfsam needs the center view, add it"
        )
    if missing and not allow_missing:
        r, c = missing[0]
        more = f" and {len(missing) - 1} more" if len(missing) > 1 else ""
        raise LfsamError(
            f"view missing from the {len(rows)}x{len(cols)} grid in {folder}: "
            f"{example_name(r, c)}{more}; add the missing view(s) or remove the partial row/column"
        )
    return [[entries.get((r, c)) for c in cols] for r in rows], rows, cols


def _parse(stem: str) -> list[tuple[str, str, tuple[int, ...], tuple[int, ...]]]:
    """Interpretations of a file stem: (scheme, prefix, indices, digit widths)."""
    found = []
    match = _PAIR.match(stem)
    if match:
        prefix = match.group("prefix") or ""
        r, c = match.group("r"), match.group("c")
        found.append(("pair", prefix, (int(r), int(c)), (len(r), len(c))))
        return found
    match = _COMPACT.match(stem)
    if match:
        digits = match.group("digits")
        half = len(digits) // 2
        found.append(
            (
                "compact",
                match.group("prefix"),
                (int(digits[:half]), int(digits[half:])),
                (half, half),
            )
        )
    match = _LINEAR.match(stem)
    if match:
        i = match.group("i")
        found.append(("linear", match.group("prefix"), (int(i),), (len(i),)))
    return found


def linear_layout(
    items: list[tuple[Path, tuple[int, ...], tuple[int, ...]]],
    folder: Path,
    grid: tuple[int, int] | None,
    partial_start: int | None = None,
) -> tuple[list[list[Path | None]], list[int], list[int]]:
    """Arrange linearly numbered views row-major on a grid (square unless ``grid`` is given).

    With ``partial_start`` (and ``grid``) the numbers are absolute: number ``partial_start +
    s * T + t`` is view ``(s, t)`` and views may be missing (None; docs/design.md section 8),
    except the center view.

    Parameters
    ----------
    items : list of (path, (index,), (digits,))
        The views with their numbers.
    folder : Path
        The folder (for messages).
    grid : (S, T) or None
        Grid shape; None means square.

    Returns
    -------
    paths, rows, cols
        ``paths[s][t]`` and the row/column positions ``0..S-1``, ``0..T-1``.

    Raises
    ------
    LfsamError
        If numbers repeat, are not consecutive, or do not fill the grid.
    """
    by_index = {}
    for path, (index,), _ in items:
        if index in by_index:
            raise LfsamError(
                f"two files for view number {index} in {folder}: {by_index[index].name} and "
                f"{path.name}; keep one"
            )
        by_index[index] = path
    indices = sorted(by_index)
    count = len(indices)
    if partial_start is not None and grid is not None:
        return _partial_linear(by_index, items, folder, grid, partial_start)
    if grid is None:
        side = math.isqrt(count)
        if side * side != count:
            raise LfsamError(
                f"{count} views numbered linearly in {folder} do not form a square grid; "
                "name the views ROW_COL (e.g. 03_05.png) so the grid is explicit"
            )
        grid = (side, side)
    s_count, t_count = grid
    start = indices[0]
    expected = list(range(start, start + s_count * t_count))
    if indices != expected:
        gap = next((i for i in expected if i not in by_index), None)
        width = items[0][2][0]
        detail = (
            f"view number {gap:0{width}d} is missing"
            if gap is not None
            else (f"found {count} views for a {s_count}x{t_count} grid")
        )
        raise LfsamError(
            f"linearly numbered views in {folder} are not a complete {s_count}x{t_count} grid: "
            f"{detail}; add the missing view(s)"
        )
    paths = [[by_index[start + s * t_count + t] for t in range(t_count)] for s in range(s_count)]
    return paths, list(range(s_count)), list(range(t_count))


def _partial_linear(by_index, items, folder: Path, grid: tuple[int, int], start: int):
    s_count, t_count = grid
    width = items[0][2][0]
    outside = [i for i in by_index if not start <= i < start + s_count * t_count]
    if outside:
        raise LfsamError(
            f"view number {outside[0]:0{width}d} in {folder} lies outside the {s_count}x{t_count} "
            f"grid numbered from {start:0{width}d}; remove it or give the right grid size"
        )
    center = start + (s_count // 2) * t_count + t_count // 2
    if center not in by_index:
        name = items[0][0].name
        raise LfsamError(
            f"the center view (number {center:0{width}d}, like {name}) of the {s_count}x{t_count} "
            f"grid in {folder} is missing; lfsam needs the center view, add it"
        )
    paths = [
        [by_index.get(start + s * t_count + t) for t in range(t_count)] for s in range(s_count)
    ]
    return paths, list(range(s_count)), list(range(t_count))


def scan_grid_folder(
    folder: str | Path,
    grid: tuple[int, int] | None = None,
    exclude: Iterable[str] = (),
) -> GridLayout:
    """Find the view grid of a folder of images from the file names.

    Parameters
    ----------
    folder : path-like
        The folder holding the views.
    grid : (S, T), optional
        Grid shape for linearly numbered views (default: square).
    exclude : iterable of str
        File names to leave out (e.g. ground-truth images).

    Returns
    -------
    GridLayout

    Raises
    ------
    LfsamError
        If the folder is missing or empty, names are ambiguous, or a view is missing.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise LfsamError(f"folder {str(folder)!r} not found; check the path")
    excluded = set(exclude)
    images = [p for p in list_images(folder) if p.name not in excluded]
    if not images:
        raise LfsamError(
            f"no view images in {folder}; it must hold one image per view, named e.g. "
            f"ROW_COL.png ({', '.join(IMAGE_SUFFIXES[:3])}, ...)"
        )
    groups: dict[tuple[str, str, str], list] = defaultdict(list)
    for path in images:
        for scheme, prefix, indices, widths in _parse(path.stem):
            groups[(scheme, prefix, path.suffix.lower())].append((path, indices, widths))
    if not groups:
        raise LfsamError(
            f"cannot tell the view positions from the image names in {folder} "
            f"(e.g. {images[0].name}); name the views ROW_COL.png, RRCC.png or by number"
        )
    # Prefer the interpretation covering the most files; among equals pair > compact > linear.
    rank = {"pair": 0, "compact": 1, "linear": 2}
    ordered = sorted(groups.items(), key=lambda kv: (-len(kv[1]), rank[kv[0][0]], kv[0][1]))
    (scheme, prefix, _suffix), items = ordered[0]
    if scheme == "compact":
        return _compact_or_linear(folder, images, groups, prefix, items, grid)
    if scheme == "linear":
        paths, rows, cols = linear_layout(items, folder, grid)
    else:
        paths, rows, cols = _pair_layout(items, folder, prefix, scheme)
    used = {p for row in paths for p in row if p is not None}
    widths = (1, 1) if scheme == "linear" else tuple(items[0][2])
    return GridLayout(
        paths, rows, cols, scheme, prefix, [p.name for p in images if p not in used], widths
    )


def _pair_layout(items, folder: Path, prefix: str, scheme: str, allow_missing: bool = True):
    entries: dict[tuple[int, int], Path] = {}
    for path, (r, c), _ in items:
        if (r, c) in entries:
            raise LfsamError(
                f"two files for view ({r}, {c}) in {folder}: {entries[(r, c)].name} and "
                f"{path.name}; keep one"
            )
        entries[(r, c)] = path
    wr, wc = items[0][2]
    suffix = items[0][0].suffix
    if scheme == "pair":
        sep = items[0][0].stem[len(items[0][0].stem) - wc - 1]
        lead = f"{prefix}{sep}" if prefix else ""

        def example(r: int, c: int) -> str:
            return f"{lead}{r:0{wr}d}{sep}{c:0{wc}d}{suffix}"
    else:

        def example(r: int, c: int) -> str:
            return f"{prefix}{r:0{wr}d}{c:0{wc}d}{suffix}"

    return assemble_grid(entries, folder, example, allow_missing=allow_missing)


def _compact_or_linear(folder, images, groups, prefix, items, grid) -> GridLayout:
    """RRCC names; fall back to linear numbering if the RRCC reading has holes."""
    try:
        paths, rows, cols = _pair_layout(items, folder, prefix, "compact", allow_missing=False)
        scheme = "compact"
    except LfsamError:
        # A partial RRCC grid, unless the names read as a complete linear numbering.
        linear = groups.get(("linear", prefix, items[0][0].suffix.lower()))
        try:
            if not linear:
                raise
            paths, rows, cols = linear_layout(linear, folder, grid)
            scheme = "linear"
        except LfsamError:
            paths, rows, cols = _pair_layout(items, folder, prefix, "compact")
            scheme = "compact"
    used = {p for row in paths for p in row if p is not None}
    return GridLayout(
        paths,
        rows,
        cols,
        scheme,
        prefix,
        [p.name for p in images if p not in used],
        (1, 1) if scheme == "linear" else tuple(items[0][2]),
    )


def _index_range(values: list[int], digits: int) -> str:
    first, last = f"{values[0]:0{digits}d}", f"{values[-1]:0{digits}d}"
    return f"{first}..{last}" if len(values) > 1 else first


def read_grid_folder(folder: str | Path, grid: tuple[int, int] | None = None) -> LightField:
    """Read a folder of views named by grid position (see the module docstring).

    Parameters
    ----------
    folder : path-like
        The folder.
    grid : (S, T), optional
        Grid shape for linearly numbered views.

    Returns
    -------
    LightField
        Views only; ``meta`` records the naming scheme, the index ranges and that the
        orientation is as named and not verified.
    """
    layout = scan_grid_folder(folder, grid)
    views, present = read_view_grid(layout.paths, with_present=True)
    naming = {
        "pair": "ROW_COL",
        "compact": "RRCC",
        "linear": "row-major number",
    }[layout.scheme]
    meta = {
        "source": str(folder),
        "format": "grid",
        "naming": f"{layout.prefix!r} + {naming}" if layout.prefix else naming,
        "view_rows": _index_range(layout.rows, layout.digits[0]),
        "view_cols": _index_range(layout.cols, layout.digits[1]),
        "orientation": "as named: first index = view row s (down), second = view column t "
        "(right); not verified (no ground truth)",
    }
    if layout.ignored:
        meta["ignored_files"] = layout.ignored
    return LightField(views, meta=meta, present=present)
