"""The one warp (lfsam.warp): exact geometry, z-buffer, and geometric occluding of slanted objects.

Geometric occluding (docs/design.md section 3) must compare every mask pixel with its own
disparity: a slanted object that nothing occludes keeps every propagated pixel, whatever the
propagation mode, and an object that a nearer one really covers still loses the covered part.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from lfsam.api import RunOptions, SegmentOptions, make_prompts, segment
from lfsam.pipeline import PipelineConfig
from lfsam.pipeline.propagation import propagate_masks
from lfsam.segmenters import load_segmenter
from lfsam.synth import PlanarObject, SceneSpec, render_scene
from lfsam.warp import (
    fill_warp_holes,
    forward_warp,
    landing_pixels,
    shift_masks,
    shift_masks_with_disparity,
)


@settings(max_examples=40, deadline=None)
@given(
    d=st.sampled_from([-2.0, -1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0]),
    ds=st.integers(-4, 4),
    dt=st.integers(-4, 4),
    halves=st.sampled_from(["even", "up"]),
)
def test_constant_disparity_with_integral_shift_is_an_exact_translation(d, ds, dt, halves):
    if (d * ds) % 1 or (d * dt) % 1:
        return  # only integral shifts are translations under both roundings
    height, width = 9, 11
    target, valid = landing_pixels(torch.full((height, width), d), ds, dt, halves=halves)
    u, v = np.meshgrid(np.arange(height), np.arange(width), indexing="ij")
    tu, tv = (u - d * ds).astype(int).ravel(), (v - d * dt).astype(int).ravel()
    inside = (tu >= 0) & (tu < height) & (tv >= 0) & (tv < width)
    assert np.array_equal(valid.numpy(), inside)
    assert np.array_equal(target.numpy()[inside], (tu * width + tv)[inside])
    assert bool((target[~valid] == -1).all())


@settings(max_examples=30, deadline=None)
@given(
    d=st.sampled_from([-1.5, -0.5, 0.5, 1.5, 2.5]),
    step=st.integers(-3, 3),
)
def test_halves_up_keeps_any_dyadic_constant_shift_a_translation(d, step):
    # floor(u - x + 0.5) = u + floor(0.5 - x) for integer u: one shift for every pixel.
    width = 12
    target, valid = landing_pixels(torch.full((1, width), d), 0, step, halves="up")
    moved = target[valid] - torch.arange(width)[valid]
    assert moved.unique().numel() <= 1


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    ds=st.integers(-3, 3),
    dt=st.integers(-3, 3),
)
def test_zbuffer_holds_the_largest_disparity_landing_on_each_pixel(seed, ds, dt):
    rng = np.random.default_rng(seed)
    disparity = rng.choice([0.0, 0.5, 1.0, 2.0, 3.0], size=(8, 10)).astype(np.float32)
    warp = forward_warp(torch.as_tensor(disparity), ds, dt)
    expected = np.full(8 * 10, -np.inf, dtype=np.float32)
    u, v = np.meshgrid(np.arange(8), np.arange(10), indexing="ij")
    tu = np.round(u - disparity * ds).astype(int).ravel()
    tv = np.round(v - disparity * dt).astype(int).ravel()
    inside = (tu >= 0) & (tu < 8) & (tv >= 0) & (tv < 10)
    np.maximum.at(expected, (tu * 10 + tv)[inside], disparity.ravel()[inside])
    assert np.array_equal(warp.zbuffer.numpy(), expected)
    # A visible pixel is never beaten by more than the tolerance at its landing pixel.
    visible = warp.visible(torch.as_tensor(disparity), 0.2).numpy()
    landed = expected[np.where(inside, tu * 10 + tv, 0)]
    assert np.array_equal(visible, inside & (disparity.ravel() >= landed - 0.2))


@settings(max_examples=25, deadline=None)
@given(
    source=st.tuples(st.integers(0, 4), st.integers(0, 4)),
    target=st.tuples(st.integers(0, 4), st.integers(0, 4)),
)
def test_warp_is_reference_agnostic(source, target):
    # Offsets are target minus source, whichever view is the source: warping a constant
    # integer disparity from view a to view b and back is the identity where it stays inside.
    ds, dt = target[0] - source[0], target[1] - source[1]
    disparity = torch.full((10, 12), 1.0)
    there, ok_there = landing_pixels(disparity, ds, dt)
    back, ok_back = landing_pixels(disparity, -ds, -dt)
    ids = torch.arange(120)
    inside = ok_there & ok_back[there.clamp(min=0)]
    assert torch.equal(back[there[inside]], ids[inside])


def test_shift_with_disparity_matches_shift_masks_and_carries_the_slant():
    mask = torch.zeros((1, 12, 16), dtype=torch.bool)
    mask[0, 3:9, 2:12] = True
    disparity = torch.linspace(0.0, 1.5, 16)[None].repeat(12, 1)
    shifts = torch.tensor([[0.0, 3.0]])
    shifted, shown = shift_masks_with_disparity(mask, disparity, shifts)
    assert torch.equal(shifted, shift_masks(mask, shifts))
    # Pixel (5, v + 3) shows what pixel (5, v) showed.
    assert torch.allclose(shown[0, 5, 5:15], disparity[5, 2:12], atol=1e-5)
    assert bool(torch.isneginf(shown[~shifted]).all())


# --- geometric occluding on rendered scenes ---------------------------------------------------


def _slanted(label, center, half, plane, texture="noise"):
    return PlanarObject(
        label=label, shape="rounded_rect", center=center, half_size=half, angle=0.0,
        plane=plane, texture=texture, texture_seed=label,
    )


def _background():
    return PlanarObject(
        label=1, shape="plane", center=(20.0, 30.0), half_size=(80.0, 80.0), angle=0.0,
        plane=(0.0, 0.0, 0.0), texture="noise", texture_seed=0,
    )


@pytest.fixture(scope="module")
def slanted_alone():
    # A slanted object (disparity 0.5 at its left edge to 2.7 at its right) over a flat
    # background: nothing covers it in any view.
    obj = _slanted(2, (20.0, 30.0), (10.0, 18.0), (0.5 - 0.06 * 12.0, 0.0, 0.06))
    spec = SceneSpec(grid=(5, 5), size=(40, 60), objects=(_background(), obj))
    return render_scene(spec, supersample=1)


@pytest.fixture(scope="module")
def slanted_behind_bar():
    # The same slanted object behind a nearer vertical bar at integer disparity 4.
    obj = _slanted(2, (20.0, 30.0), (10.0, 18.0), (0.5 - 0.06 * 12.0, 0.0, 0.06))
    bar = _slanted(3, (20.0, 30.0), (19.0, 2.0), (4.0, 0.0, 0.0), texture="checker")
    spec = SceneSpec(grid=(5, 5), size=(40, 60), objects=(_background(), obj, bar))
    return render_scene(spec, supersample=1)


def _object_masks(lf, occlusion, propagation, point):
    config = PipelineConfig(refine=False, occlusion=occlusion, propagation=propagation)
    result = segment(
        lf, make_prompts([point]), model=load_segmenter("oracle", lightfield=lf),
        disparity=lf.center_disparity,
        options=SegmentOptions(pipeline=config, run=RunOptions(progress=False)),
    )
    return result.masks.mask(0)


@pytest.mark.parametrize("propagation", ["pixel", "mean", "median"])
def test_geometric_occluding_keeps_every_pixel_of_an_unoccluded_slanted_object(
    slanted_alone, propagation
):
    plain = _object_masks(slanted_alone, "none", propagation, (30.0, 20.0))
    geometric = _object_masks(slanted_alone, "geometric", propagation, (30.0, 20.0))
    assert plain.sum() > 25 * 100  # the object, in all 25 views
    assert np.array_equal(geometric, plain)


def test_whole_mask_occluding_no_longer_compares_with_one_disparity():
    # The old test (z-buffer > the mask's mean disparity + tolerance) removes the near side of a
    # slanted mask; comparing each pixel with its own disparity removes nothing.
    disparity = torch.zeros((20, 40))
    disparity[5:15, 5:35] = torch.linspace(0.5, 2.5, 30)[None]
    mask = (disparity > 0)[None]
    warp = forward_warp(disparity, 0, 2)
    coarse = propagate_masks(mask, disparity, 0, 2, "mean")
    mean = disparity[mask[0]].mean()
    old_hidden = warp.zbuffer.reshape(20, 40) > mean + 0.2
    assert int((coarse[0] & old_hidden).sum()) > 0
    fixed = propagate_masks(mask, disparity, 0, 2, "mean", occlusion_tolerance=0.2)
    assert torch.equal(fixed, coarse)


@pytest.mark.parametrize("propagation", ["pixel", "mean", "median"])
def test_geometric_occluding_removes_what_a_nearer_object_covers(slanted_behind_bar, propagation):
    lf = slanted_behind_bar
    point = (45.0, 20.0)  # on the slanted object, right of the bar
    assert lf.center_labels[20, 45] == 2
    bar = lf.labels == 3
    plain = _object_masks(lf, "none", propagation, point)
    geometric = _object_masks(lf, "geometric", propagation, point)
    assert (plain & bar).sum() > 100  # without occluding the mask spills over the bar
    assert (geometric & bar).sum() == 0  # the bar's pixels are all removed
    assert not (geometric & ~plain).any()
    if propagation != "pixel":
        # A whole-mask shift loses exactly what the bar covers (the bar lands exactly).
        assert np.array_equal(geometric, plain & ~bar)


def _reference_holes(warp, size):
    """The hole list as the docstring of ``ForwardWarp.hole_sources`` defines it, with a
    boolean selection (the form it had before the dense index)."""
    height, width = size
    filled = warp.hole_disparity(size)
    landed = torch.isfinite(warp.zbuffer).reshape(size)
    hole_u, hole_v = torch.nonzero(~landed & torch.isfinite(filled), as_tuple=True)
    d = filled[hole_u, hole_v]
    src_u = torch.round(hole_u + d * warp.ds).long()
    src_v = torch.round(hole_v + d * warp.dt).long()
    ok = (src_u >= 0) & (src_u < height) & (src_v >= 0) & (src_v < width)
    return hole_u[ok], hole_v[ok], src_u[ok], src_v[ok]


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    ds=st.integers(-3, 3),
    dt=st.integers(-3, 3),
    objects=st.integers(0, 3),
    keep=st.booleans(),
)
def test_dense_hole_filling_equals_the_hole_list(seed, ds, dt, objects, keep):
    """The dense hole index (no host round trip, issue 44) gives the same holes, the same
    seen pixels and the same filled masks as the hole list, with and without ``keep``."""
    rng = np.random.default_rng(seed)
    size = (int(rng.integers(3, 14)), int(rng.integers(3, 14)))
    disparity = torch.as_tensor(rng.uniform(-2.5, 2.5, size), dtype=torch.float32)
    disparity[torch.as_tensor(rng.random(size) < 0.1)] = float("nan")
    warp = forward_warp(disparity, ds, dt)
    expected = _reference_holes(warp, size)
    for got, want in zip(warp.hole_sources(size), expected, strict=True):
        assert torch.equal(got, want)
    seen = torch.isfinite(warp.zbuffer).reshape(size).clone()
    seen[expected[0], expected[1]] = True
    assert torch.equal(warp.seen(size), seen)
    masks = torch.as_tensor(rng.random((objects, *size)) < 0.5)
    coarse = torch.as_tensor(rng.random((objects, *size)) < 0.5)
    visible = torch.as_tensor(rng.random(size[0] * size[1]) < 0.7) if keep else None
    sparse = fill_warp_holes(coarse, masks, warp, visible, dense=False)
    dense = fill_warp_holes(coarse, masks, warp, visible, dense=True)
    assert torch.equal(sparse, dense)
    # the holes, and only they, changed to their sources' values
    hole_u, hole_v, src_u, src_v = expected
    want = coarse.clone()
    values = masks[:, src_u, src_v]
    if visible is not None:
        values &= visible.reshape(size)[src_u, src_v]
    want[:, hole_u, hole_v] = values
    assert torch.equal(dense, want)
