"""Export as NumPy arrays (docs/design.md section 8).

``labels.npy`` is the label field ``[S, T, U, V]`` (int32, 0 = unlabeled); ``masks.npy`` the
per-object masks ``[K, S, T, U, V]`` (bool) of the objects in ``ids.npy`` (``masks[k]`` is
``labels == ids[k]``); ``present.npy`` the ``[S, T]`` flags of the views that exist (absent views
are all zero). ``masks.npy`` is written one object at a time, so it never has to fit in memory;
read it with ``np.load(..., mmap_mode="r")``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lfsam.export.common import object_ids, write_sidecar
from lfsam.result import SegmentationResult

__all__ = ["write_npy"]


def write_npy(result: SegmentationResult, folder: Path) -> list[str]:
    """Write ``labels.npy``, ``ids.npy``, ``masks.npy``, ``present.npy`` and the sidecar.

    Returns
    -------
    names : list of str
        The array files written.
    """
    ids = object_ids(result)
    labels = np.asarray(result.labels, dtype=np.int32)
    np.save(folder / "labels.npy", labels)
    np.save(folder / "ids.npy", ids)
    np.save(folder / "present.npy", result.present_mask)
    masks = np.lib.format.open_memmap(
        folder / "masks.npy", mode="w+", dtype=bool, shape=(len(ids), *labels.shape)
    )
    for index, object_id in enumerate(ids):
        masks[index] = labels == object_id
    masks.flush()
    del masks
    names = ["labels.npy", "ids.npy", "masks.npy", "present.npy"]
    write_sidecar(
        folder,
        result,
        "npy",
        {"files": names, "masks": "masks.npy[k] = (labels == ids[k]), shape [K, S, T, U, V]"},
    )
    return names
