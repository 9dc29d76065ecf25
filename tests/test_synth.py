"""The synthetic light-field generator: content, exact ground truth, determinism."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.ndimage import binary_erosion

import lfsam.synth.render as render_module
from lfsam.errors import LfsamError
from lfsam.synth import (
    TEXTURES,
    PlanarObject,
    SceneSpec,
    demo_scene,
    generate_scene,
    make_texture,
    random_scene,
    render_scene,
    sample_geometry,
)


@pytest.fixture(scope="module")
def scene():
    return generate_scene(grid=(5, 5), size=(48, 64), seed=3, num_objects=4)


def test_shapes_dtypes_and_labels(scene):
    assert scene.views.shape == (5, 5, 48, 64, 3) and scene.views.dtype == np.uint8
    assert scene.disparity.shape == (5, 5, 48, 64) and scene.disparity.dtype == np.float32
    assert scene.labels.shape == (5, 5, 48, 64) and scene.labels.dtype == np.int32
    # Background = 1, objects 2..5; every object is visible in the center view.
    assert set(np.unique(scene.center_labels)) == {1, 2, 3, 4, 5}
    assert scene.labels.min() == 1  # every pixel of every view is labelled
    assert scene.meta["format"] == "synth" and scene.meta["seed"] == 3


def test_disparities_lie_in_the_range_and_some_objects_are_slanted():
    lf = generate_scene(
        grid=(3, 3), size=(40, 56), seed=9, num_objects=6, disparity_range=(-1.0, 3.0)
    )
    assert lf.disparity.min() >= -1.0 - 1e-6 and lf.disparity.max() <= 3.0 + 1e-6
    # Background in the farthest part of the range, objects in front of it.
    center_d, center_l = lf.center_disparity, lf.center_labels
    assert center_d[center_l == 1].max() < center_d[center_l > 1].min()
    slanted = [o for o in lf.meta["generator"]["objects"][1:] if any(o["slope"])]
    assert slanted
    for obj in slanted:
        values = center_d[center_l == obj["label"]]
        assert values.max() - values.min() > 0.01
    # Sub-pixel: disparities are not whole numbers.
    assert np.mean(np.abs(center_d - np.round(center_d)) > 0.05) > 0.5


def test_unlabelled_background():
    lf = generate_scene(grid=(3, 3), size=(24, 32), seed=1, num_objects=2, label_background=False)
    assert set(np.unique(lf.center_labels)) == {0, 1, 2}


def test_deterministic_per_seed():
    a = generate_scene(grid=(3, 3), size=(24, 32), seed=7, num_objects=3)
    b = generate_scene(grid=(3, 3), size=(24, 32), seed=7, num_objects=3)
    c = generate_scene(grid=(3, 3), size=(24, 32), seed=8, num_objects=3)
    np.testing.assert_array_equal(a.views, b.views)
    np.testing.assert_array_equal(a.disparity, b.disparity)
    np.testing.assert_array_equal(a.labels, b.labels)
    assert not np.array_equal(a.views, c.views)


def _two_plane_scene(grid=(3, 3), size=(40, 48)):
    """Background at disparity 0 and an ellipse at disparity exactly 2 (integer shifts)."""
    background = PlanarObject(
        1, "plane", (19.5, 23.5), (40.0, 44.0), 0.0, (0.0, 0.0, 0.0), "noise", 5
    )
    disc = PlanarObject(2, "ellipse", (20.0, 22.0), (9.0, 12.0), 0.4, (2.0, 0.0, 0.0), "checker", 6)
    return SceneSpec(grid, size, (background, disc))


def test_integer_disparity_moves_content_by_exact_pixels():
    spec = _two_plane_scene()
    lf = render_scene(spec, supersample=2)
    center = lf.center
    for s in range(3):
        for t in range(3):
            ds, dt = s - center[0], t - center[1]
            # Center pixel (u, v) of the disc is at (u - 2 ds, v - 2 dt) in view (s, t).
            mask = lf.center_labels == 2
            u, v = np.nonzero(mask)
            np.testing.assert_array_equal(lf.labels[s, t][u - 2 * ds, v - 2 * dt], 2)
            assert (lf.labels[s, t] == 2).sum() == mask.sum()
            np.testing.assert_array_equal(lf.disparity[s, t][u - 2 * ds, v - 2 * dt], 2.0)
            # Inside the disc (away from its anti-aliased rim, which mixes in the background
            # that does not move) the colours move with it: the same texture samples, up to
            # rounding.
            iu, iv = np.nonzero(binary_erosion(mask, np.ones((3, 3))))
            diff = lf.views[s, t][iu - 2 * ds, iv - 2 * dt].astype(int) - lf.center_view[iu, iv]
            assert np.abs(diff).max() <= 1
            # The background (disparity 0) does not move where the disc is in neither view.
            free = binary_erosion((lf.labels[s, t] == 1) & (lf.center_labels == 1), np.ones((3, 3)))
            assert np.abs(lf.views[s, t][free].astype(int) - lf.center_view[free]).max() <= 1


def test_render_matches_exact_geometry_at_pixel_centres(scene):
    spec = random_scene(grid=(5, 5), size=(48, 64), seed=3, num_objects=4)
    rows, cols = np.meshgrid(np.arange(48), np.arange(64), indexing="ij")
    for s, t in [(0, 0), (2, 2), (4, 1)]:
        labels, disparity = sample_geometry(spec, s, t, rows, cols)
        np.testing.assert_array_equal(scene.labels[s, t], labels)
        np.testing.assert_array_equal(scene.disparity[s, t], disparity.astype(np.float32))


def test_scene_has_occlusions_and_disocclusions(scene):
    center = scene.center
    u, v = np.nonzero(scene.center_labels > 1)
    d = scene.center_disparity[u, v]
    hidden = 0
    for s, t in [(0, 0), (4, 4), (0, 4), (4, 0)]:
        pu = np.round(u - d * (s - center[0])).astype(int)
        pv = np.round(v - d * (t - center[1])).astype(int)
        ok = (pu >= 0) & (pu < 48) & (pv >= 0) & (pv < 64)
        seen = scene.labels[s, t][pu[ok], pv[ok]]
        hidden += int(
            np.sum(
                (seen != scene.center_labels[u, v][ok])
                & (scene.disparity[s, t][pu[ok], pv[ok]] > d[ok] + 0.05)
            )
        )
    assert hidden > 20


def test_supersampling_smooths_edges_only():
    spec = random_scene(grid=(1, 1), size=(48, 64), seed=12, num_objects=4)
    sharp = render_scene(spec, supersample=1)
    smooth = render_scene(spec, supersample=4)
    labels = sharp.labels[0, 0]
    edge = np.zeros_like(labels, dtype=bool)
    edge[:, 1:] |= labels[:, 1:] != labels[:, :-1]
    edge[:, :-1] |= labels[:, 1:] != labels[:, :-1]
    edge[1:] |= labels[1:] != labels[:-1]
    edge[:-1] |= labels[1:] != labels[:-1]
    diff = np.abs(sharp.views[0, 0].astype(float) - smooth.views[0, 0]).mean(axis=-1)
    assert diff[edge].mean() > 2 * diff[~edge].mean()
    np.testing.assert_array_equal(sharp.labels, smooth.labels)


@pytest.mark.parametrize("name", TEXTURES)
def test_textures_are_deterministic_and_textured(name):
    a = make_texture(name, 4, (40, 60), zoom=2)
    b = make_texture(name, 4, (40, 60), zoom=2)
    assert a.shape == (3, 40, 60) and a.dtype == torch.float32
    assert torch.equal(a, b)
    assert 0.0 <= float(a.min()) and float(a.max()) <= 1.0
    assert float(a.std()) > 0.03
    assert not torch.equal(a, make_texture(name, 5, (40, 60), zoom=2))


def test_bad_settings_are_user_errors():
    with pytest.raises(LfsamError, match="LO < HI"):
        generate_scene(grid=(3, 3), size=(16, 16), disparity_range=(1.0, 1.0))
    with pytest.raises(LfsamError, match="grid"):
        generate_scene(grid=(0, 3), size=(16, 16))
    with pytest.raises(LfsamError, match="at least 8x8"):
        generate_scene(grid=(3, 3), size=(4, 16))


def test_demo_scene_is_the_documented_default(monkeypatch):
    calls = []
    monkeypatch.setattr(render_module, "generate_scene", lambda **kw: calls.append(kw) or "lf")
    assert demo_scene() == "lf"
    assert calls == [{"grid": (9, 9), "size": (240, 320), "seed": 0}]
