"""Textures for the synthetic scenes: photographs shipped with scikit-image and procedural ones.

Every texture is a function of its name, a seed and an output size, so a scene description stays
small and renders identically every time. Photographs are random crops of scikit-image's sample
images (``skimage.data``; the grayscale ones are tinted between two random colours); procedural
textures are multi-octave value noise, rotated checkerboards, stripes and dots. All are
richly textured, so that disparity estimation and feature matching have something to work with.
"""

from __future__ import annotations

import functools

import numpy as np
import torch
import torch.nn.functional as F

from lfsam.errors import LfsamError

__all__ = ["GRAY_PHOTOS", "PHOTOS", "PROCEDURAL", "TEXTURES", "make_texture"]

#: Colour photographs from :mod:`skimage.data`.
PHOTOS = ("astronaut", "coffee", "chelsea", "rocket", "immunohistochemistry")
#: Grayscale photographs from :mod:`skimage.data`, tinted.
GRAY_PHOTOS = ("brick", "grass", "gravel", "camera")
#: Procedural textures.
PROCEDURAL = ("noise", "checker", "stripes", "dots")
#: Every texture name.
TEXTURES = PHOTOS + GRAY_PHOTOS + PROCEDURAL


@functools.lru_cache(maxsize=16)
def _photo(name: str) -> torch.Tensor:
    """A scikit-image sample image as float32 ``[3, H, W]`` in [0, 1]."""
    import skimage.data

    image = np.asarray(getattr(skimage.data, name)())
    if image.ndim == 2:
        image = image[..., None]
    image = image[..., :3].astype(np.float32) / 255.0
    return torch.from_numpy(np.ascontiguousarray(image.transpose(2, 0, 1)))


def _resize(image: torch.Tensor, size: tuple[int, int]) -> torch.Tensor:
    """Resize ``[C, H, W]`` to ``size`` with an anti-aliasing filter when shrinking."""
    return F.interpolate(
        image[None], size=size, mode="bilinear", align_corners=False, antialias=True
    )[0].clamp(0.0, 1.0)


def _random_colour(rng: np.random.Generator, low: float = 0.05, high: float = 0.95) -> torch.Tensor:
    return torch.tensor(rng.uniform(low, high, size=3), dtype=torch.float32)[:, None, None]


def _tint(gray: torch.Tensor, rng: np.random.Generator) -> torch.Tensor:
    """Map a ``[1, H, W]`` gray image between two random, clearly different colours."""
    dark = _random_colour(rng, 0.0, 0.45)
    light = _random_colour(rng, 0.55, 1.0)
    return dark + (light - dark) * gray


def _photo_crop(
    name: str, rng: np.random.Generator, size: tuple[int, int], zoom: float
) -> torch.Tensor:
    image = _photo(name)
    _, height, width = image.shape
    aspect = size[1] / size[0]
    # About one photo pixel per output pixel / zoom (so photos keep their fine detail), within
    # the largest crop of the wanted aspect, at a random place.
    crop_h = min(height, width / aspect)
    wanted = size[0] / zoom * rng.uniform(0.8, 1.25)
    ch = max(8, int(min(crop_h, wanted)))
    cw = max(8, min(width, int(ch * aspect)))
    top = int(rng.integers(0, height - ch + 1))
    left = int(rng.integers(0, width - cw + 1))
    crop = image[:, top : top + ch, left : left + cw]
    if rng.random() < 0.5:
        crop = crop.flip(-1)
    crop = _resize(crop, size)
    return _tint(crop, rng) if crop.shape[0] == 1 else crop


def _value_noise(rng: np.random.Generator, size: tuple[int, int], zoom: float) -> torch.Tensor:
    """Fractal value noise ``[1, H, W]`` in [0, 1]: random grids upsampled bicubically, from
    3 cells across down to cells of about 3 displayed pixels (``3 zoom`` texture pixels),
    amplitude x0.8 per octave."""
    height, width = size
    total = torch.zeros(1, 1, height, width)
    weight_sum = 0.0
    finest = max(4, int(max(height, width) / (3.0 * zoom)))
    cells, weight = 3, 1.0
    while True:
        grid = torch.tensor(rng.random((1, 1, cells, cells)), dtype=torch.float32)
        total += F.interpolate(grid, size=size, mode="bicubic", align_corners=False) * weight
        weight_sum += weight
        if cells >= finest:
            break
        cells, weight = min(cells * 2, finest), weight * 0.8
    noise = total[0] / weight_sum
    low, high = noise.min(), noise.max()
    return (noise - low) / (high - low + 1e-6)


def _coords(size: tuple[int, int]) -> tuple[torch.Tensor, torch.Tensor]:
    rows = torch.arange(size[0], dtype=torch.float32)[:, None].expand(size)
    cols = torch.arange(size[1], dtype=torch.float32)[None, :].expand(size)
    return rows, cols


def _procedural(
    name: str, rng: np.random.Generator, size: tuple[int, int], zoom: float
) -> torch.Tensor:
    rows, cols = _coords(size)
    angle = rng.uniform(0, np.pi)
    along = rows * np.sin(angle) + cols * np.cos(angle)
    across = -rows * np.cos(angle) + cols * np.sin(angle)
    period = rng.uniform(5.0, 14.0) * zoom
    noise = _value_noise(rng, size, zoom)
    if name == "noise":
        palette = [_random_colour(rng) for _ in range(3)]
        second = _value_noise(rng, size, zoom)
        return (
            palette[0] * noise + palette[1] * (1 - noise) * second + palette[2] * (1 - second) * 0.5
        ).clamp(0, 1)
    if name == "checker":
        pattern = ((torch.floor(along / period) + torch.floor(across / period)) % 2)[None]
    elif name == "stripes":
        pattern = (0.5 + 0.5 * torch.sin(2 * np.pi * along / period))[None]
    elif name == "dots":
        cell_r = torch.remainder(along, period) - period / 2
        cell_c = torch.remainder(across, period) - period / 2
        radius = period * rng.uniform(0.2, 0.4)
        pattern = (cell_r**2 + cell_c**2 <= radius**2).float()[None]
    else:
        raise LfsamError(f"unknown procedural texture {name!r}; use one of {', '.join(PROCEDURAL)}")
    # Mix in noise so that no two patches of the pattern look alike (helps matching).
    base = _tint(pattern, rng)
    return (0.75 * base + 0.25 * _tint(noise, rng)).clamp(0, 1)


def make_texture(name: str, seed: int, size: tuple[int, int], zoom: float = 1.0) -> torch.Tensor:
    """Render texture ``name`` at ``size`` = (rows, columns), deterministically per ``seed``.

    Parameters
    ----------
    name : str
        One of :data:`TEXTURES`.
    seed : int
        Selects the crop, colours and pattern parameters.
    size : (int, int)
        Output rows and columns (at least 2 each).
    zoom : float
        Texture pixels per displayed pixel (the renderer's supersampling factor): photographs
        are cropped to about ``size / zoom`` of their pixels and patterns scaled by ``zoom``,
        so the detail on screen does not depend on the supersampling.

    Returns
    -------
    texture : Tensor, float32, ``[3, rows, columns]`` in [0, 1]

    Raises
    ------
    LfsamError
        If ``name`` is not one of :data:`TEXTURES`.
    """
    size = (max(2, int(size[0])), max(2, int(size[1])))
    rng = np.random.default_rng(seed)
    if name in PHOTOS or name in GRAY_PHOTOS:
        return _photo_crop(name, rng, size, zoom).contiguous()
    if name in PROCEDURAL:
        return _procedural(name, rng, size, zoom).contiguous()
    raise LfsamError(f"unknown texture {name!r}; choose one of {', '.join(TEXTURES)}")
