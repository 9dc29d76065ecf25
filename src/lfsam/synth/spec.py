"""Scene descriptions of the synthetic light-field generator: the data model.

A scene is a stack of textured planar patches seen by a grid of cameras. Each patch has

- a disparity plane ``d(u, v) = a + b u + c v`` in center-view pixel coordinates (``b = c = 0``:
  fronto-parallel; otherwise slanted);
- an outline (:mod:`lfsam.synth.shapes`) and a texture (:mod:`lfsam.synth.textures`) in its own
  local coordinates ``(y, x) in [-1, 1]^2``, placed by a center, half sizes and a rotation.

By the package convention (docs/design.md section 1) the patch point seen at center pixel ``(u, v)``
is seen in the view at offset ``(ds, dt)`` at ``u' = u - d(u, v) ds``, ``v' = v - d(u, v) dt``.
For a plane this map is affine,

    [u', v'] = A [u, v] + o,   A = [[1 - b ds, -c ds], [-b dt, 1 - c dt]],   o = -a [ds, dt],

so every view pixel maps back to the patch by the inverse affine map, and the disparity of a
scene point is the same in every view. ``A`` is invertible while ``b ds + c dt < 1``; the random
scenes keep it below 0.5.

The random generator (:func:`lfsam.synth.scene.random_scene`) and the renderer
(:mod:`lfsam.synth.render`) build on these classes; this module imports neither.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from lfsam.errors import LfsamError
from lfsam.synth.shapes import SHAPE_NOUNS

__all__ = ["PlanarObject", "SceneSpec"]


@dataclass(frozen=True)
class PlanarObject:
    """One textured planar patch of a synthetic scene.

    Parameters
    ----------
    label : int
        Its instance label in the ground truth (0 = leave unlabeled).
    shape : {"plane", "ellipse", "rounded_rect", "polygon"}
        Outline; ``"plane"`` is unbounded (the background).
    center : (float, float)
        Center-view pixel ``(u0, v0)`` of the local origin.
    half_size : (float, float)
        Half extents ``(hu, hv)`` in pixels along the local row and column axes.
    angle : float
        Rotation of the local axes against the pixel axes, in radians.
    plane : (float, float, float)
        ``(a, b, c)`` of ``d(u, v) = a + b u + c v`` (center-view coordinates).
    texture : str
        Texture name (:data:`lfsam.synth.textures.TEXTURES`).
    texture_seed : int
        Seed of the texture.
    vertices : tuple of (y, x)
        Polygon vertices in local coordinates.
    corner : float
        Rounded-rectangle corner radius in local units.
    """

    label: int
    shape: str
    center: tuple[float, float]
    half_size: tuple[float, float]
    angle: float
    plane: tuple[float, float, float]
    texture: str
    texture_seed: int
    vertices: tuple[tuple[float, float], ...] = ()
    corner: float = 0.3

    @property
    def category(self) -> str:
        """Its category name: texture then shape noun, e.g. ``"brick disc"`` (the ground truth
        of text prompts, docs/design.md section 9)."""
        return f"{self.texture} {SHAPE_NOUNS[self.shape]}"

    def _local_matrix(self) -> np.ndarray:
        """``K`` with local ``(y, x) = K ([u, v] - center)``."""
        cos, sin = np.cos(self.angle), np.sin(self.angle)
        rotation = np.array([[cos, sin], [-sin, cos]])
        return np.diag([1.0 / self.half_size[0], 1.0 / self.half_size[1]]) @ rotation

    def view_maps(self, ds: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Affine maps from a pixel ``(u', v')`` of the view at offset ``(ds, dt)``.

        Returns
        -------
        local : ndarray (2, 3)
            ``[y, x] = local @ [u', v', 1]``: the patch's local coordinates there.
        disparity : ndarray (3,)
            ``d = disparity @ [u', v', 1]``: the patch's disparity there.
        """
        a, b, c = self.plane
        forward = np.array([[1.0 - b * ds, -c * ds], [-b * dt, 1.0 - c * dt]])
        offset = -a * np.array([ds, dt])
        if np.linalg.det(forward) <= 1e-6:
            raise LfsamError(
                f"object {self.label} is too slanted for view offset ({ds}, {dt}); "
                "reduce its disparity slope or the grid size"
            )
        inverse = np.linalg.inv(forward)
        k = self._local_matrix()
        local = np.concatenate(
            [k @ inverse, (-k @ (inverse @ offset + np.asarray(self.center)))[:, None]], axis=1
        )
        slope = np.array([b, c]) @ inverse
        disparity = np.array([slope[0], slope[1], a - slope @ offset])
        return local, disparity

    def center_corners(self) -> np.ndarray:
        """Corners of the local box ``[-1, 1]^2`` in center-view pixels, ``(2, 4)`` ``(u, v)``."""
        corners = np.array([[-1, -1, 1, 1], [-1, 1, -1, 1]], dtype=np.float64)
        return np.asarray(self.center)[:, None] + np.linalg.inv(self._local_matrix()) @ corners

    def view_bbox(self, ds: float, dt: float) -> tuple[float, float, float, float] | None:
        """``(u_min, u_max, v_min, v_max)`` of the patch in the view, or None if unbounded."""
        if self.shape == "plane":
            return None
        a, b, c = self.plane
        forward = np.array([[1.0 - b * ds, -c * ds], [-b * dt, 1.0 - c * dt]])
        offset = -a * np.array([ds, dt])
        view = forward @ self.center_corners() + offset[:, None]
        return view[0].min(), view[0].max(), view[1].min(), view[1].max()

    def describe(self) -> dict:
        """JSON-ready summary (for ``meta``)."""
        a, b, c = self.plane
        u0, v0 = self.center
        return {
            "label": self.label,
            "shape": self.shape,
            "texture": self.texture,
            "category": self.category,
            "center": [round(u0, 3), round(v0, 3)],
            "half_size": [round(x, 3) for x in self.half_size],
            "disparity_at_center": round(a + b * u0 + c * v0, 4),
            "slope": [round(b, 5), round(c, 5)],
        }


@dataclass(frozen=True)
class SceneSpec:
    """A synthetic scene: the camera grid, the view size and the patches (background first).

    Parameters
    ----------
    grid : (S, T)
        Views per column and row of the grid.
    size : (U, V)
        Pixel rows and columns of each view.
    objects : tuple of PlanarObject
        The patches; where several cover a pixel, the largest disparity (closest) wins.
    meta : dict
        Generator settings, copied into the light field's ``meta``.
    """

    grid: tuple[int, int]
    size: tuple[int, int]
    objects: tuple[PlanarObject, ...]
    meta: dict = field(default_factory=dict)

    @property
    def center(self) -> tuple[int, int]:
        """The reference view ``(S // 2, T // 2)``."""
        return self.grid[0] // 2, self.grid[1] // 2
