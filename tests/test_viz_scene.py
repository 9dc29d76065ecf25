"""A tiny synthetic light field for the visualisation tests, and a check that it is right.

Textured rectangles at constant integer disparities over a textured background plane, rendered
by the package's convention (docs/design.md section 1): the center pixel ``(u, v)`` of an object
with disparity ``d`` is seen in view ``(s, t)`` at ``(u - d (s - s_c), v - d (t - t_c))``. Closer
objects (larger ``d``) are painted last. Other test modules import :func:`make_scene`.
"""

from __future__ import annotations

import numpy as np

from lfsam.geometry import project_pixels
from lfsam.lightfield import LightField

# (label, disparity, (u0, u1, v0, v1)) in the center view; background: label 0, disparity -1.
BACKGROUND_DISPARITY = -1
OBJECTS = (
    (3, 0, (6, 42, 34, 60)),
    (1, 1, (10, 30, 6, 28)),
    (2, 2, (22, 40, 22, 44)),
)


def make_scene(
    grid: tuple[int, int] = (5, 5),
    size: tuple[int, int] = (48, 64),
    objects=OBJECTS,
    seed: int = 0,
) -> LightField:
    """Render the scene; returns a LightField with per-view labels and disparity."""
    rng = np.random.default_rng(seed)
    s_count, t_count = grid
    u_count, v_count = size
    s_c, t_c = s_count // 2, t_count // 2
    ds = (np.arange(s_count) - s_c)[:, None, None, None]
    dt = (np.arange(t_count) - t_c)[None, :, None, None]
    u = np.arange(u_count)[None, None, :, None]
    v = np.arange(v_count)[None, None, None, :]
    shape = (s_count, t_count, u_count, v_count)
    # The background plane, farther than every object: a texture larger than the view by the
    # largest shift, sampled where each view sees it.
    d = BACKGROUND_DISPARITY
    m = abs(d) * max(s_c, t_c, s_count - 1 - s_c, t_count - 1 - t_c)
    wall = rng.integers(90, 140, size=(u_count + 2 * m, v_count + 2 * m, 3), dtype=np.uint8)
    views = wall[np.broadcast_to(u + d * ds + m, shape), np.broadcast_to(v + d * dt + m, shape)]
    labels = np.zeros(shape, dtype=np.int32)
    disparity = np.full(shape, d, dtype=np.float32)
    for label, d, (u0, u1, v0, v1) in sorted(objects, key=lambda o: o[1]):
        base = rng.integers(40, 216, size=3)
        texture = np.clip(base + rng.integers(-35, 36, size=(u1 - u0, v1 - v0, 3)), 0, 255)
        # Center-view coordinates of the point each view pixel sees on this object's plane.
        uc = np.broadcast_to(u + d * ds, shape)
        vc = np.broadcast_to(v + d * dt, shape)
        inside = (uc >= u0) & (uc < u1) & (vc >= v0) & (vc < v1)
        views[inside] = texture[uc[inside] - u0, vc[inside] - v0]
        labels[inside] = label
        disparity[inside] = d
    return LightField(views=views, disparity=disparity, labels=labels)


def test_scene_follows_the_package_convention():
    lf = make_scene()
    s_c, t_c = lf.center
    for s, t in [(0, 0), (0, 4), (4, 1), (2, 3)]:
        for label, d, (u0, u1, v0, v1) in OBJECTS:
            uu, vv = np.meshgrid(np.arange(u0, u1), np.arange(v0, v1), indexing="ij")
            visible = lf.labels[s_c, t_c, uu, vv] == label
            up, vp = project_pixels(uu, vv, d, s - s_c, t - t_c)
            ok = visible & (up >= 0) & (up < 48) & (vp >= 0) & (vp < 64)
            up, vp = up[ok].astype(int), vp[ok].astype(int)
            # Points of the object visible in the center view and not covered by a closer
            # object in view (s, t) keep their label and colour.
            same = lf.labels[s, t, up, vp] == label
            assert same.mean() > 0.5
            np.testing.assert_array_equal(
                lf.views[s, t, up[same], vp[same]], lf.views[s_c, t_c, uu[ok][same], vv[ok][same]]
            )


def test_scene_has_parallax_and_occlusion():
    lf = make_scene()
    assert not np.array_equal(lf.views[0, 0], lf.views[4, 4])
    # Object 2 (closest) covers part of object 1 in some view but not in another.
    overlap = [(lf.labels[s, t] == 1).sum() for s in range(5) for t in range(5)]
    assert len(set(overlap)) > 1
