"""The package's own light-field format: a folder any image viewer can open.

Layout of a scene folder (version 1)::

    lfsam_scene.json      marker and description (below)
    view_00_00.png ...    one RGB PNG per view, view_RR_CC.png, 0-based, zero-padded to
                          2 digits or more; RR = view row s (down), CC = view column t (right)
    disparity.npy         optional ground-truth disparity, float32, [S, T, U, V] or center [U, V]
    labels.npy            optional ground-truth labels, int32, same shapes, 0 = no label

``lfsam_scene.json`` holds ``format: "lfsam-scene"``, ``version``, ``grid`` [S, T],
``view_size`` [U, V], ``center``, ``views`` (the file-name pattern), ``disparity`` and ``labels``
(``"all views"``, ``"center"`` or null), optional ``camera`` (focal length in pixels, baseline
and focus distance in metres: :mod:`lfsam.camera`, docs/design.md section 11), optional
``categories`` (label id -> category name, e.g. ``{"2": "brick disc"}``; docs/design.md section
9), the disparity ``convention`` in words,
and ``meta`` (free JSON: where the scene came from, the orientation applied on import,
generator settings). Disparity is always in the package's convention (docs/design.md section
1), so a scene converted from any data set reads back without further checks.

A scene is written into a temporary folder next to the target and renamed onto it only when
complete (:func:`lfsam.fileutil.atomic_folder_output`), so a failed write leaves no partial
scene.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from lfsam.errors import LfsamError
from lfsam.fileutil import atomic_folder_output
from lfsam.io.images import read_view_grid, write_view_grid
from lfsam.lightfield import LightField, categories_from_json, categories_to_json

__all__ = [
    "MARKER",
    "SCENE_FORMAT",
    "VERSION",
    "check_scene_target",
    "json_safe",
    "read_native",
    "write_native",
]

MARKER = "lfsam_scene.json"
SCENE_FORMAT = "lfsam-scene"
VERSION = 1
CONVENTION = (
    "a point at pixel (u, v) of view (s, t) with disparity d is at (u - d (s' - s), "
    "v - d (t' - t)) in view (s', t'); s = view row (down), t = view column (right), "
    "u = pixel row, v = pixel column; larger disparity = closer"
)


def json_safe(value: Any) -> Any:
    """A JSON-serialisable copy of ``value``; NumPy scalars become numbers, other objects drop.

    Dictionaries keep only keys whose values can be represented.
    """
    if isinstance(value, dict):
        out = {}
        for key, item in value.items():
            converted = json_safe(item)
            if converted is not None or item is None:
                out[str(key)] = converted
        return out
    if isinstance(value, (list, tuple)):
        return [json_safe(item) for item in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if np.isfinite(value) else None
    if isinstance(value, (str, os.PathLike)):
        return str(value)
    if isinstance(value, np.ndarray) and value.size <= 64:
        return json_safe(value.tolist())
    return None


def _extent(array: np.ndarray | None) -> str | None:
    if array is None:
        return None
    return "all views" if array.ndim == 4 else "center"


def _view_digits(grid_shape: tuple[int, int]) -> int:
    return max(2, len(str(max(grid_shape) - 1)))


def _view_pattern(digits: int) -> str:
    return f"view_{{s:0{digits}d}}_{{t:0{digits}d}}.png"


def check_scene_target(path: str | os.PathLike) -> Path:
    """Check that a scene folder may be written at ``path``.

    Raises
    ------
    LfsamError
        If the parent folder is missing, or ``path`` is a file or a non-empty folder that is
        not an lfsam scene (lfsam only replaces its own scene folders).
    """
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise LfsamError(
            f"output folder {str(parent)!r} does not exist; create it (mkdir -p {parent}) first"
        )
    if path.exists():
        if not path.is_dir():
            raise LfsamError(f"{str(path)!r} is a file; give a new folder name for the scene")
        if any(path.iterdir()) and not (path / MARKER).is_file():
            raise LfsamError(
                f"{str(path)!r} is a non-empty folder that is not an lfsam scene; "
                "choose a new folder name (lfsam only replaces its own scene folders)"
            )
    return path


def write_native(lf: LightField, path: str | os.PathLike, compress_level: int = 6) -> Path:
    """Write ``lf`` as a scene folder, atomically.

    Parameters
    ----------
    lf : LightField
        The light field (ground truth in the package convention).
    path : path-like
        The scene folder to create. An existing scene folder (or an empty folder) is replaced;
        any other existing path is refused.
    compress_level : int
        PNG zlib level (0-9). The bytes written depend only on ``lf`` and this level.

    Returns
    -------
    Path
        The scene folder.

    Raises
    ------
    LfsamError
        If the parent folder is missing or ``path`` is a file or a folder that is not a scene.
    """
    path = check_scene_target(path)
    digits = _view_digits(lf.grid_shape)
    pattern = _view_pattern(digits)
    description = {
        "format": SCENE_FORMAT,
        "version": VERSION,
        "grid": list(lf.grid_shape),
        "view_size": list(lf.view_shape),
        "center": list(lf.center),
        "views": "view_{s}_{t}.png",
        "view_digits": digits,
        "disparity": _extent(lf.disparity),
        "labels": _extent(lf.labels),
        "categories": None if lf.categories is None else categories_to_json(lf.categories),
        "present": None if lf.is_complete else lf.present.tolist(),
        "convention": CONVENTION,
        "camera": json_safe(lf.meta.get("camera")),
        "meta": json_safe({k: v for k, v in lf.meta.items() if k != "camera"}),
    }
    with atomic_folder_output(path, mode=0o755) as tmp:
        write_view_grid(lf.views, tmp, pattern, compress_level=compress_level)
        for s, t in zip(*np.nonzero(~lf.present), strict=True):  # absent views: no file
            (tmp / pattern.format(s=s, t=t)).unlink()
        if lf.disparity is not None:
            np.save(tmp / "disparity.npy", lf.disparity.astype(np.float32))
        if lf.labels is not None:
            np.save(tmp / "labels.npy", lf.labels.astype(np.int32))
        (tmp / MARKER).write_text(json.dumps(description, indent=2, sort_keys=True) + "\n")
    return path


def is_native(path: Path) -> bool:
    """Whether ``path`` is a scene folder (or its ``lfsam_scene.json``)."""
    return (path.is_dir() and (path / MARKER).is_file()) or path.name == MARKER


def _load_gt(path: Path, name: str) -> np.ndarray:
    try:
        return np.load(path, allow_pickle=False)
    except Exception as exc:  # any NumPy failure on a damaged file
        raise LfsamError(
            f"cannot read {name} {str(path)!r} ({exc}); the scene is damaged, re-create it"
        ) from None


def read_native(path: str | os.PathLike) -> LightField:
    """Read a scene folder written by :func:`write_native`.

    Parameters
    ----------
    path : path-like
        The scene folder or its ``lfsam_scene.json``.

    Returns
    -------
    LightField
        ``meta`` is the stored meta with ``source`` and ``format`` set to this folder; where the
        scene itself came from moves to ``converted_from``.

    Raises
    ------
    LfsamError
        If the description is unreadable, of a newer version, or a file is missing.
    """
    path = Path(path)
    folder = path.parent if path.name == MARKER else path
    marker = folder / MARKER
    try:
        description = json.loads(marker.read_text())
    except FileNotFoundError:
        raise LfsamError(f"{str(folder)!r} is not an lfsam scene (no {MARKER})") from None
    except (OSError, ValueError) as exc:
        raise LfsamError(f"cannot read {marker} ({exc}); re-create the scene") from None
    if not isinstance(description, dict) or description.get("format") != SCENE_FORMAT:
        raise LfsamError(f"{marker} is not an lfsam scene description; re-create the scene")
    if int(description.get("version", 0)) > VERSION:
        raise LfsamError(
            f"{folder} was written by a newer lfsam (scene version {description['version']}); "
            "upgrade lfsam"
        )
    try:
        s_count, t_count = (int(x) for x in description["grid"])
        digits = int(description.get("view_digits", 2))
        valid = min(s_count, t_count) >= 1 and s_count * t_count <= 100_000 and 1 <= digits <= 6
    except (KeyError, TypeError, ValueError, OverflowError):
        valid = False
    if not valid:
        raise LfsamError(f"{marker} has no valid 'grid'; re-create the scene")
    pattern = _view_pattern(digits)
    present = description.get("present")
    try:
        present = np.ones((s_count, t_count), bool) if present is None else np.array(present)
    except ValueError:
        present = None
    if present is None or present.shape != (s_count, t_count) or present.dtype != bool:
        raise LfsamError(f"{marker} has an invalid 'present'; re-create the scene")
    paths = [
        [folder / pattern.format(s=s, t=t) if present[s, t] else None for t in range(t_count)]
        for s in range(s_count)
    ]
    missing = [p for row in paths for p in row if p is not None and not p.is_file()]
    if missing:
        raise LfsamError(
            f"scene {folder} lacks view {missing[0].name}"
            + (f" and {len(missing) - 1} more" if len(missing) > 1 else "")
            + "; re-create or re-convert the scene"
        )
    views = read_view_grid(paths)
    disparity = labels = None
    if description.get("disparity"):
        disparity = _load_gt(folder / "disparity.npy", "disparity")
    if description.get("labels"):
        labels = _load_gt(folder / "labels.npy", "labels")
    categories = description.get("categories")
    if categories is not None:
        categories = categories_from_json(categories, f"{marker}: categories")
    meta = dict(description.get("meta") or {})
    old_source, old_format = meta.pop("source", None), meta.pop("format", None)
    if old_source is not None or old_format is not None:
        meta["converted_from"] = f"{old_format or '?'}: {old_source or '?'}"
    meta.update(source=str(folder), format="lfsam")
    if description.get("camera") is not None:
        meta["camera"] = description["camera"]
    return LightField(
        views, disparity=disparity, labels=labels, meta=meta, present=present,
        categories=categories if labels is not None else None,
    )
