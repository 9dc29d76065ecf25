"""The center warp's crack and hole rules, pixel by pixel (lfsam.disparity.center_warp).

`_close_cracks` and `_fill_holes` work on the pixels that can change only (issue 65/66 speed);
here a plain per-pixel reference of each rule, as its docstring states it, must give the same
values on every pixel of small random scenes.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from lfsam.disparity import center_warp as cw


def _confirmed_at(center: torch.Tensor, row: int, col: int, d: float, ds: float, dt: float):
    if not math.isfinite(d):
        return False
    height, width = center.shape
    value = torch.tensor(d, dtype=torch.float32)
    u = int(torch.round(torch.tensor(float(row)) + value * ds))
    v = int(torch.round(torch.tensor(float(col)) + value * dt))
    if not (0 <= u < height and 0 <= v < width):
        return False
    return bool((center[u, v] - value).abs() <= cw._CONFIRM)


def _reference_cracks(zbuffer, center, ds, dt):
    height, width = zbuffer.shape
    out = zbuffer.clone()
    for row in range(height):
        for col in range(width):
            best = -math.inf
            for r in range(row - 1, row + 2):
                for c in range(col - 1, col + 2):
                    if 0 <= r < height and 0 <= c < width:
                        value = float(zbuffer[r, c])
                        if _confirmed_at(center, row, col, value, ds, dt) and value > best:
                            best = value
            own = zbuffer[row, col]
            if best > own + cw._CONFIRM:
                out[row, col] = best
    return out


def _reference_holes(zbuffer, center, ds, dt, reach):
    height, width = zbuffer.shape
    out = zbuffer.clone()
    landed = torch.isfinite(zbuffer)
    scale = max(abs(ds), abs(dt))
    step_u, step_v = ds / scale, dt / scale
    for row in range(height):
        for col in range(width):
            if landed[row, col]:
                continue
            found = []
            for sign in (1.0, -1.0):
                value = math.inf
                for k in range(1, reach + 1):
                    u = int(torch.round(torch.tensor(float(row)) + sign * k * step_u))
                    v = int(torch.round(torch.tensor(float(col)) + sign * k * step_v))
                    if 0 <= u < height and 0 <= v < width and landed[u, v]:
                        value = float(zbuffer[u, v])
                        break
                found.append(value)
            confirmed = [_confirmed_at(center, row, col, f, ds, dt) for f in found]
            if confirmed[0] and confirmed[1]:
                filled = max(found)
            elif confirmed[0] or confirmed[1]:
                filled = found[0] if confirmed[0] else found[1]
            else:
                filled = min(found)
            if math.isinf(filled):
                filled = float(zbuffer[landed].min())
            out[row, col] = filled
    return out


@st.composite
def scenes(draw):
    height = draw(st.integers(6, 14))
    width = draw(st.integers(6, 14))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    disparity = np.full((height, width), rng.uniform(-2.0, 0.0), np.float32)
    for _ in range(draw(st.integers(0, 3))):  # nearer blocks: occlusions and disocclusions
        r, c = rng.integers(0, height), rng.integers(0, width)
        disparity[r:r + rng.integers(2, 7), c:c + rng.integers(2, 7)] = rng.uniform(-1.0, 3.0)
    disparity += (rng.uniform(-0.3, 0.3) * np.arange(width))[None].astype(np.float32)
    offset = draw(st.tuples(st.integers(-3, 3), st.integers(-3, 3)).filter(lambda o: o != (0, 0)))
    return torch.from_numpy(disparity), offset


@settings(max_examples=25, deadline=None)
@given(scenes())
def test_cracks_and_holes_follow_their_rules_on_every_pixel(scene):
    center, (ds, dt) = scene
    zbuffer = cw._zbuffer(center, float(ds), float(dt))
    cracks = cw._close_cracks(zbuffer, center, float(ds), float(dt))
    torch.testing.assert_close(cracks, _reference_cracks(zbuffer, center, ds, dt),
                               rtol=0, atol=0)
    if not torch.isfinite(cracks).any():
        return
    reach = 6
    holes = cw._fill_holes(cracks, center, float(ds), float(dt), reach)
    torch.testing.assert_close(holes, _reference_holes(cracks, center, ds, dt, reach),
                               rtol=0, atol=0)
