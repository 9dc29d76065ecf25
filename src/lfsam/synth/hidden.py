"""Hidden objects: small patches the center view cannot see but outer views can (issue 16).

The paper's automatic mode (section 3.1) generates masks in the center view only, so an object
entirely behind a nearer one there gets no label anywhere, although the outer views, displaced by
the baseline, see around the occluder. Scenes with such objects test whether a method recovers
them (docs/design.md section 6: synthetic scenes; section 8: object recall).

A hidden object is a small fronto-parallel patch placed just in front of the background and
behind every other object, with its whole center-view outline at least :data:`MARGIN` pixels
inside the region that nearer objects cover there. By the convention (docs/design.md section 1) it
moves by ``(d_occluder - d_hidden) (ds, dt)`` pixels relative to its occluder in the view at offset
``(ds, dt)``, so placed near the occluder's edge it comes out from behind it in the outer rows
and columns. Placements are drawn at random and kept only when the exact z-buffer
(:func:`lfsam.synth.raster.zbuffer`) confirms, at pixel centres, that the center view shows none
of it and some corner view shows at least ``min_area`` pixels of it (for every hidden object
placed so far). Deterministic per seed, and independent of the rest of the scene's random draws:
the scene without its hidden objects is the scene generated with ``hidden_objects=0``.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import torch

from lfsam.errors import LfsamError
from lfsam.synth.raster import local_coordinates, region, zbuffer
from lfsam.synth.shapes import inside, random_outline
from lfsam.synth.spec import PlanarObject, SceneSpec
from lfsam.synth.textures import TEXTURES

__all__ = ["MARGIN", "add_hidden_objects", "default_min_area"]

#: Pixels between a hidden object's center-view outline and its occluder's edge (keeps the
#: anti-aliased center-view RGB free of it too).
MARGIN = 2.0

_TRIES = 300
_CHOICES = 4


def default_min_area(size: tuple[int, int]) -> int:
    """Pixels a hidden object must show in some corner view: 100 at 240x320, scaled by area,
    at least 12."""
    return max(12, math.ceil(100 * size[0] * size[1] / (240 * 320)))


def _corner_offsets(spec: SceneSpec) -> list[tuple[float, float]]:
    sc, tc = spec.center
    last_s, last_t = spec.grid[0] - 1, spec.grid[1] - 1
    corners = {(0, 0), (0, last_t), (last_s, 0), (last_s, last_t)}
    return [(float(s - sc), float(t - tc)) for s, t in sorted(corners) if (s, t) != (sc, tc)]


def _pixel_grid(size: tuple[int, int]) -> tuple[torch.Tensor, torch.Tensor]:
    rows = torch.arange(size[0], dtype=torch.float64)[:, None]
    cols = torch.arange(size[1], dtype=torch.float64)[None, :]
    return rows, cols


def _take(obj: PlanarObject, ds: float, dt: float, rows, cols, best: torch.Tensor):
    """Where a patch appended to a scene would be visible in a view, given the scene's
    z-buffered disparity ``best`` there: ``(box, mask)`` with ``mask`` the shape of
    ``best[box]`` (the z-buffer's rule: strictly closer wins)."""
    box = region(obj, ds, dt, rows, cols)
    y, x, d = local_coordinates(obj, ds, dt, rows[box[0]], cols[:, box[1]])
    covered = inside(obj.shape, x, y, obj.vertices, obj.corner)
    return box, covered & (d > best[box])


def _depth_interval(spec: SceneSpec) -> tuple[float, float]:
    """Disparities between the background's nearest point (over the view plus the largest
    parallax) and the farthest point of every other patch."""
    background, others = spec.objects[0], spec.objects[1:]
    a, b, c = background.plane
    height, width = spec.size
    reach = max(abs(o) for offset in _corner_offsets(spec) for o in offset)
    us = np.array([0.0, 0.0, height - 1.0, height - 1.0])
    vs = np.array([0.0, width - 1.0, 0.0, width - 1.0])
    margin = float(np.max(np.abs(a + b * us + c * vs))) * reach + 2.0
    us = np.array([-margin, -margin, height + margin, height + margin])
    vs = np.array([-margin, width + margin, -margin, width + margin])
    behind = float(np.max(a + b * us + c * vs)) if background.shape == "plane" else -np.inf
    front = np.inf
    for obj in others:
        u, v = obj.center_corners()
        oa, ob, oc = obj.plane
        front = min(front, float(np.min(oa + ob * u + oc * v)))
    return behind, front


def _new_object(
    label: int,
    center: tuple[float, float],
    half: tuple[float, float],
    angle: float,
    disparity: float,
    outline: tuple[str, tuple[tuple[float, float], ...]],
    texture: str,
    texture_seed: int,
    corner: float,
) -> PlanarObject:
    return PlanarObject(
        label=label,
        shape=outline[0],
        center=center,
        half_size=half,
        angle=angle,
        plane=(float(disparity), 0.0, 0.0),
        texture=texture,
        texture_seed=texture_seed,
        vertices=outline[1],
        corner=corner,
    )


def add_hidden_objects(
    spec: SceneSpec,
    count: int,
    seed: int = 0,
    min_area: int | None = None,
) -> tuple[SceneSpec, list[int]]:
    """Add ``count`` small objects that the center view cannot see but a corner view can.

    Parameters
    ----------
    spec : SceneSpec
        The scene (background first); the hidden objects are appended after its patches, with
        labels following the largest label in it.
    count : int
        Objects to hide.
    seed : int
        Seed of the placement draws (combined with a fixed tag, so the draws do not repeat the
        scene's own).
    min_area : int, optional
        Pixels each hidden object must show in at least one corner view (default
        :func:`default_min_area`).

    Returns
    -------
    spec : SceneSpec
        The scene with the hidden objects.
    labels : list of int
        Their labels.

    Raises
    ------
    LfsamError
        When the grid has no outer views, nothing in the scene can hide an object, or no
        placement shows ``min_area`` pixels in a corner view (too little parallax).
    """
    count = int(count)
    if count < 0:
        raise LfsamError(f"number of hidden objects must be >= 0, got {count}")
    if count == 0:
        return spec, []
    if not _corner_offsets(spec):
        raise LfsamError(
            f"hidden objects need outer views, but the grid is {spec.grid[0]}x{spec.grid[1]}; "
            "use a grid of at least 2x2 views"
        )
    height, width = spec.size
    min_area = default_min_area(spec.size) if min_area is None else int(min_area)
    behind, front = _depth_interval(spec)
    if not behind < front:
        raise LfsamError(
            "hidden objects need a gap in depth between the background and the other objects; "
            "use a scene made by random_scene"
        )
    rng = np.random.default_rng([int(seed), 0x41DE])
    base = len(spec.objects)
    reach = max(abs(o) for offset in _corner_offsets(spec) for o in offset)
    short = min(height, width)
    first_label = max(obj.label for obj in spec.objects) + 1
    # scipy loads only when hidden objects are asked for: lfsam.synth (and so `lfsam --help`)
    # imports this module
    from scipy.ndimage import distance_transform_edt

    rows, cols = _pixel_grid(spec.size)
    labels: list[int] = []
    offsets = _corner_offsets(spec)
    for k in range(count):
        # Behind every other object, in front of the background (never tied with another).
        depth = behind + (front - behind) * rng.uniform(0.25, 0.75)
        winner, best, _ = zbuffer(spec.objects, 0.0, 0.0, rows, cols)
        near = ((winner > 0) & (best > depth)).numpy()
        # Distance of each pixel to the nearest pixel not covered by a nearer patch (the view's
        # border counts as uncovered: the object must hide behind an object, not off-view).
        distance = distance_transform_edt(np.pad(near, 1))[1:-1, 1:-1]
        parallax = np.maximum(best.numpy() - depth, 0.0) * reach * math.sqrt(2.0)
        center_best = best
        views = [zbuffer(spec.objects, ds, dt, rows, cols)[:2] for ds, dt in offsets]
        # Pixels each earlier hidden object shows in each corner view.
        shown = np.array(
            [[int((w == base + i).sum()) for w, _ in views] for i in range(k)], dtype=np.int64
        ).reshape(k, len(views))
        placed: tuple[int, PlanarObject] | None = None
        valid = 0
        for attempt in range(_TRIES):
            shrink = 0.85 ** (attempt // 60)
            # Small: 3.5 to 6.5 % of the view's short side, at least 3 to 4.5 pixels.
            hu, hv = (max(short * rng.uniform(0.035, 0.065), rng.uniform(3.0, 4.5)) for _ in "uv")
            half = (float(hu * shrink), float(hv * shrink))
            outline = random_outline(rng)
            extent = max(half) * (1.0 if outline[0] == "ellipse" else math.sqrt(2.0))
            gap = distance - extent - MARGIN
            candidates = np.flatnonzero(((gap >= 0) & (gap <= 0.35 * parallax)).ravel())
            angle = float(rng.uniform(0, np.pi))
            texture = str(rng.choice(TEXTURES))
            texture_seed = int(rng.integers(2**31 - 1))
            corner = float(rng.uniform(0.15, 0.5))
            if candidates.size == 0:
                continue
            pick = int(candidates[rng.integers(candidates.size)])
            center = (float(pick // width), float(pick % width))
            obj = _new_object(
                first_label + k,
                center,
                half,
                angle,
                depth,
                outline,
                texture,
                texture_seed,
                corner,
            )
            if bool(_take(obj, 0.0, 0.0, rows, cols, center_best)[1].any()):
                continue
            own = np.zeros(len(views), dtype=np.int64)
            others = shown.copy()
            for j, ((ds, dt), (w, b)) in enumerate(zip(offsets, views, strict=True)):
                box, take = _take(obj, ds, dt, rows, cols, b)
                own[j] = int(take.sum())
                covered = w[box][take]
                for i in range(k):
                    others[i, j] -= int((covered == base + i).sum())
            if own.max() >= min_area and (k == 0 or bool(np.all(others.max(axis=1) >= min_area))):
                # Keep the placement that shows the most of it, among the first few valid ones.
                if placed is None or own.max() > placed[0]:
                    placed = (int(own.max()), obj)
                valid += 1
                if valid == _CHOICES:
                    break
        if placed is None:
            raise LfsamError(
                f"could hide only {k} of {count} objects with at least {min_area} pixels in a "
                f"corner view (the corner views move them at most {float(parallax.max()):.1f} "
                "pixels against their occluders); use a larger grid, a wider disparity range or "
                "fewer hidden objects"
            )
        spec = replace(spec, objects=(*spec.objects, placed[1]))
        labels.append(first_label + k)
    return spec, labels
