"""Writing what ``lfsam render`` and the viewer's "lfsam render" dock make: images, coverage
maps and removed light fields.

Every output is written atomically (:mod:`lfsam.fileutil`): complete or absent. A removed light
field is an ordinary light field in lfsam's native format (a scene folder of PNG views, or
``.npz``), so ``lfsam info``, ``segment``, ``disparity`` and ``view`` read it; the pixels no
view saw (inpainted) are flagged in ``inpainted.npy`` (bool ``[S, T, U, V]``), a file of the
folder or a member of the archive (docs/design.md section 13).

The command line (:mod:`lfsam.cli.render`) and the viewer (:mod:`lfsam.viewer.render_dock`)
write the same files through this same code.
"""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import numpy as np

from lfsam.fileutil import atomic_folder_output, atomic_output
from lfsam.io import resolve_output, write_lightfield
from lfsam.io.native import check_scene_target
from lfsam.lightfield import LightField
from lfsam.viz import save_image

__all__ = ["FLAG_NAME", "read_flags", "write_coverage", "write_image", "write_removed"]

#: Name of the flag mask of inpainted pixels, in the folder or the archive.
FLAG_NAME = "inpainted.npy"


def write_image(path: str | os.PathLike, image: np.ndarray) -> Path:
    """An RGB float image in [0, 255], rounded to uint8 (atomic)."""
    return save_image(path, np.clip(np.round(image), 0, 255).astype(np.uint8))


def write_coverage(path: str | os.PathLike, coverage: np.ndarray) -> Path:
    """The share of views that saw each pixel as a gray PNG (0 = none, 255 = all)."""
    gray = np.clip(np.round(coverage * 255.0), 0, 255).astype(np.uint8)
    return save_image(path, np.repeat(gray[..., None], 3, axis=-1))


def write_removed(lf: LightField, flags: np.ndarray, path: str | os.PathLike) -> Path:
    """The removed light field ``lf`` with its flag mask, as a scene folder or ``.npz``."""
    flags = np.asarray(flags, dtype=bool)
    if resolve_output(path) == "npz":
        with atomic_output(path) as tmp:
            write_lightfield(lf, tmp, format="npz")
            with zipfile.ZipFile(tmp, "a", compression=zipfile.ZIP_DEFLATED) as archive:
                info = zipfile.ZipInfo(FLAG_NAME, date_time=(1980, 1, 1, 0, 0, 0))
                info.compress_type = zipfile.ZIP_DEFLATED
                info.external_attr = 0o644 << 16
                with archive.open(info, "w", force_zip64=True) as member:
                    np.lib.format.write_array(member, flags, allow_pickle=False)
        return Path(path)
    target = check_scene_target(path)
    with atomic_folder_output(target, mode=0o755) as tmp:
        write_lightfield(lf, tmp)
        np.save(tmp / FLAG_NAME, flags)
    return target


def read_flags(path: str | os.PathLike) -> np.ndarray:
    """The flag mask of a removed light field written by :func:`write_removed`."""
    path = Path(path)
    if path.is_dir():
        return np.load(path / FLAG_NAME)
    with np.load(path) as archive:
        return archive[FLAG_NAME.removesuffix(".npy")]
