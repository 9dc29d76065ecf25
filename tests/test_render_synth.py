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


def test_removal_fills_what_other_views_see_and_flags_the_rest(scene):
    """Judged by the scene's truth (lfsam.synth.seen_behind), not by the removal's own flags:
    few pixels that no view sees are claimed as filled, most that another view sees are filled,
    and on a scene whose object stands clear of the others every view's seen pixels are close
    to the twin."""
    from lfsam.synth import seen_behind

    lf, obj, twin = scene
    sc, tc = lf.center
    masks = lf.labels == obj
    views, unseen = remove_objects(lf.views, masks, lf.disparity[sc, tc])
    seen = seen_behind(lf, twin, [obj])
    assert seen.sum() > 500 and (masks & ~seen).sum() > 500  # both kinds of pixel are there
    claimed = masks & ~unseen
    assert (claimed & ~seen).sum() <= 0.05 * claimed.sum()
    assert (claimed & seen).sum() >= 0.5 * seen.sum()
    settings = {**SETTINGS, "seed": 11}
    lf = generate_scene(**settings)
    twin = generate_scene_without([3], **settings)
    masks = lf.labels == 3
    views, unseen = remove_objects(lf.views, masks, lf.disparity[sc, tc])
    seen = seen_behind(lf, twin, [3])
    for s in range(lf.grid_shape[0]):
        for t in range(lf.grid_shape[1]):
            if seen[s, t].sum() > 20:
                assert _psnr(views[s, t][seen[s, t]], twin.views[s, t][seen[s, t]]) >= 30.0


def test_the_rim_splits_into_the_surfaces_behind_an_object():
    """A wall and, on one side, a box nearer than the wall but behind the object: both planes,
    exactly, and where each may continue."""
    from lfsam.render.background_disparity import REACH, rim_surfaces

    rows, cols = np.mgrid[0:60, 0:80].astype(np.float64)
    disparity = -1.5 + 0.004 * rows - 0.002 * cols  # the wall, slanted
    box = cols >= 40
    disparity[box] = -0.7  # a box, fronto-parallel
    mask = (rows >= 20) & (rows < 40) & (cols >= 25) & (cols < 55)
    disparity[mask] = 1.2  # the object in front
    planes, near = rim_surfaces(disparity.astype(np.float32), mask)
    assert len(planes) == 2
    wall, boxed = sorted(planes, key=lambda p: p[0])
    assert np.allclose(wall, [-1.5, 0.004, -0.002], atol=1e-5)
    assert np.allclose(boxed, [-0.7, 0.0, 0.0], atol=1e-5)
    order = [int(np.argmin([abs(p[0] - q[0]) for p in planes])) for q in (wall, boxed)]
    assert near[order[1]][30, 50] and not near[order[1]][30, 26 - REACH]


def test_objects_in_front_of_the_focal_plane_are_the_nearer_other_objects():
    from lfsam.render import objects_in_front

    labels = np.zeros((3, 3, 10, 12), dtype=np.int32)
    labels[:, :, 1:4, 1:4] = 2  # near
    labels[:, :, 5:8, 1:4] = 3  # behind the focal plane
    labels[:, :, 1:4, 6:9] = 4  # the chosen object, near too
    labels[0, 0, 8:, 8:] = 5  # not in the center view: unknown depth, left alone
    disparity = np.full((10, 12), -1.0, dtype=np.float32)
    disparity[1:4, 1:4] = 1.5
    disparity[5:8, 1:4] = -1.5
    disparity[1:4, 6:9] = 1.0
    front = objects_in_front(labels, [4], disparity, focus=-1.0)
    assert np.array_equal(front, labels == 2)
    assert not objects_in_front(labels, [4], disparity, focus=1.4).any()  # within the margin


def test_see_through_leaves_out_the_other_objects_in_front_when_asked():
    """A nearer object beside the chosen one veils what lies behind it in the views that see
    across; leaving its rays out brings the see-through closer to the twin (on this scene,
    measured: 34.3 dB with them, 62.1 dB without)."""
    from lfsam.render import objects_in_front

    settings = {**SETTINGS, "seed": 1}
    lf, obj = generate_scene(**settings), 3
    twin = generate_scene_without([obj], **settings)
    sc, tc = lf.center
    masks = lf.labels == obj
    disparity = lf.disparity[sc, tc]
    focus = rim_disparity(masks[sc, tc], disparity)
    front = objects_in_front(lf.labels, [obj], disparity, focus)
    assert front.any()  # the scene holds a nearer object
    veiled, _ = see_through(lf.views, masks, focus=focus)
    clear, coverage = see_through(lf.views, masks, focus=focus, occluders=front)
    hidden = masks[sc, tc] & (coverage >= 0.25) & (np.abs(twin.disparity[sc, tc] - focus) < 0.25)
    truth = twin.views[sc, tc][hidden]
    assert hidden.sum() > 20
    assert _psnr(clear[hidden], truth) >= _psnr(veiled[hidden], truth) + 10.0
    kept = see_through(lf.views, masks, focus=focus, occluders=np.zeros_like(masks))
    assert np.array_equal(kept[0], veiled)  # no occluders: as without them


def test_pixels_too_deep_inside_the_masks_are_not_gathered_and_the_answer_is_the_same(
        scene, monkeypatch):
    """Removal leaves out the pixels no ray can reach (deeper inside every other view's mask
    than the candidates can move a ray); without that shortcut the answer is the same."""
    import lfsam.render.remove as remove

    lf, obj, _ = scene
    sc, tc = lf.center
    masks = lf.labels == obj
    gathered = []
    choose = remove._choose

    def counting(sources, n, ys, xs, *args):
        gathered.append(ys.numel())
        return choose(sources, n, ys, xs, *args)

    monkeypatch.setattr(remove, "_choose", counting)
    views, unseen = remove_objects(lf.views, masks, lf.disparity[sc, tc])
    pruned = sum(gathered)
    gathered.clear()
    monkeypatch.setattr(remove, "PRUNE_MARGIN", float("inf"))  # nothing is too deep
    every_views, every_unseen = remove_objects(lf.views, masks, lf.disparity[sc, tc])
    assert np.array_equal(views, every_views) and np.array_equal(unseen, every_unseen)
    assert pruned < sum(gathered), (pruned, sum(gathered))  # some were left out
