"""See-through (glass) and mirror objects for the synthetic generator (docs/design.md section 6).

Every disparity estimator assumes that a surface point looks the same from every view. Glass and
mirrors break that: what a view sees inside them is not their surface but what lies behind them
(refracted) or what they reflect, which moves across the views with a disparity of its own. A robot
reaching for such an object needs the surface's depth, so the generator renders them with the
surface's exact disparity and labels while their colour shows something else:

- the object keeps an opaque **frame**, the outer :data:`FRAME` of its outline (local units: the
  outline spans [-1, 1]), textured as a matte object would be (a glass's rim, a mirror's frame);
- **glass**: inside the frame, :data:`SEE_THROUGH` of the colour is the scene behind the object
  (everything else rendered without it) magnified by :data:`REFRACTION` about the object's center
  in that view (a lens: the content's apparent disparity becomes
  ``d_s + (d_b - d_s) / REFRACTION``, ``d_s`` the surface's, ``d_b`` the background's),
  :data:`GLASS_REFLECTANCE` a faint reflection (as a mirror's, below: glass reflects too), the rest
  the object's own texture (the glass's tint and dirt, which lie on its surface);
- **mirror**: inside the frame, :data:`REFLECTANCE` of the colour is a reflected scene, a texture of
  its own on a fronto-parallel virtual plane :data:`MIRROR_GAP` pixels per view step farther than
  the surface at its center (the virtual image behind a plane mirror), the rest its own texture.

The same scene with every object matte (``materials`` off) has identical geometry, labels and
frames: the comparison of issue 45.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F

from lfsam.errors import LfsamError
from lfsam.synth.shapes import inside
from lfsam.synth.spec import PlanarObject
from lfsam.synth.textures import make_texture

__all__ = [
    "FRAME",
    "GLASS_REFLECTANCE",
    "MATERIALS",
    "MIRROR_GAP",
    "REFLECTANCE",
    "REFRACTION",
    "SEE_THROUGH",
    "assign_materials",
    "inner_region",
    "mirror_colour",
    "reflection_texture",
    "refracted_grid",
]

#: The materials an object can have.
MATERIALS = ("matte", "glass", "mirror")
#: Width of the opaque frame, in local units of the outline (which spans [-1, 1]).
FRAME = 0.2
#: Share of a glass object's colour that is the scene behind it.
SEE_THROUGH = 0.6
#: Share of a glass object's colour that is a reflection.
GLASS_REFLECTANCE = 0.25
#: Magnification of the scene seen through glass, about the object's center.
REFRACTION = 0.85
#: Share of a mirror's colour that is the reflection.
REFLECTANCE = 0.8
#: How much farther (pixels per view step) the mirror's virtual image lies than its surface.
MIRROR_GAP = 1.0


def assign_materials(labels: list[int], glass: int, mirror: int) -> dict[int, str]:
    """``{label: material}`` for the first ``glass`` labels (glass) and the next ``mirror``.

    Raises
    ------
    LfsamError
        If there are fewer objects than glass and mirror objects asked for.
    """
    if glass < 0 or mirror < 0:
        raise LfsamError(f"numbers of glass and mirror objects must be >= 0, got {glass}, {mirror}")
    if glass + mirror > len(labels):
        raise LfsamError(
            f"{glass} glass + {mirror} mirror objects asked for but the scene has only "
            f"{len(labels)} objects; raise --objects or lower them"
        )
    chosen = {label: "glass" for label in labels[:glass]}
    chosen.update({label: "mirror" for label in labels[glass : glass + mirror]})
    return chosen


def inner_region(obj: PlanarObject, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
    """Where the local coordinates ``(x, y)`` lie inside the frame (the outline shrunk by
    :data:`FRAME`)."""
    scale = 1.0 / (1.0 - FRAME)
    return inside(obj.shape, x * scale, y * scale, obj.vertices, obj.corner)


def _center_in_view(obj: PlanarObject, ds: float, dt: float) -> tuple[float, float]:
    """Where the object's center is seen in the view at offset ``(ds, dt)``."""
    a, b, c = obj.plane
    u0, v0 = obj.center
    d = a + b * u0 + c * v0
    return u0 - d * ds, v0 - d * dt


def refracted_grid(
    obj: PlanarObject, ds: float, dt: float, us: torch.Tensor, vs: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """The sample rows and columns at which a view sees the scene behind glass ``obj``:
    ``us``, ``vs`` magnified by :data:`REFRACTION` about the object's center in that view."""
    uc, vc = _center_in_view(obj, ds, dt)
    return uc + REFRACTION * (us - uc), vc + REFRACTION * (vs - vc)


def mirror_colour(
    obj: PlanarObject,
    ds: float,
    dt: float,
    u: torch.Tensor,
    v: torch.Tensor,
    texture: torch.Tensor,
) -> torch.Tensor:
    """The reflection a mirror shows at view samples ``(u, v)`` (``[rows, 1]``, ``[1, cols]``).

    The reflection is ``texture`` on a fronto-parallel virtual plane at disparity ``d_v`` (the
    surface's at its center minus :data:`MIRROR_GAP`): view sample ``p`` shows its point seen at
    ``p + d_v (ds, dt)`` in the center view, looked up in the object's local frame there.

    Returns
    -------
    torch.Tensor, shape (3, rows, cols)
    """
    a, b, c = obj.plane
    u0, v0 = obj.center
    virtual = a + b * u0 + c * v0 - MIRROR_GAP
    cu = (u + virtual * ds) - u0
    cv = (v + virtual * dt) - v0
    cos, sin = np.cos(obj.angle), np.sin(obj.angle)
    y = (cos * cu + sin * cv) / obj.half_size[0]
    x = (-sin * cu + cos * cv) / obj.half_size[1]
    grid = torch.stack(torch.broadcast_tensors(x, y), dim=-1).float()
    return F.grid_sample(
        texture[None], grid[None], mode="bilinear", padding_mode="reflection", align_corners=False
    )[0]


def reflection_texture(obj: PlanarObject, shape: tuple[int, int], zoom: int) -> torch.Tensor:
    """The texture a mirror reflects (its own random photograph-like pattern, deterministic)."""
    return make_texture("chelsea", obj.texture_seed ^ 0x3141, shape, zoom=zoom)
