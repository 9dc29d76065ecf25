"""Reading and writing the sub-aperture images of a light field, in parallel.

Decoding 81 PNG views of 512x512 pixels one after the other takes seconds; Pillow releases the
GIL while it decodes and encodes, so a thread pool scales with the cores. Every problem with one
file (unreadable, different size) becomes a one-line :class:`~lfsam.errors.LfsamError` that names
the file.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
from PIL import Image
from tqdm import tqdm

from lfsam.errors import LfsamError

__all__ = [
    "IMAGE_SUFFIXES",
    "image_size",
    "read_image",
    "read_view_grid",
    "write_view_grid",
]

#: File suffixes read as images (lower case).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".ppm", ".webp")


def _workers() -> int:
    return max(1, min(8, os.cpu_count() or 1))


def image_size(path: Path) -> tuple[int, int]:
    """``(rows, columns)`` of an image, from its header only.

    Raises
    ------
    LfsamError
        If the file cannot be opened as an image.
    """
    try:
        with Image.open(path) as image:
            width, height = image.size
    except Exception as exc:  # any decoder failure on a damaged file
        raise LfsamError(
            f"cannot read image {str(path)!r} ({type(exc).__name__}); replace or remove the file"
        ) from None
    return height, width


def read_image(path: str | os.PathLike) -> np.ndarray:
    """Read one image as RGB uint8 ``(rows, columns, 3)``.

    Grayscale images are repeated into three channels, an alpha channel is dropped and 16-bit
    images are scaled to 8 bits.

    Raises
    ------
    LfsamError
        If the file is missing or cannot be decoded.
    """
    path = Path(path)
    try:
        with Image.open(path) as image:
            image.load()
            mode = image.mode
            if mode in ("I;16", "I;16B", "I;16L", "I"):
                array = np.asarray(image).astype(np.int64)
                peak = 65535 if mode.startswith("I;16") or array.max() > 255 else 255
                gray = np.clip(array * 255 // peak, 0, 255).astype(np.uint8)
                return np.repeat(gray[..., None], 3, axis=2)
            if mode != "RGB":
                image = image.convert("RGB")
            return np.asarray(image, dtype=np.uint8)
    except FileNotFoundError:
        raise LfsamError(f"image {str(path)!r} not found; check the path") from None
    except Exception as exc:  # any decoder failure on a damaged file (zlib, struct, ...)
        raise LfsamError(
            f"cannot read image {str(path)!r} ({type(exc).__name__}: {exc}); "
            "replace or remove the file"
        ) from None


def read_view_grid(
    paths: Sequence[Sequence[Path | None]],
    desc: str = "reading views",
    with_present: bool = False,
):
    """Read a grid of view images into one ``(S, T, U, V, 3)`` uint8 array, in parallel.

    Parameters
    ----------
    paths : S x T nested sequence of paths
        ``paths[s][t]`` is the image of view ``(s, t)``, or None for a missing view of a partial
        grid (left all zero; docs/design.md section 8).
    desc : str
        Label of the progress bar (shown on a terminal only).
    with_present : bool
        Also return the ``(S, T)`` bool mask of the views read.

    Returns
    -------
    views : ndarray, (S, T, U, V, 3), uint8
    present : ndarray, (S, T), bool
        Only with ``with_present``.

    Raises
    ------
    LfsamError
        If an image cannot be read or the views differ in size (the message names both files).
    """
    s_count, t_count = len(paths), len(paths[0])
    flat = [None if p is None else Path(p) for row in paths for p in row]
    present = np.array([p is not None for p in flat]).reshape(s_count, t_count)
    first = next(p for p in flat if p is not None)
    first_shape = image_size(first)
    views = np.zeros((s_count * t_count, *first_shape, 3), dtype=np.uint8)

    def load(index: int) -> None:
        image = read_image(flat[index])
        if image.shape[:2] != first_shape:
            raise LfsamError(
                f"views differ in size: {flat[index].name} is {image.shape[0]}x{image.shape[1]} "
                f"but {first.name} is {first_shape[0]}x{first_shape[1]} (rows x columns); "
                "all views of a light field must have the same size"
            )
        views[index] = image

    with ThreadPoolExecutor(max_workers=_workers()) as pool:
        futures = [pool.submit(load, i) for i, p in enumerate(flat) if p is not None]
        for future in tqdm(futures, desc=desc, unit="view", disable=None, leave=False):
            future.result()
    views = views.reshape(s_count, t_count, *first_shape, 3)
    return (views, present) if with_present else views


def write_view_grid(
    views: np.ndarray, folder: Path, pattern: str, compress_level: int = 6
) -> list[str]:
    """Write every view of ``views`` as a PNG in ``folder``, in parallel.

    Parameters
    ----------
    views : ndarray, (S, T, U, V, 3), uint8
    folder : Path
        An existing folder.
    pattern : str
        File name with ``{s}`` and ``{t}`` fields, e.g. ``"view_{s:02d}_{t:02d}.png"``.
    compress_level : int
        zlib level of the PNG encoder (0-9); the output is byte-identical for equal input.

    Returns
    -------
    names : list of str
        The file names written, row-major.
    """
    s_count, t_count = views.shape[:2]
    jobs = [(s, t, pattern.format(s=s, t=t)) for s in range(s_count) for t in range(t_count)]

    def save(job: tuple[int, int, str]) -> None:
        s, t, name = job
        Image.fromarray(np.ascontiguousarray(views[s, t])).save(
            folder / name, format="PNG", compress_level=compress_level
        )

    with ThreadPoolExecutor(max_workers=_workers()) as pool:
        futures = [pool.submit(save, job) for job in jobs]
        for future in tqdm(futures, desc="writing views", unit="view", disable=None, leave=False):
            future.result()
    return [name for _, _, name in jobs]
