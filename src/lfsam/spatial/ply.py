"""PLY point clouds: binary little-endian ``x y z`` (float32) and ``red green blue`` (uint8).

The format of the Stanford PLY files that Open3D, MeshLab, CloudCompare and ``plyfile`` read
(Turk, "The PLY polygon file format", 1994); ``lfsam export --to ply`` writes one per object
(docs/design.md section 11). Files are written atomically
(:func:`lfsam.fileutil.atomic_output`): a failed write leaves no partial file.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from lfsam.errors import LfsamError
from lfsam.fileutil import atomic_output

__all__ = ["read_ply", "write_ply"]

#: One vertex on disk: three little-endian float32 and three bytes (15 bytes, no padding).
VERTEX = np.dtype(
    [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"), ("green", "u1"), ("blue", "u1")]
)


def write_ply(
    path: str | os.PathLike,
    xyz: np.ndarray,
    rgb: np.ndarray,
    comments: list[str] | tuple[str, ...] = (),
) -> Path:
    """Write ``N`` coloured points as a binary little-endian PLY file, atomically.

    Parameters
    ----------
    path : path-like
    xyz : (N, 3) float array
        Coordinates (stored as float32).
    rgb : (N, 3) uint8 array
        Colours.
    comments : sequence of str
        Header comments (one line each; e.g. the units and the frame).

    Returns
    -------
    Path

    Raises
    ------
    ValueError
        If ``xyz`` and ``rgb`` are not both ``(N, 3)`` (the caller's arrays are wrong).

    Examples
    --------
    >>> import tempfile, numpy as np
    >>> path = write_ply(tempfile.mkdtemp() + "/p.ply", np.zeros((2, 3)), np.zeros((2, 3), "u1"))
    >>> xyz, rgb = read_ply(path)
    >>> xyz.shape, rgb.dtype
    ((2, 3), dtype('uint8'))
    """
    xyz = np.asarray(xyz)
    rgb = np.asarray(rgb)
    if xyz.ndim != 2 or xyz.shape[1] != 3 or rgb.shape != xyz.shape:
        raise ValueError(f"need (N, 3) points and colours, got {xyz.shape} and {rgb.shape}")
    vertices = np.empty(len(xyz), dtype=VERTEX)
    for axis, name in enumerate("xyz"):
        vertices[name] = xyz[:, axis]
    for axis, name in enumerate(("red", "green", "blue")):
        vertices[name] = rgb[:, axis]
    header = ["ply", "format binary_little_endian 1.0"]
    header += [f"comment {line.replace(chr(10), ' ')}" for line in comments]
    header += [f"element vertex {len(vertices)}"]
    header += [f"property float {name}" for name in "xyz"]
    header += [f"property uchar {name}" for name in ("red", "green", "blue")]
    header += ["end_header"]
    path = Path(path)
    with atomic_output(path) as tmp, open(tmp, "wb") as handle:
        handle.write(("\n".join(header) + "\n").encode("ascii"))
        handle.write(vertices.tobytes())
    return path


def read_ply(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Read a file written by :func:`write_ply`: ``(N, 3)`` float32 points, ``(N, 3)`` uint8
    colours.

    Raises
    ------
    LfsamError
        If the file is not a binary little-endian PLY with exactly these vertex properties.
    """
    path = Path(path)
    with open(path, "rb") as handle:
        lines = []
        while True:
            line = handle.readline()
            if not line:
                raise LfsamError(f"{path}: no end_header; not a complete PLY file")
            text = line.decode("ascii", errors="replace").strip()
            lines.append(text)
            if text == "end_header":
                break
        body = handle.read()
    if lines[0] != "ply" or "format binary_little_endian 1.0" not in lines:
        raise LfsamError(f"{path} is not a binary little-endian PLY file")
    properties = [line.split()[-1] for line in lines if line.startswith("property")]
    if properties != list(VERTEX.names):
        raise LfsamError(f"{path}: vertex properties {properties}, expected {VERTEX.names}")
    count = next(int(line.split()[-1]) for line in lines if line.startswith("element vertex"))
    if len(body) != count * VERTEX.itemsize:
        raise LfsamError(f"{path}: {len(body)} data bytes for {count} vertices; file truncated")
    vertices = np.frombuffer(body, dtype=VERTEX)
    xyz = np.stack([vertices[name] for name in "xyz"], axis=1).astype(np.float32)
    rgb = np.stack([vertices[name] for name in ("red", "green", "blue")], axis=1)
    return xyz, rgb.astype(np.uint8)
