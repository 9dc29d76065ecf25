"""What every export format shares: view file names, object ids, the JSON sidecar.

Views are named ``view_SS_TT`` with ``SS`` the view row and ``TT`` the view column, zero-padded to
the same width, so that sorting the names gives row-major view order (docs/design.md section 8).
Objects are the non-zero label ids of the result, the same id in every view.
"""

from __future__ import annotations

import json
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from lfsam.result import SegmentationResult
from lfsam.version import __version__

__all__ = [
    "SIDECAR",
    "object_ids",
    "parallel",
    "view_name",
    "view_names",
    "write_sidecar",
]

#: Name of the JSON description written into every export folder.
SIDECAR = "lfsam_export.json"


def _digits(grid_shape: tuple[int, int]) -> int:
    return max(2, len(str(max(grid_shape) - 1)))


def view_name(s: int, t: int, grid_shape: tuple[int, int], suffix: str = ".png") -> str:
    """File name of view ``(s, t)``: ``view_SS_TT`` + suffix, zero-padded for the grid."""
    digits = _digits(grid_shape)
    return f"view_{s:0{digits}d}_{t:0{digits}d}{suffix}"


def view_names(result: SegmentationResult, suffix: str = ".png") -> dict[tuple[int, int], str]:
    """``{(s, t): name}`` for the views present, row-major."""
    present = result.present_mask
    s_count, t_count = result.grid_shape
    return {
        (s, t): view_name(s, t, (s_count, t_count), suffix)
        for s in range(s_count)
        for t in range(t_count)
        if present[s, t]
    }


def object_ids(result: SegmentationResult) -> np.ndarray:
    """The non-zero label ids of ``result`` over all views present, sorted (int64)."""
    ids = np.unique(result.labels[result.present_mask])
    return ids[ids != 0].astype(np.int64)


def parallel(function, jobs) -> None:
    """Run ``function(job)`` for every job on a few threads (PNG encoding releases the GIL)."""
    with ThreadPoolExecutor(max_workers=4) as pool:
        for future in [pool.submit(function, job) for job in jobs]:
            future.result()


def write_sidecar(
    folder: Path, result: SegmentationResult, export_format: str, extra: dict[str, Any]
) -> None:
    """Write :data:`SIDECAR`: grid, view size, object ids, source, views present, files."""
    s_count, t_count, rows, cols = result.labels.shape
    description = {
        "format": f"lfsam-export-{export_format}",
        "lfsam_version": __version__,
        "grid": [s_count, t_count],
        "view_size": [rows, cols],
        "center": [s_count // 2, t_count // 2],
        "object_ids": object_ids(result).tolist(),
        "source": str(result.meta.get("input", result.meta.get("source", ""))),
        "method": result.meta.get("method"),
        "views_present": int(result.present_mask.sum()),
        "present": result.present_mask.tolist(),
        "view_order": "row-major: view row s, then view column t; sorted file names agree",
        **extra,
    }
    (folder / SIDECAR).write_text(json.dumps(description, indent=2) + "\n")
