"""An answer's place (issue 47, docs/design.md section 10, "Tracking" step 8): a partly hidden
object's template placed where it explains SAM's answer, its occluder contradicting nothing and
a background farther than the object contradicting every place where the object would show;
seed 403's ellipse behind the near occluder tracked through the frames it was lost in."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lfsam.api import RunOptions, SegmentOptions
from lfsam.prompts import ObjectPrompts, PointPrompt
from lfsam.video.io.synth import generate_video
from lfsam.video.tracking import placement, rules
from lfsam.video.tracking.carry import Template, deepest
from lfsam.video.tracking.online import OnlineTracker
from lfsam.video.tracking.placement import answer_place, placed_by_answer

QUIET = SegmentOptions(run=RunOptions(progress=False))

SHAPE = (64, 80)
TRUE = (20, 30)  # the object's template origin


def _scene(cover: float, seed: int = 0):
    """A textured disc (disparity 1) in front of a textured background (-1), its right part
    ``cover`` behind a near occluder (2): the view, its disparity, the answer (the disc's
    visible pixels) and the disc's whole template."""
    rng = np.random.default_rng(seed)
    image = rng.uniform(0, 255, (*SHAPE, 3)).astype(np.float32)
    disparity = np.full(SHAPE, -1.0, np.float32)
    rows, cols = np.mgrid[:24, :24]
    disc = (rows - 11.5) ** 2 + (cols - 11.5) ** 2 <= 11.5**2
    look = rng.uniform(0, 255, (24, 24, 3)).astype(np.float32)
    r0, c0 = TRUE
    region = (slice(r0, r0 + 24), slice(c0, c0 + 24))
    image[region][disc] = look[disc]
    disparity[region][disc] = 1.0
    mask = np.zeros(SHAPE, bool)
    mask[region] = disc
    edge = c0 + round(24 * (1 - cover))
    image[r0 - 4:r0 + 28, edge:c0 + 30] = 40.0  # the occluder, plain
    disparity[r0 - 4:r0 + 28, edge:c0 + 30] = 2.0
    mask[:, edge:] = False
    return image, disparity, mask, Template(look, disc, TRUE)


def _at(template: Template, du: int, dv: int) -> Template:
    return Template(template.image, template.mask,
                    (template.origin[0] + du, template.origin[1] + dv))


@settings(max_examples=25, deadline=None)
@given(du=st.integers(-6, 6), dv=st.integers(-6, 6), cover=st.floats(0.3, 0.6),
       seed=st.integers(0, 5))
def test_the_template_goes_where_it_explains_the_answer(du, dv, cover, seed):
    image, disparity, mask, template = _scene(cover, seed)
    shift = answer_place(mask, _at(template, du, dv), image, disparity, 1.0, 8)
    assert shift == (None if (du, dv) == (0, 0) else (-du, -dv))
    placed = placed_by_answer(_at(template, du, dv), mask, image, disparity, 1.0, 8)
    assert placed.origin == TRUE


def test_a_farther_background_beside_the_answer_decides_a_plain_objects_place():
    """A plain rectangle (disparity 1), its right 60 % behind an occluder (2): its colour
    and the answer fit its template at every shift that covers the answer; only the
    background (-1), which would be hidden where the rectangle lay, tells where it is."""
    image = np.full((*SHAPE, 3), 200.0, np.float32)
    disparity = np.full(SHAPE, -1.0, np.float32)
    r0, c0 = TRUE
    image[r0:r0 + 16, c0:c0 + 20] = 90.0
    disparity[r0:r0 + 16, c0:c0 + 20] = 1.0
    image[r0 - 4:r0 + 20, c0 + 8:c0 + 26] = 40.0
    disparity[r0 - 4:r0 + 20, c0 + 8:c0 + 26] = 2.0
    mask = (image == 90.0).all(-1)
    template = Template(np.full((16, 20, 3), 90.0, np.float32), np.ones((16, 20), bool),
                        (r0, c0 - 5))
    assert answer_place(mask, template, image, disparity, 1.0, 8) == (0, 5)
    unknown = np.where(disparity == -1.0, np.nan, disparity).astype(np.float32)
    assert answer_place(mask, template, image, unknown, 1.0, 8) is None
    # the occluder read as farther than the rectangle: the rectangle would show there
    farther = np.where(disparity == 2.0, -1.5, disparity).astype(np.float32)
    assert answer_place(mask, template, image, farther, 1.0, 8) is None


def test_an_answer_that_is_not_the_object_moves_nothing():
    image, disparity, mask, template = _scene(0.4)
    other = Template(np.full_like(template.image, 128.0), template.mask, template.origin)
    assert answer_place(mask, _at(other, 3, -2), image, disparity, 1.0, 8) is None


def test_no_reach_no_answer_or_a_template_cut_by_the_border_moves_nothing():
    image, disparity, mask, template = _scene(0.5)
    cut = Template(template.image, template.mask, (-15, TRUE[1] + 2))
    assert answer_place(mask, cut, image, disparity, 1.0, 8) is None
    assert answer_place(mask, _at(template, 2, 2), image, disparity, 1.0, 0) is None
    assert answer_place(np.zeros_like(mask), _at(template, 2, 2), image, disparity, 1.0,
                        8) is None


def _deepest(mask):
    row, col, _ = deepest(mask)
    return PointPrompt(float(col), float(row))


@pytest.fixture(scope="module")
def behind():
    """Seed 403's first nine frames (5x5 views of 96x128, the hard cases): the object of label
    6, an ellipse whose depth swings behind the near occluder, shows 137-233 of its pixels in
    frames 2-8."""
    return list(itertools.islice(generate_video(grid=(5, 5), size=(96, 128), frames=12,
                                                seed=403, num_objects=5, hard=True), 9))


def _center_ious(frames, label: int) -> list[float]:
    """The object's center-view IoU in each frame, tracked from one click per object."""
    labels = frames[0].labels[frames[0].center]
    prompts = [ObjectPrompts(k + 1, (_deepest(labels == value),))
               for k, value in enumerate(v for v in np.unique(labels[labels > 1])
                                         if (labels == v).sum() >= 100)]
    obj_id = next(p.obj_id for p in prompts
                  if labels[round(p.points[0].y), round(p.points[0].x)] == label)
    tracker = OnlineTracker("oracle", disparity="gt", options=QUIET, search=True, memory=False)
    tracker.add_prompts(prompts)
    ious = []
    for lf in frames:
        ours = tracker.track(lf).labels[lf.center] == obj_id
        truth = lf.labels[lf.center] == label
        ious.append(float((ours & truth).sum() / max((ours | truth).sum(), 1)))
    return ious


def test_a_behind_the_occluder_is_kept_where_its_answers_place_it(behind,
                                                                      monkeypatch):
    shown = [int((lf.labels[lf.center] == 6).sum()) for lf in behind]
    assert shown[1] < 100 and min(shown[2:]) >= 100
    ious = _center_ious(behind, 6)
    assert min(ious[2:]) >= 0.9, ious
    # placed by its matches alone, it drifts off and is lost at frame 8 (unless the ring's
    # views count only what the objects placed in the frame leave of it, sixteenth pass:
    # that also finds it there)
    monkeypatch.setattr(placement, "CHECK", False)
    assert _center_ious(behind, 6)[8] >= 0.9
    monkeypatch.setattr(rules, "PLACED_SUPPORT", False)
    assert _center_ious(behind, 6)[8] < 0.5
