"""Reading light fields from every supported layout, and writing the package's own formats.

:func:`read_lightfield` detects the layout from the path (or takes it by name, see
:data:`FORMATS`) and returns a :class:`~lfsam.lightfield.LightField` whose views are ordered and
whose ground truth is signed in the package's one convention (docs/design.md section 1), with
``meta["source"]`` and ``meta["format"]`` set. :func:`write_lightfield` writes the package's scene
folder (:mod:`lfsam.io.native`) or an ``.npz`` archive (:mod:`lfsam.io.arrays`).

Formats (docs/design.md section 2):

==========  ============================================================================
name        layout
==========  ============================================================================
lfsam       scene folder with ``lfsam_scene.json`` and ``view_RR_CC.png`` (this package)
npz         ``.npz`` with ``views`` [S, T, U, V, 3] (+ ``disparity``, ``labels``, ``meta``)
npy         ``.npy`` holding one [S, T, U, V, 3] array
h5          HDF5 file with a 5-D dataset (``LF``, ``views``, ``data``, ...)
mat         MATLAB file (v5 or v7.3) with a 5-D variable
urbanlf     UrbanLF-Syn / -Real scene folder (``1_1.png``, ``1_1_disparity.npy``, ...)
hci4d       HCI 4D benchmark scene folder (``input_Cam000.png``, ``gt_disp_lowres.pfm``)
hci-old     old HCI archive (``lf.h5`` with ``LF``, ``GT_DEPTH``; ``labels.h5``)
grid        any folder of views named ``[prefix_]ROW_COL.png``, ``RRCC.png`` or by number
==========  ============================================================================
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from lfsam.errors import LfsamError
from lfsam.fileutil import check_output_path
from lfsam.io.arrays import read_h5, read_mat, read_npy, read_npz, write_npz
from lfsam.io.grid_folder import list_images, read_grid_folder
from lfsam.io.hci4d import is_hci4d, read_hci4d
from lfsam.io.hci_old import is_hci_old, read_hci_old
from lfsam.io.images import IMAGE_SUFFIXES
from lfsam.io.native import MARKER, check_scene_target, is_native, read_native, write_native
from lfsam.io.urbanlf import is_urbanlf, read_urbanlf
from lfsam.lightfield import LightField

__all__ = [
    "FORMATS",
    "WRITE_FORMATS",
    "detect_format",
    "read_lightfield",
    "resolve_output",
    "write_lightfield",
]

_READERS: dict[str, Callable[[Path], LightField]] = {
    "lfsam": read_native,
    "npz": read_npz,
    "npy": read_npy,
    "h5": read_h5,
    "mat": read_mat,
    "urbanlf": read_urbanlf,
    "hci4d": read_hci4d,
    "hci-old": read_hci_old,
    "grid": read_grid_folder,
}

#: Names accepted by :func:`read_lightfield` (and ``--format`` on the command line).
FORMATS: tuple[str, ...] = tuple(_READERS)

#: Names accepted by :func:`write_lightfield`.
WRITE_FORMATS: tuple[str, ...] = ("lfsam", "npz")

_ALIASES = {
    "native": "lfsam",
    "lfsam-scene": "lfsam",
    "hdf5": "h5",
    "hci": "hci4d",
    "hci-4d": "hci4d",
    "hci_4d": "hci4d",
    "hci_old": "hci-old",
    "hciold": "hci-old",
    "urban": "urbanlf",
    "urbanlf-syn": "urbanlf",
    "urbanlf-real": "urbanlf",
    "folder": "grid",
}

_FILE_FORMATS = {".npz": "npz", ".npy": "npy", ".mat": "mat"}
_H5_SUFFIXES = (".h5", ".hdf5", ".he5")


def _normalise(fmt: str) -> str:
    name = _ALIASES.get(fmt.lower().strip(), fmt.lower().strip())
    if name not in _READERS:
        raise LfsamError(f"unknown light-field format {fmt!r}; choose one of {', '.join(FORMATS)}")
    return name


def detect_format(path: str | os.PathLike) -> str:
    """The format name of the light field at ``path`` (one of :data:`FORMATS`).

    Parameters
    ----------
    path : path-like
        A file or a folder.

    Returns
    -------
    str

    Raises
    ------
    LfsamError
        If the path is missing or holds no recognisable light field.
    """
    path = Path(path)
    if not path.exists():
        raise LfsamError(f"no such file or folder: {str(path)!r}; check the path")
    if path.is_file():
        suffix = path.suffix.lower()
        if path.name == MARKER:
            return "lfsam"
        if suffix in _FILE_FORMATS:
            return _FILE_FORMATS[suffix]
        if suffix in _H5_SUFFIXES:
            return "hci-old" if is_hci_old(path) else "h5"
        if suffix in IMAGE_SUFFIXES:
            raise LfsamError(
                f"{path} is a single image; give the folder that holds one image per view "
                "(or an .npz/.npy/.h5/.mat array of all views)"
            )
        raise LfsamError(
            f"cannot tell the light-field format of {path} from its suffix; use a folder of "
            "views or .npz/.npy/.h5/.mat, or pass --format"
        )
    if not path.is_dir():
        raise LfsamError(f"{str(path)!r} is neither a file nor a folder")
    if is_native(path):
        return "lfsam"
    if is_hci_old(path):
        return "hci-old"
    if is_hci4d(path):
        return "hci4d"
    if is_urbanlf(path):
        return "urbanlf"
    if list_images(path):
        return "grid"
    if not any(path.iterdir()):
        raise LfsamError(
            f"folder {str(path)!r} is empty; point to a folder of view images or a light-field file"
        )
    raise LfsamError(
        f"no light field found in {str(path)!r} (no view images, no {MARKER}, no lf.h5); "
        "point to a folder of view images or a light-field file"
    )


def read_lightfield(
    path: str | os.PathLike, format: str | None = None, value_range: int | None = None
) -> LightField:
    """Read a light field from any supported layout, in the package convention.

    Parameters
    ----------
    path : path-like
        File or folder (see the table in this module's docstring).
    format : str, optional
        One of :data:`FORMATS` (or an alias such as ``"hci"``); detected from the path if None.
    value_range : {1, 255}, optional
        Whether floating-point views (arrays in npz/npy/h5/mat) are [0, 1] or [0, 255]; None
        decides by the rule of :func:`lfsam.lightfield.float_scale`.

    Returns
    -------
    LightField
        With ``meta["source"]`` (the path) and ``meta["format"]`` (the format name).

    Raises
    ------
    LfsamError
        For a missing path, an unknown format or unreadable or inconsistent data.
    """
    path = Path(path)
    if not path.exists():
        raise LfsamError(f"no such file or folder: {str(path)!r}; check the path")
    name = _normalise(format) if format else detect_format(path)
    folder_formats = ("urbanlf", "hci4d", "grid")
    if name in folder_formats and not path.is_dir():
        raise LfsamError(f"format {name!r} reads a folder, but {str(path)!r} is a file")
    if name in ("npz", "npy", "h5", "mat") and not path.is_file():
        raise LfsamError(f"format {name!r} reads a file, but {str(path)!r} is a folder")
    if name in ("npz", "npy", "h5", "mat"):
        lf = _READERS[name](path, value_range=value_range)
    else:
        lf = _READERS[name](path)
    lf.meta.setdefault("source", str(path))
    lf.meta["format"] = name
    return lf


def resolve_output(path: str | os.PathLike, format: str | None = None) -> str:
    """Check that a light field can be written to ``path``; return the format to write.

    Call it before long work so that a bad output path fails at once.

    Parameters
    ----------
    path : path-like
        Output; a name ending in ``.npz`` means an archive, anything else a scene folder.
    format : {"lfsam", "npz"}, optional
        Overrides the choice by suffix; must agree with it.

    Returns
    -------
    str
        ``"lfsam"`` or ``"npz"``.

    Raises
    ------
    LfsamError
        For an unknown format, a format that disagrees with the suffix, a missing parent
        folder, or a path that must not be replaced.
    """
    path = Path(path)
    by_suffix = "npz" if path.suffix.lower() == ".npz" else "lfsam"
    name = by_suffix if format is None else _ALIASES.get(format.lower(), format.lower())
    if name not in WRITE_FORMATS:
        raise LfsamError(
            f"cannot write format {format!r}; choose one of {', '.join(WRITE_FORMATS)}"
        )
    if name != by_suffix:
        hint = "end the name in .npz" if name == "npz" else "use a name without the .npz suffix"
        raise LfsamError(f"output {str(path)!r} does not fit format {name!r}; {hint}")
    if name == "npz":
        check_output_path(path)
    else:
        check_scene_target(path)
    return name


def write_lightfield(
    lf: LightField,
    path: str | os.PathLike,
    format: str | None = None,
) -> Path:
    """Write a light field in the package's scene-folder format or as ``.npz``.

    Parameters
    ----------
    lf : LightField
        Ground truth in the package convention (as every reader returns it).
    path : path-like
        Output; a name ending in ``.npz`` writes an archive, anything else a scene folder.
    format : {"lfsam", "npz"}, optional
        Overrides the choice by suffix; must agree with it.

    Returns
    -------
    Path
        What was written.

    Raises
    ------
    LfsamError
        For an unknown format, a format that disagrees with the suffix, or an unwritable path
        (see :func:`resolve_output`).
    """
    if resolve_output(path, format) == "npz":
        return write_npz(lf, path)
    return write_native(lf, path)
