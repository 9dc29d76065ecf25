"""Issue 45, fifth round: the robust local quadratic fit of the disparity away from edges
(lfsam.disparity.surface_fit; docs/design.md section 3.2)."""

from __future__ import annotations

import numpy as np
import torch

from lfsam.disparity import estimate_disparity
from lfsam.disparity.surface_fit import fit_surface


def _grid(rows: int, cols: int) -> tuple[torch.Tensor, torch.Tensor]:
    u = torch.arange(rows, dtype=torch.float32)[:, None].expand(rows, cols)
    v = torch.arange(cols, dtype=torch.float32)[None, :].expand(rows, cols)
    return u, v


def test_a_quadratic_surface_is_kept_exactly():
    u, v = _grid(40, 50)
    surface = 0.3 + 0.04 * u - 0.02 * v + 4e-4 * (u - 20) ** 2 - 3e-4 * (u - 20) * (v - 25)
    mask = torch.ones(40, 50, dtype=torch.bool)
    guide = torch.full((3, 40, 50), 0.4)
    fitted = fit_surface(surface, mask, guide)
    # a constant or a plane fitted over 15 x 15 pixels would be off by the curvature (the ridge
    # on the coefficients leaves a trace where the window is cut by the frame)
    torch.testing.assert_close(fitted[7:-7, 7:-7], surface[7:-7, 7:-7], atol=1e-4, rtol=0)
    torch.testing.assert_close(fitted, surface, atol=3e-3, rtol=0)
    plane = fit_surface(surface, mask, guide, regulariser=1e6)  # slopes and curvature held at 0
    assert float((plane - surface)[7:-7, 7:-7].abs().max()) > 0.005


def test_noise_on_a_slanted_plane_is_averaged_without_flattening_the_slant():
    u, _ = _grid(60, 60)
    plane = -0.5 + 0.06 * u  # the slant of HCI antinous' floor, 0.06 px per row
    noise = torch.from_numpy(np.random.default_rng(1).normal(0, 0.06, (60, 60))).float()
    mask = torch.ones(60, 60, dtype=torch.bool)
    mask[:, :3] = False  # pixels outside the mask keep their value and give none
    guide = torch.full((3, 60, 60), 0.2)
    fitted = fit_surface(plane + noise, mask, guide)
    inside = (slice(8, -8), slice(10, -8))
    before = (noise[inside]).abs().mean()
    after = (fitted - plane)[inside].abs().mean()
    assert after < before / 4
    # no bias along the slant (a constant fill would be off by the slope times the distance)
    assert float((fitted - plane)[inside].mean().abs()) < 0.005
    torch.testing.assert_close(fitted[:, :3], (plane + noise)[:, :3], rtol=0, atol=0)


def test_the_colour_weight_keeps_two_surfaces_apart():
    u, v = _grid(40, 40)
    disparity = torch.where(v < 20, 0.2 + 0.01 * u, 1.0 - 0.02 * u)
    guide = torch.where(v < 20, 0.2, 0.7)[None].expand(3, -1, -1).contiguous()
    mask = torch.ones(40, 40, dtype=torch.bool)
    fitted = fit_surface(disparity, mask, guide)
    # next to the step each side keeps its own surface (an unweighted fit mixes them)
    torch.testing.assert_close(fitted, disparity, atol=2e-3, rtol=0)
    mixed = fit_surface(disparity, mask, guide, colour_sigma=10.0, range_sigma=100.0)
    assert float((mixed - disparity)[:, 18:22].abs().max()) > 0.05


def _slanted_floor(grid: int = 7, size: tuple[int, int] = (64, 72), seed: int = 0):
    """A weakly textured plane slanted in depth (0.02 px per view step per row), its views
    rendered exactly and quantised to 8 bits (the noise), and its center view's ground truth."""
    rng = np.random.default_rng(seed)
    rows, cols = size
    d0, slope = -0.6, 0.02
    freq = rng.uniform(0.15, 0.5, (6, 2)) * rng.choice([-1, 1], (6, 2))
    phase = rng.uniform(0, 2 * np.pi, 6)

    def texture(x, y):
        return 0.3 + 0.01 * sum(
            np.sin(freq[k, 0] * x + freq[k, 1] * y + phase[k]) for k in range(6)
        )

    up, vp = np.meshgrid(np.arange(rows, dtype=np.float64), np.arange(cols, dtype=np.float64),
                         indexing="ij")
    views = np.zeros((grid, grid, rows, cols, 3), dtype=np.uint8)
    c = grid // 2
    for s in range(grid):
        for t in range(grid):
            ds, dt = s - c, t - c
            u = (up + d0 * ds) / (1.0 - slope * ds)  # the reference row this pixel shows
            d = d0 + slope * u
            g = texture(u, vp + d * dt)
            views[s, t] = np.clip(np.round(255 * g), 0, 255).astype(np.uint8)[..., None]
    return views, d0 + slope * up


def test_the_estimator_fits_a_noisy_slanted_floor_better_with_the_surface_fit():
    views, truth = _slanted_floor()
    options = {"disparity_range": (-1.0, 1.0), "device": "cpu", "fusion": False}
    without = estimate_disparity(views, surface_fit=False, **options)
    with_fit = estimate_disparity(views, **options)
    assert with_fit.meta["surface_fit"] is True
    inner = (slice(8, -8), slice(8, -8))
    bad_without = float(np.mean(np.abs(without.disparity - truth)[inner] > 0.07))
    bad_with = float(np.mean(np.abs(with_fit.disparity - truth)[inner] > 0.07))
    err_without = float(np.mean(np.abs(without.disparity - truth)[inner]))
    err_with = float(np.mean(np.abs(with_fit.disparity - truth)[inner]))
    assert bad_with < 0.5 * bad_without
    assert err_with < 0.7 * err_without
    # the slant survives: the rows' means rise by the ground truth's 0.02 px per row
    rows = with_fit.disparity[inner].mean(1)
    slope = np.polyfit(np.arange(len(rows)), rows, 1)[0]
    assert abs(slope - 0.02) < 0.002
    # the confidence is the cost volume's, unchanged by the fit
    np.testing.assert_array_equal(with_fit.confidence, without.confidence)
