"""Export as one 16-bit label PNG per view (docs/design.md section 8).

``view_SS_TT.png`` holds the label field of view ``(s, t)`` (0 = unlabeled, else the object id,
the same in every view) as a 16-bit grayscale PNG; absent views of a partial grid have no file and
are flagged in the sidecar's ``present``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from lfsam.errors import LfsamError
from lfsam.export.common import object_ids, parallel, view_names, write_sidecar
from lfsam.result import SegmentationResult

__all__ = ["MAX_ID", "write_png"]

#: The largest id a 16-bit PNG holds.
MAX_ID = 65535


def write_png(result: SegmentationResult, folder: Path) -> list[str]:
    """Write every view present as ``view_SS_TT.png`` (uint16 labels) plus the sidecar.

    Returns
    -------
    names : list of str
        The PNG files written, row-major.

    Raises
    ------
    LfsamError
        If a label id does not fit 16 bits.
    """
    ids = object_ids(result)
    if ids.size and ids[-1] > MAX_ID:
        raise LfsamError(
            f"label id {int(ids[-1])} does not fit a 16-bit PNG (max {MAX_ID}); "
            "export with --to npy instead"
        )
    names = view_names(result)

    def save(item) -> None:
        (s, t), name = item
        image = Image.fromarray(np.ascontiguousarray(result.labels[s, t], dtype=np.uint16))
        image.save(folder / name, format="PNG")

    parallel(save, names.items())
    write_sidecar(
        folder,
        result,
        "png",
        {"files": list(names.values()), "encoding": "16-bit grayscale, value = object id"},
    )
    return list(names.values())
