"""The search of issue 47 across the light field (docs/design.md section 10, "Tracking"): an
object hidden in the center and corner views but seen in another view of the ring is found
there in the first frame it shows; the disparity tells an object from a background of the same
colours; the vectorised matching gives the numbers of the plain one."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from lfsam.prompts import ObjectPrompts
from lfsam.video.tracking import carry, match, rules
from lfsam.video.tracking.carry import MAX_PIXEL_DIFFERENCE, Template
from lfsam.video.tracking.search import Track, search_object

GRID, CENTER, SIZE = (5, 5), (2, 2), (40, 50)
RING = [(0, 0), (0, 2), (0, 4), (2, 0), (2, 4), (4, 0), (4, 2), (4, 4)]


def _texture(seed: int, shape=SIZE) -> np.ndarray:
    return np.random.default_rng(seed).uniform(0, 255, (*shape, 3)).astype(np.float32)


def _scene(shown_in: set[tuple[int, int]], place=(15, 20), side=8):
    """Per view: an image and labels (1 background, 2 the object where shown). The object is
    the same textured square in every view where it is shown (no parallax: disparity 0);
    elsewhere it is covered by a flat grey occluder (label 3)."""
    object_look = _texture(1, (side, side))
    images, labels = {}, {}
    for s in range(GRID[0]):
        for t in range(GRID[1]):
            image, label = _texture(100 + 7 * s + t), np.ones(SIZE, np.int64)
            r, c = place
            if (s, t) in shown_in:
                image[r:r + side, c:c + side] = object_look
                label[r:r + side, c:c + side] = 2
            else:
                image[r - 2:r + side + 2, c - 2:c + side + 2] = 128.0
                label[r - 2:r + side + 2, c - 2:c + side + 2] = 3
            images[(s, t)], labels[(s, t)] = image, label
    return images, labels, object_look


def _oracle(labels):
    """``answer(prompts)``: the label under the first positive point in the prompted view."""
    asked = []

    def answer(obj: ObjectPrompts):
        point = next(p for p in obj.points if p.positive)
        view = point.view or CENTER
        asked.append(view)
        label = labels[view][round(point.y), round(point.x)]
        return view, labels[view] == label

    return answer, asked


def _search(images, labels, track, views, disparities=None):
    answer, asked = _oracle(labels)
    found = search_object(1, track, lambda v: images[v], CENTER, views, answer,
                          lambda v: None, None, (), False, disparities=disparities)
    return found, asked


def test_an_object_hidden_in_the_center_and_corners_is_found_in_a_ring_view():
    """Seen only in the top edge's middle view: found there (the corners alone miss it)."""
    images, labels, look = _scene({(0, 2)})
    side = look.shape[0]
    template = Template(look, np.ones((side, side), bool), (13, 18))  # 2 pixels off
    track = Track(CENTER, template, unseen=1, area=side * side, sightings=2)
    found, asked = _search(images, labels, track, RING)
    assert found is not None
    view, mask, _, located = found
    assert view == (0, 2) and located.origin == (15, 20)
    np.testing.assert_array_equal(mask, labels[(0, 2)] == 2)
    assert asked[0] == (0, 2)  # prompted where it is seen most, first
    corners = [v for v in RING if v[0] != 2 and v[1] != 2]
    assert _search(images, labels, track, corners)[0] is None  # the corners alone: not found


def test_the_disparity_tells_an_object_from_a_background_of_its_colours(monkeypatch):
    """A flat object in front of a background of the same colour: without the disparity every
    shift looks the same (the template stays at its predicted place, on the background);
    with it, the object is found where it moved. (Without it, the second look at its own
    view with the refused background's pixels left out, ``rules.REFUSED_AGAIN``, finds it
    too: the match alone is compared here.)"""
    image = np.full((*SIZE, 3), 90.0, np.float32)
    disparity = np.full(SIZE, -1.8, np.float32)
    disparity[20:30, 24:34] = 1.5  # the object, moved by (4, 5) since the last frame
    labels = {v: np.where(disparity > 0, 2, 1) for v in [CENTER, *RING]}
    images = {v: image for v in labels}
    template = Template(np.full((10, 10, 3), 90.0, np.float32), np.ones((10, 10), bool),
                        (16, 19))
    track = Track(CENTER, template, disparity=1.5, area=100, sightings=2)
    found, _ = _search(images, labels, track, RING, disparities=lambda v: disparity)
    assert found is not None and found[2] == (4, 5)
    np.testing.assert_array_equal(found[1], disparity > 0)
    monkeypatch.setattr(rules, "REFUSED_AGAIN", False)
    without, _ = _search(images, labels, track, RING)
    assert without is None or without[2] != (4, 5)


@pytest.mark.parametrize("origin, radius", [((12, 15), 6), ((1, 2), 9), ((30, 40), None),
                                            ((-4, 44), 5)])
def test_the_vectorised_matching_gives_the_plain_numbers(origin, radius):
    rng = np.random.default_rng(3)
    image = rng.uniform(0, 255, (*SIZE, 4)).astype(np.float32)
    template = Template(rng.uniform(0, 255, (9, 11, 4)).astype(np.float32),
                        rng.random((9, 11)) > 0.3, origin)
    plain, du, dv = carry.cost_map(template, image, radius)
    fast, du2, dv2 = match.cost_map(template, image, radius)
    np.testing.assert_array_equal(du, du2)
    np.testing.assert_array_equal(dv, dv2)
    np.testing.assert_array_equal(np.isfinite(plain), np.isfinite(fast))
    finite = np.isfinite(plain)
    np.testing.assert_allclose(fast[finite], plain[finite], rtol=1e-4, atol=0.5)
    # the robust cost of many shifts at once against one shift at a time (RGB only)
    rgb = replace(template, image=template.image[..., :3])
    shifts = [(-3, 2), (0, 0), (5, -7), (-60, 0)]
    costs, counts = match.robust_costs(rgb, image[..., :3], *np.array(shifts).T)
    for (a, b), cost, count in zip(shifts, costs, counts, strict=True):
        total, support = 0.0, 0
        for r, c in zip(*np.nonzero(rgb.mask), strict=True):
            y, x = origin[0] + a + r, origin[1] + b + c
            d = MAX_PIXEL_DIFFERENCE
            if 0 <= y < SIZE[0] and 0 <= x < SIZE[1]:
                d = min(float(np.abs(image[y, x, :3] - rgb.image[r, c]).sum()), d)
            total += d
            support += d < MAX_PIXEL_DIFFERENCE
        assert cost == pytest.approx(total, rel=1e-5) and count == support


def _light_field(shown_in: set[tuple[int, int]]):
    from lfsam.lightfield import LightField

    images, labels, _ = _scene(shown_in, side=12)
    order = [(s, t) for s in range(GRID[0]) for t in range(GRID[1])]
    views = np.stack([images[v] for v in order]).reshape(*GRID, *SIZE, 3)
    label = np.stack([labels[v] for v in order]).reshape(*GRID, *SIZE).astype(np.int32)
    return LightField(np.clip(views, 0, 255).astype(np.uint8),
                      np.zeros((*GRID, *SIZE), np.float32), label)


def test_a_tracked_object_covered_in_the_center_and_corners_is_kept_from_a_ring_view():
    """Frame 1 shows the object only in view (0, 2): the tracker carries it from there in that
    very frame, under its id (before, only the corners were searched: hidden)."""
    from lfsam.api import RunOptions, SegmentOptions
    from lfsam.prompts import PointPrompt
    from lfsam.video.tracking.online import OnlineTracker

    every = {(s, t) for s in range(GRID[0]) for t in range(GRID[1])}
    frames = [_light_field(every), _light_field({(0, 2)})]
    tracker = OnlineTracker("oracle", disparity="gt",
                            options=SegmentOptions(run=RunOptions(progress=False)))
    tracker.add_prompts([ObjectPrompts(1, (PointPrompt(26.0, 21.0),))])
    first = tracker.track(frames[0])
    assert first.meta["tracks"] == {"1": "prompted"}
    result = tracker.track(frames[1])
    assert result.meta["tracks"] == {"1": "tracked"}
    gt, ours = frames[1].labels[0, 2] == 2, result.labels[0, 2] == 1
    assert (gt & ours).sum() >= 0.5 * (gt | ours).sum()
