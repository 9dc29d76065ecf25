"""Rendering around objects against synthetic ground truth (issue 66; docs/design.md 13).

The twin of a scene without an object (lfsam.synth.generate_scene_without) is what lies
behind it: see-through and removal are compared with it. Small scenes, ground-truth center
disparity and labels (oracle masks) keep these fast; the benchmark (benchmarks/bench_render.py)
measures the same with estimated disparity on held-out seeds at full size.
"""

from __future__ import annotations

import numpy as np
import pytest

from lfsam.render import object_focus, refocus, remove_objects, see_through
from lfsam.render.background_disparity import rim_disparity
from lfsam.synth import generate_scene, generate_scene_without

SETTINGS = dict(grid=(5, 5), size=(64, 96), seed=21, num_objects=3)


def _psnr(a, b):
    mse = np.mean((np.asarray(a, float) - np.asarray(b, float)) ** 2)
    return 10 * np.log10(255.0**2 / max(mse, 1e-12))


@pytest.fixture(scope="module")
def scene():
    lf = generate_scene(**SETTINGS)
    obj = int(np.unique(lf.labels).max())  # the last object drawn
    twin = generate_scene_without([obj], **SETTINGS)
    return lf, obj, twin


def test_the_twin_is_the_scene_where_the_object_is_not(scene):
    lf, obj, twin = scene
    assert not (twin.labels == obj).any()
    far = ~np.isin(lf.labels, [obj])
    same = twin.labels[far] == lf.labels[far]
    assert same.mean() > 0.999
    assert np.array_equal(twin.disparity[far & (twin.labels == lf.labels)],
                          lf.disparity[far & (twin.labels == lf.labels)])


def test_see_through_shows_what_lies_behind(scene):
    lf, _, _ = scene
    sc, tc = lf.center
    ids, counts = np.unique(lf.labels[sc, tc], return_counts=True)
    obj = int(ids[1:][np.argmax(counts[1:])])  # the object most seen in the center view
    twin = generate_scene_without([obj], **SETTINGS)
    masks = lf.labels == obj
    disparity = lf.disparity[sc, tc]
    image, coverage = see_through(lf.views, masks, disparity=disparity)
    focus = rim_disparity(masks[sc, tc], disparity)
    hidden = masks[sc, tc] & (coverage >= 0.25)
    hidden &= np.abs(twin.disparity[sc, tc] - focus) < 0.25
    assert hidden.sum() > 50
    truth = twin.views[sc, tc][hidden]
    plain = refocus(lf.views, focus)
    assert _psnr(image[hidden], truth) >= 30.0
    assert _psnr(image[hidden], truth) >= _psnr(plain[hidden], truth) + 8.0
    assert coverage.min() >= 0.0 and coverage.max() <= 1.0
    assert np.all(image[coverage == 0] == 0)


def test_remove_fills_each_view_from_the_others(scene):
    lf, obj, twin = scene
    sc, tc = lf.center
    masks = lf.labels == obj
    views, unseen = remove_objects(lf.views, masks, lf.disparity[sc, tc])
    assert not (unseen & ~np.isin(lf.labels, [obj]) & ~_grown(masks)).any()
    assert np.array_equal(views[~_grown(masks)], lf.views[~_grown(masks)])
    for s in range(lf.grid_shape[0]):
        for t in range(lf.grid_shape[1]):
            filled = masks[s, t] & ~unseen[s, t]
            if filled.sum() > 20:
                assert _psnr(views[s, t][filled], twin.views[s, t][filled]) >= 30.0, (s, t)


def _grown(masks):
    import torch

    from lfsam.render.background_disparity import dilate

    return dilate(torch.from_numpy(masks), 1).numpy()


def test_refocus_on_a_fronto_parallel_object_is_sharp(scene):
    lf, _, _ = scene
    sc, tc = lf.center
    flat = [o["label"] for o in lf.meta["generator"]["objects"][1:]
            if o["slope"] == [0.0, 0.0]]
    assert flat, "the scene should hold a fronto-parallel object"
    label = flat[0]
    inner = _inner(lf.labels[sc, tc] == label)
    focus = object_focus(lf.labels[sc, tc] == label, lf.disparity[sc, tc])
    image = refocus(lf.views, focus)
    center = lf.views[sc, tc]
    assert _psnr(image[inner], center[inner]) >= 35.0
    rest = lf.labels[sc, tc] == 1
    assert _psnr(image[rest], center[rest]) < 30.0  # the rest visibly blurred


def _inner(mask):
    """The object's pixels all of whose rays hit it (its mask, eroded by the aperture's reach)."""
    import torch

    from lfsam.render.background_disparity import dilate

    return ~dilate(torch.from_numpy(~mask), 3).numpy()
