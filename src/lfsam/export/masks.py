"""Export as binary masks: one folder per object, one 1-bit PNG per view (docs/design.md
section 8).

``object_NNNN/view_SS_TT.png`` is white where object ``NNNN`` (its label id, the same in every
view) covers view ``(s, t)``. Every object gets a file for every view present (all black where it
is not visible); absent views of a partial grid have no files.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from lfsam.export.common import object_ids, parallel, view_names, write_sidecar
from lfsam.result import SegmentationResult

__all__ = ["object_folder", "write_masks"]


def object_folder(object_id: int, ids: np.ndarray) -> str:
    """Folder name of one object, zero-padded to the widest id (at least 4 digits)."""
    width = max(4, len(str(int(ids.max())))) if ids.size else 4
    return f"object_{int(object_id):0{width}d}"


def write_masks(result: SegmentationResult, folder: Path) -> list[str]:
    """Write ``object_NNNN/view_SS_TT.png`` for every object and view present plus the sidecar.

    Returns
    -------
    folders : list of str
        The object folders, by id.
    """
    ids = object_ids(result)
    names = view_names(result)
    folders = [object_folder(i, ids) for i in ids]
    for name in folders:
        (folder / name).mkdir()

    def save(item) -> None:
        (s, t), name = item
        view = result.labels[s, t]
        for object_id, sub in zip(ids, folders, strict=True):
            Image.fromarray(view == object_id).save(folder / sub / name, format="PNG")

    parallel(save, names.items())
    write_sidecar(
        folder,
        result,
        "masks",
        {
            "objects": dict(zip(folders, ids.tolist(), strict=True)),
            "files": list(names.values()),
            "encoding": "1-bit PNG per object and view, white = object",
        },
    )
    return folders
