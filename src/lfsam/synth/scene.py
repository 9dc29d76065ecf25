"""Random scenes for the synthetic light-field generator (docs/design.md section 6).

:func:`random_scene` draws a :class:`~lfsam.synth.spec.SceneSpec` (the data model of
:mod:`lfsam.synth.spec`): a slanted textured background and overlapping textured planar objects,
optionally with hidden objects (:mod:`lfsam.synth.hidden`). :class:`PlanarObject` and
:class:`SceneSpec` are importable from here too.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch

from lfsam.errors import LfsamError
from lfsam.synth.hidden import add_hidden_objects
from lfsam.synth.raster import zbuffer
from lfsam.synth.shapes import random_outline
from lfsam.synth.spec import PlanarObject, SceneSpec
from lfsam.synth.textures import GRAY_PHOTOS, PHOTOS, TEXTURES

__all__ = ["PlanarObject", "SceneSpec", "random_outline", "random_scene"]


def _check_settings(grid, size, num_objects, disparity_range, hidden_objects=0) -> None:
    if len(grid) != 2 or min(grid) < 1:
        raise LfsamError(f"grid must be two positive numbers, got {grid}")
    if len(size) != 2 or min(size) < 8:
        raise LfsamError(f"view size must be at least 8x8 pixels, got {size}")
    if num_objects < 0:
        raise LfsamError(f"number of objects must be >= 0, got {num_objects}")
    if hidden_objects < 0:
        raise LfsamError(f"number of hidden objects must be >= 0, got {hidden_objects}")
    low, high = disparity_range
    if not (np.isfinite(low) and np.isfinite(high) and high > low):
        raise LfsamError(f"disparity range must be LO,HI with LO < HI, got {low},{high}; e.g. -2,2")


def _fit_plane(
    plane: tuple[float, float, float], points: np.ndarray, low: float, high: float
) -> tuple[float, float, float]:
    """Shift the plane's offset so its disparity at ``points`` (2 x N, ``(u, v)``) lies within
    ``[low, high]`` (the slope is left alone; it must fit the interval)."""
    a, b, c = plane
    values = a + b * points[0] + c * points[1]
    if values.max() > high:
        a -= values.max() - high
    elif values.min() < low:
        a += low - values.min()
    return float(a), float(b), float(c)


def _limit_slope(b: float, c: float, reach: tuple[float, float], limit: float = 0.45):
    """Scale ``(b, c)`` so that ``|b| reach_s + |c| reach_t <= limit`` (keeps A invertible)."""
    total = abs(b) * reach[0] + abs(c) * reach[1]
    return (b, c) if total <= limit else (b * limit / total, c * limit / total)


def _random_object(
    rng: np.random.Generator,
    label: int,
    size: tuple[int, int],
    reach: tuple[float, float],
    band: tuple[float, float],
    slanted: bool,
    near: PlanarObject | None,
) -> PlanarObject:
    height, width = size
    short = min(height, width)
    half = (short * rng.uniform(0.1, 0.26), short * rng.uniform(0.1, 0.26))
    if near is not None:
        # Overlap a previous object so that the scene has occlusions and disocclusions.
        direction = rng.uniform(0, 2 * np.pi)
        distance = (max(near.half_size) + max(half)) * rng.uniform(0.45, 0.85)
        center = (
            float(
                np.clip(near.center[0] + distance * np.sin(direction), 0.1 * height, 0.9 * height)
            ),
            float(np.clip(near.center[1] + distance * np.cos(direction), 0.1 * width, 0.9 * width)),
        )
    else:
        center = (rng.uniform(0.15, 0.85) * height, rng.uniform(0.15, 0.85) * width)
    span = band[1] - band[0]
    variation = rng.uniform(0.08, 0.3) * span if slanted else 0.0
    level = rng.uniform(band[0] + variation / 2, band[1] - variation / 2)
    radius = max(half)
    heading = rng.uniform(0, 2 * np.pi)
    b, c = _limit_slope(
        variation / (2 * radius) * np.sin(heading),
        variation / (2 * radius) * np.cos(heading),
        reach,
    )
    plane = (float(level - b * center[0] - c * center[1]), float(b), float(c))
    shape, vertices = random_outline(rng)
    obj = PlanarObject(
        label=label,
        shape=shape,
        center=(float(center[0]), float(center[1])),
        half_size=(float(half[0]), float(half[1])),
        angle=float(rng.uniform(0, np.pi)),
        plane=plane,
        texture=str(rng.choice(TEXTURES)),
        texture_seed=int(rng.integers(2**31 - 1)),
        vertices=vertices,
        corner=float(rng.uniform(0.15, 0.5)),
    )
    # Keep the whole patch (its local box [-1, 1]^2) inside the disparity band.
    return replace(obj, plane=_fit_plane(plane, obj.center_corners(), band[0], band[1]))


def random_scene(
    grid: tuple[int, int] = (9, 9),
    size: tuple[int, int] = (240, 320),
    seed: int = 0,
    num_objects: int = 6,
    disparity_range: tuple[float, float] = (-2.0, 2.0),
    slanted_fraction: float = 0.5,
    label_background: bool = True,
    min_visible: float = 0.35,
    hidden_objects: int = 0,
) -> SceneSpec:
    """A random scene: a slanted textured background and overlapping textured objects.

    The background is a plane in the farthest fifth of ``disparity_range``; the objects lie in
    the nearer three quarters, each fronto-parallel or (with probability ``slanted_fraction``)
    slanted, with disparities spanning up to 30 % of the range across the object. About
    two thirds of the objects are placed overlapping an earlier one. Objects are re-drawn until
    at least ``min_visible`` of each is visible in the center view (up to a fixed number of
    tries), so that every labelled object can be prompted there.

    Parameters
    ----------
    grid, size : (int, int)
        View grid ``(S, T)`` and view size ``(U, V)``.
    seed : int
        Seed of :class:`numpy.random.Generator`; equal seeds give equal scenes.
    num_objects : int
        Objects in front of the background.
    disparity_range : (float, float)
        ``(LO, HI)`` in pixels per view step; every disparity of the scene lies inside.
    slanted_fraction : float
        Probability that an object is slanted.
    label_background : bool
        Give the background its own label 1 (objects then get 2, 3, ...). With False the
        background is label 0 ("no label") and objects get 1, 2, ...
    min_visible : float
        Fraction of each object's area that must be visible in the center view.
    hidden_objects : int
        Small objects to add that the center view cannot see but a corner view can
        (:func:`lfsam.synth.hidden.add_hidden_objects`; labels after the other objects', listed
        in ``meta["hidden_labels"]``). Drawn from their own random stream, so the rest of the
        scene is the scene with ``hidden_objects=0``.

    Returns
    -------
    SceneSpec
    """
    grid = (int(grid[0]), int(grid[1]))
    size = (int(size[0]), int(size[1]))
    _check_settings(grid, size, num_objects, disparity_range, hidden_objects)
    low, high = float(disparity_range[0]), float(disparity_range[1])
    span = high - low
    rng = np.random.default_rng(seed)
    center = (grid[0] // 2, grid[1] // 2)
    reach = (
        float(max(center[0], grid[0] - 1 - center[0], 1)),
        float(max(center[1], grid[1] - 1 - center[1], 1)),
    )
    height, width = size

    # Background: a gently slanted plane in the farthest fifth of the range.
    variation = rng.uniform(0.0, 0.1) * span
    heading = rng.uniform(0, 2 * np.pi)
    b, c = _limit_slope(
        variation * np.sin(heading) / height, variation * np.cos(heading) / width, reach
    )
    level = low + variation / 2 + rng.uniform(0.0, 0.1) * span
    # The background texture covers the view plus the largest parallax shift.
    margin = max(abs(low), abs(high)) * max(reach) + 2.0
    extended = np.array(
        [
            [-margin, -margin, height + margin, height + margin],
            [-margin, width + margin, -margin, width + margin],
        ]
    )
    plane = (float(level - b * (height - 1) / 2 - c * (width - 1) / 2), float(b), float(c))
    background = PlanarObject(
        label=1 if label_background else 0,
        shape="plane",
        center=((height - 1) / 2, (width - 1) / 2),
        half_size=(height / 2 + margin, width / 2 + margin),
        angle=0.0,
        plane=_fit_plane(plane, extended, low, low + 0.2 * span),
        texture=str(rng.choice(PHOTOS + GRAY_PHOTOS + ("noise",))),
        texture_seed=int(rng.integers(2**31 - 1)),
    )
    first = 2 if label_background else 1
    band = (low + 0.25 * span, high)
    objects: list[PlanarObject] = []

    def draw(index: int) -> PlanarObject:
        near = None
        if index > 0 and rng.random() < 0.67:
            near = objects[int(rng.integers(0, index))] if objects else None
        return _random_object(
            rng, first + index, size, reach, band, bool(rng.random() < slanted_fraction), near
        )

    for index in range(num_objects):
        objects.append(draw(index))
    # Re-draw objects that are mostly hidden in the center view.
    for _round in range(30):
        spec = SceneSpec(grid, size, (background, *objects))
        hidden = _mostly_hidden(spec, min_visible)
        if not hidden:
            break
        for index in hidden:
            objects[index] = draw(index)
    meta = {
        "seed": int(seed),
        "grid": list(grid),
        "size": list(size),
        "num_objects": int(num_objects),
        "disparity_range": [low, high],
        "slanted_fraction": float(slanted_fraction),
        "label_background": bool(label_background),
    }
    spec = SceneSpec(grid, size, (background, *objects), meta)
    if hidden_objects:
        spec, hidden_labels = add_hidden_objects(spec, hidden_objects, seed)
        meta["hidden_objects"] = int(hidden_objects)
        meta["hidden_labels"] = hidden_labels
        spec = replace(spec, meta=meta)
    return spec


def _mostly_hidden(spec: SceneSpec, min_visible: float) -> list[int]:
    """Indices (into the objects after the background) visible below ``min_visible``."""
    rows = torch.arange(spec.size[0], dtype=torch.float64)[:, None]
    cols = torch.arange(spec.size[1], dtype=torch.float64)[None, :]
    winner, _, covered = zbuffer(spec.objects, 0.0, 0.0, rows, cols, with_coverage=True)
    hidden = []
    for index in range(1, len(spec.objects)):
        area = int(covered[index - 1].sum())
        visible = int((winner == index).sum())
        if area == 0 or visible < max(4, min_visible * area):
            hidden.append(index - 1)
    return hidden
