"""Portable Float Map (PFM) images, the format of the HCI 4D benchmark's disparity maps.

A PFM file is a three-line ASCII header followed by raw float32 samples:

- ``PF`` (three channels) or ``Pf`` (one channel);
- ``width height``;
- a scale whose sign gives the byte order: negative = little endian, positive = big endian.

Rows are stored bottom-to-top, so the first row of the file is the bottom row of the image
(P. Debevec's PFM description, https://www.pauldebevec.com/Research/HDR/PFM/; the HCI 4D
benchmark's ``file_io.py`` reads it the same way). :func:`read_pfm` returns rows top-to-bottom.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from lfsam.errors import LfsamError
from lfsam.fileutil import atomic_output

__all__ = ["read_pfm", "write_pfm"]


def _read_token(handle, path: Path) -> bytes:
    """Read one whitespace-delimited header token (PFM headers are ASCII)."""
    token = b""
    while True:
        char = handle.read(1)
        if not char:
            raise LfsamError(f"{path} ends inside its PFM header; the file is truncated")
        if char.isspace():
            if token:
                return token
            continue
        token += char
        if len(token) > 32:
            raise LfsamError(f"{path} is not a PFM file (header token too long)")


def read_pfm(path: str | os.PathLike) -> np.ndarray:
    """Read a PFM image.

    Parameters
    ----------
    path : path-like
        The ``.pfm`` file.

    Returns
    -------
    image : ndarray, float32, shape (H, W) for ``Pf`` or (H, W, 3) for ``PF``
        Rows top-to-bottom (the file's bottom-to-top rows are flipped), native byte order.

    Raises
    ------
    LfsamError
        If the file is missing, has a bad header, or holds fewer samples than its header says.
    """
    path = Path(path)
    if not path.is_file():
        raise LfsamError(f"PFM file {str(path)!r} not found; check the path")
    with open(path, "rb") as handle:
        magic = _read_token(handle, path)
        if magic not in (b"PF", b"Pf"):
            raise LfsamError(
                f"{path} is not a PFM file (starts with {magic[:8]!r}, expected 'PF' or 'Pf')"
            )
        try:
            width = int(_read_token(handle, path))
            height = int(_read_token(handle, path))
            scale = float(_read_token(handle, path))
        except ValueError:
            raise LfsamError(f"{path} has a malformed PFM header; re-export the file") from None
        if not (0 < width <= 1 << 16 and 0 < height <= 1 << 16) or not scale or scale != scale:
            raise LfsamError(f"{path} has an invalid PFM header ({width}x{height}, scale {scale})")
        channels = 3 if magic == b"PF" else 1
        dtype = np.dtype("<f4") if scale < 0 else np.dtype(">f4")
        count = width * height * channels
        raw = handle.read(count * 4)
        data = np.frombuffer(raw[: len(raw) // 4 * 4], dtype=dtype)
    if data.size != count:
        raise LfsamError(
            f"{path} holds {data.size} samples but its header says {count}; the file is truncated"
        )
    shape = (height, width, channels) if channels == 3 else (height, width)
    return np.ascontiguousarray(data.reshape(shape)[::-1]).astype(np.float32)


def write_pfm(path: str | os.PathLike, image: np.ndarray) -> None:
    """Write a PFM image (little endian, rows bottom-to-top), atomically.

    Parameters
    ----------
    path : path-like
        Output ``.pfm`` file.
    image : ndarray, shape (H, W) or (H, W, 3)
        Values are stored as float32, rows given top-to-bottom.

    Raises
    ------
    LfsamError
        If ``image`` is not 2-D or 3-channel 3-D.
    """
    image = np.asarray(image)
    if image.ndim == 2:
        magic = b"Pf"
    elif image.ndim == 3 and image.shape[2] == 3:
        magic = b"PF"
    else:
        raise LfsamError(f"PFM images must be (H, W) or (H, W, 3), got shape {image.shape}")
    height, width = image.shape[:2]
    header = magic + f"\n{width} {height}\n-1\n".encode("ascii")
    data = np.ascontiguousarray(image[::-1], dtype="<f4")
    with atomic_output(path) as tmp, open(tmp, "wb") as handle:
        handle.write(header)
        handle.write(data.tobytes())
