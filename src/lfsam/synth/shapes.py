"""Object outlines for the synthetic scenes, as inside-tests in the object's own coordinates.

Each object has local coordinates ``(y, x)`` (local row, local column) in which its outline fits
the square ``[-1, 1]^2``: an ellipse ``x^2 + y^2 <= 1``, a rounded rectangle (signed-distance
test of a box with rounded corners, Quilez, "2D distance functions"), or a star-shaped polygon
(even-odd crossing test, Shimrat 1962). The tests are vectorised over any tensor shape.
:func:`random_outline` draws one at random (for the random scenes and their hidden objects).
"""

from __future__ import annotations

import numpy as np
import torch

from lfsam.errors import LfsamError

__all__ = ["SHAPES", "SHAPE_NOUNS", "inside", "random_outline"]

#: Bounded outlines (``"plane"`` is the unbounded background).
SHAPES = ("ellipse", "rounded_rect", "polygon")

#: The everyday noun of each outline, the last word of a patch's category name (text prompts
#: such as ``--text disc``; docs/design.md section 9).
SHAPE_NOUNS = {"plane": "background", "ellipse": "disc", "rounded_rect": "tile", "polygon": "star"}


def _ellipse(x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
    return x * x + y * y <= 1.0


def _rounded_rect(x: torch.Tensor, y: torch.Tensor, radius: float) -> torch.Tensor:
    # Box [-1, 1]^2 with corners rounded by `radius`: distance of (|x|, |y|) to the inner box.
    qx = x.abs() - (1.0 - radius)
    qy = y.abs() - (1.0 - radius)
    outside = torch.sqrt(qx.clamp(min=0) ** 2 + qy.clamp(min=0) ** 2)
    inner = torch.maximum(qx, qy).clamp(max=0)
    return outside + inner <= radius


def _polygon(
    x: torch.Tensor, y: torch.Tensor, vertices: tuple[tuple[float, float], ...]
) -> torch.Tensor:
    result = torch.zeros_like(x, dtype=torch.bool)
    count = len(vertices)
    for i in range(count):
        yi, xi = vertices[i]
        yj, xj = vertices[(i + 1) % count]
        if yi == yj:
            continue
        crosses = (yi > y) != (yj > y)
        x_cross = (xj - xi) * (y - yi) / (yj - yi) + xi
        result ^= crosses & (x < x_cross)
    return result


def inside(
    shape: str,
    x: torch.Tensor,
    y: torch.Tensor,
    vertices: tuple[tuple[float, float], ...] = (),
    corner: float = 0.3,
) -> torch.Tensor:
    """Whether local points ``(y, x)`` lie inside an outline.

    Parameters
    ----------
    shape : {"plane", "ellipse", "rounded_rect", "polygon"}
        ``"plane"`` is everywhere inside.
    x, y : Tensor
        Local column and row coordinates (same shape).
    vertices : tuple of (y, x)
        Polygon vertices in order, inside ``[-1, 1]^2``.
    corner : float
        Corner radius of the rounded rectangle, in local units (0..1).

    Returns
    -------
    Tensor of bool, the shape of ``x``

    Raises
    ------
    LfsamError
        If ``shape`` is not one of :data:`SHAPES`.
    """
    if shape == "plane":
        return torch.ones_like(x, dtype=torch.bool)
    if shape == "ellipse":
        return _ellipse(x, y)
    if shape == "rounded_rect":
        return _rounded_rect(x, y, corner)
    if shape == "polygon":
        return _polygon(x, y, vertices)
    raise LfsamError(f"unknown shape {shape!r}; use plane or one of {', '.join(SHAPES)}")


def random_outline(rng: np.random.Generator) -> tuple[str, tuple[tuple[float, float], ...]]:
    """A random outline name (:data:`lfsam.synth.shapes.SHAPES`) and, for a polygon, its
    star-shaped vertices (5 to 8, jittered angles, radii 0.55 to 1 in local units)."""
    shape = str(rng.choice(SHAPES))
    vertices: tuple[tuple[float, float], ...] = ()
    if shape == "polygon":
        count = int(rng.integers(5, 9))
        angles = np.sort(np.arange(count) * 2 * np.pi / count + rng.uniform(-0.3, 0.3, count))
        radii = rng.uniform(0.55, 1.0, count)
        vertices = tuple(
            (float(r * np.sin(t)), float(r * np.cos(t))) for r, t in zip(radii, angles, strict=True)
        )
    return shape, vertices
