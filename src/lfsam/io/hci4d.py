"""The HCI 4D Light Field Benchmark (Honauer et al., ACCV 2016).

A scene folder holds ``input_Cam000.png`` ... ``input_Cam080.png`` (views numbered row-major
from the top-left view of a 9x9 grid, 512x512 pixels), ``gt_disp_lowres.pfm`` (disparity of the
center view, PFM rows bottom-to-top), optionally ``gt_disp_lowres_CamNNN.pfm`` for other views and
``parameters.cfg`` (an INI file with ``num_cams_x``, ``num_cams_y``, ``baseline_mm``, ...).

The benchmark's files follow the package convention as stored (docs/design.md section 1; checked by
photo-consistency in ``tests/test_convention.py``): view ``(s, t)`` sees center pixel ``(u, v)``
at ``(u - d (s - 4), v - d (t - 4))``.
"""

from __future__ import annotations

import configparser
import math
import os
import re
from pathlib import Path

import numpy as np

from lfsam.errors import LfsamError
from lfsam.io.grid_folder import linear_layout
from lfsam.io.images import read_view_grid
from lfsam.io.pfm import read_pfm
from lfsam.lightfield import LightField

__all__ = ["is_hci4d", "read_hci4d", "read_parameters"]

_VIEW = re.compile(r"^input_Cam(\d+)\.png$", re.IGNORECASE)
_GT_VIEW = re.compile(r"^gt_disp_lowres_Cam(\d+)\.pfm$", re.IGNORECASE)


def is_hci4d(folder: Path) -> bool:
    """Whether ``folder`` looks like an HCI 4D scene (has ``input_Cam000.png``-style views)."""
    return folder.is_dir() and any(_VIEW.match(p.name) for p in folder.iterdir())


def _number(text: str):
    try:
        return int(text)
    except ValueError:
        try:
            return float(text)
        except ValueError:
            return text


def read_parameters(path: str | os.PathLike) -> dict[str, dict[str, object]]:
    """Parse an HCI 4D ``parameters.cfg`` into ``{section: {key: number or text}}``."""
    parser = configparser.ConfigParser()
    try:
        parser.read(path)
    except (configparser.Error, UnicodeDecodeError) as exc:
        raise LfsamError(f"cannot parse {path} ({exc}); fix or remove the file") from None
    return {
        section: {key: _number(value) for key, value in parser[section].items()}
        for section in parser.sections()
    }


def read_hci4d(folder: str | os.PathLike) -> LightField:
    """Read an HCI 4D benchmark scene folder.

    Parameters
    ----------
    folder : path-like
        The scene folder.

    Views may be missing (partial grids such as the "star" subsets that keep 33 of the 81 views
    with their original names): the grid position of each view comes from its number and the
    light field's ``present`` flags the views found (docs/design.md section 8).

    Returns
    -------
    LightField
        Views ``[S, T, U, V, 3]``; disparity of every view when every ``gt_disp_lowres_CamNNN.pfm``
        exists, else of the center view from ``gt_disp_lowres.pfm`` when present; ``meta`` holds
        the parsed ``parameters.cfg`` under ``parameters``.

    Raises
    ------
    LfsamError
        If views are missing or the ground truth does not match the view size.
    """
    folder = Path(folder)
    items = []
    gt_files: dict[int, Path] = {}
    for path in sorted(folder.iterdir()):
        match = _VIEW.match(path.name)
        if match:
            items.append((path, (int(match.group(1)),), (len(match.group(1)),)))
        match = _GT_VIEW.match(path.name)
        if match:
            gt_files[int(match.group(1))] = path
    if not items:
        raise LfsamError(
            f"no input_CamNNN.png views in {folder}; is this an HCI 4D benchmark scene?"
        )
    parameters: dict = {}
    grid = None
    cfg = folder / "parameters.cfg"
    if cfg.is_file():
        parameters = read_parameters(cfg)
        extrinsics = parameters.get("extrinsics", {})
        if isinstance(extrinsics.get("num_cams_y"), int) and isinstance(
            extrinsics.get("num_cams_x"), int
        ):
            grid = (extrinsics["num_cams_y"], extrinsics["num_cams_x"])
    paths, first = _layout(items, folder, grid)
    views, present = read_view_grid(paths, with_present=True)
    s_count, t_count = views.shape[:2]
    center_index = first + (s_count // 2) * t_count + t_count // 2
    disparity = None
    all_views = [first + i for i in range(s_count * t_count)]
    if all(i in gt_files for i in all_views) and _shapes_match(
        gt_files, all_views, views.shape[2:4]
    ):
        disparity = np.stack([read_pfm(gt_files[i]) for i in all_views]).reshape(
            s_count, t_count, *views.shape[2:4]
        )
    if disparity is None:
        center_file = folder / "gt_disp_lowres.pfm"
        if not center_file.is_file() and center_index in gt_files:
            center_file = gt_files[center_index]
        if center_file.is_file():
            disparity = read_pfm(center_file)
            if disparity.shape != views.shape[2:4]:
                raise LfsamError(
                    f"{center_file.name} is {disparity.shape[0]}x{disparity.shape[1]} but the "
                    f"views are {views.shape[2]}x{views.shape[3]}; use the low-resolution "
                    "ground truth that matches the views"
                )
    meta = {
        "source": str(folder),
        "format": "hci4d",
        "orientation": "as stored (HCI 4D: views row-major from the top-left, disparity as "
        "stored) = package convention",
    }
    if parameters:
        meta["parameters"] = parameters
    return LightField(views, disparity=disparity, meta=meta, present=present)


def _layout(items, folder: Path, grid: tuple[int, int] | None):
    """Paths of the grid (None for missing views) and the number of view (0, 0).

    A complete, consecutively numbered set keeps its own first number. Otherwise the set is a
    partial grid (e.g. the "star" subsets: center row, center column and diagonals, 33 of 81)
    numbered as in the benchmark, ``input_Cam000`` = top-left view; the grid is the one of
    ``parameters.cfg``, else the smallest square holding the highest number.
    """
    try:
        paths, _, _ = linear_layout(items, folder, grid)
        return paths, min(index for _, (index,), _ in items)
    except LfsamError as complete_error:
        highest = max(index for _, (index,), _ in items)
        if grid is None:
            side = math.isqrt(highest)
            side += 1 if side * side <= highest else 0
            grid = (side, side)
        if highest >= grid[0] * grid[1] or len(items) > grid[0] * grid[1]:
            raise complete_error from None
        paths, _, _ = linear_layout(items, folder, grid, partial_start=0)
        return paths, 0


def _shapes_match(gt_files: dict[int, Path], indices: list[int], shape) -> bool:
    """Whether every per-view PFM has the view size (read from the headers only)."""
    for index in indices:
        with open(gt_files[index], "rb") as handle:
            header = handle.read(64).split()
        try:
            if (int(header[2]), int(header[1])) != tuple(shape):
                return False
        except (IndexError, ValueError):
            return False
    return True
