"""A track that jumps onto a look-alike keeps its shadow (issue 47, eighth pass;
docs/design.md section 10, "Tracking", :mod:`lfsam.video.tracking.consistency`): an object that goes
behind an occluder while a look-alike of its pixels sits near its path at another depth is
matched on the look-alike (a well supported match); the jump, far from the prediction and at
another depth, keeps the track before it as a shadow, searched for every frame, and the
object takes its id back where it comes out (before: the look-alike kept the id for good)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from lfsam.api import RunOptions, SegmentOptions
from lfsam.lightfield import LightField
from lfsam.prompts import ObjectPrompts, PointPrompt
from lfsam.video.io.synth import generate_video
from lfsam.video.tracking import consistency
from lfsam.video.tracking.carry import Template
from lfsam.video.tracking.motion import VELOCITY_SUPPORT, Track, search_radius
from lfsam.video.tracking.online import OnlineTracker
from search_oracle import least_ious

GRID, CENTER, SIZE, SIDE = (5, 5), (2, 2), (44, 60), 8
QUIET = SegmentOptions(run=RunOptions(progress=False))
#: The object's row and its columns per frame (3 pixels a frame); None: behind the occluder.
ROW, COLUMNS = 8, [5, 8, 11, None, 17, 20]
#: The occluder's columns (frames 3 and 4), the look-alike's place and disparity.
OCCLUDER = (12, 21)
LOOK_ALIKE, LOOK_ALIKE_DISPARITY = (20, 14), 1.0


def _frame(index: int) -> LightField:
    """One frame: a textured background (disparity 0, the same in every view), the object
    (label 2, disparity 0), from frame 3 a look-alike with the object's very pixels (label 4,
    disparity 1, its parallax rendered) and in frames 3-4 a flat occluder in front of the
    object's path (label 3)."""
    rng = np.random.default_rng(7)
    background = rng.uniform(0, 255, (*SIZE, 3))
    look = np.random.default_rng(8).uniform(0, 255, (SIDE, SIDE, 3))
    views = np.empty((*GRID, *SIZE, 3))
    labels = np.ones((*GRID, *SIZE), np.int32)
    disparity = np.zeros((*GRID, *SIZE), np.float32)
    for s in range(GRID[0]):
        for t in range(GRID[1]):
            image, label, depth = views[s, t], labels[s, t], disparity[s, t]
            image[:] = background
            if index >= 3:
                r = round(LOOK_ALIKE[0] - LOOK_ALIKE_DISPARITY * (s - CENTER[0]))
                c = round(LOOK_ALIKE[1] - LOOK_ALIKE_DISPARITY * (t - CENTER[1]))
                image[r:r + SIDE, c:c + SIDE] = look
                label[r:r + SIDE, c:c + SIDE] = 4
                depth[r:r + SIDE, c:c + SIDE] = LOOK_ALIKE_DISPARITY
            if COLUMNS[index] is not None:
                c = COLUMNS[index]
                image[ROW:ROW + SIDE, c:c + SIDE] = look
                label[ROW:ROW + SIDE, c:c + SIDE] = 2
            if index in (3, 4):
                image[ROW - 2:ROW + SIDE + 2, OCCLUDER[0]:OCCLUDER[1]] = 128.0
                label[ROW - 2:ROW + SIDE + 2, OCCLUDER[0]:OCCLUDER[1]] = 3
    return LightField(np.clip(views, 0, 255).astype(np.uint8), disparity, labels)


def _tracked() -> list:
    tracker = OnlineTracker("oracle", disparity="gt", options=QUIET)
    tracker.add_prompts([ObjectPrompts(1, (PointPrompt(COLUMNS[0] + 4.0, ROW + 4.0),))])
    return [(frame, tracker.track(frame)) for frame in map(_frame, range(len(COLUMNS)))]


def _iou(frame: LightField, result, label: int) -> float:
    gt, ours = frame.labels[CENTER] == label, result.labels[CENTER] == 1
    return float((gt & ours).sum() / max((gt | ours).sum(), 1))


def test_the_object_takes_its_id_back_from_a_look_alike_it_jumped_to():
    """Frame 3: the object is behind the occluder, its match lies on the look-alike 12 rows
    below the prediction at disparity 1 (a jump: kept, doubted); frames 4-5: the object
    comes out where it was going and is found there under its id, the look-alike dropped
    (without the check the look-alike, a perfect match, kept the id in frames 4 and 5)."""
    frames = _tracked()
    assert frames[0][1].meta["tracks"] == {"1": "prompted"}
    for frame, result in frames[1:3]:
        assert _iou(frame, result, 2) == 1.0
    frame, result = frames[3]
    assert _iou(frame, result, 4) == 1.0  # the look-alike: the object shows nowhere
    for frame, result in frames[4:]:
        assert _iou(frame, result, 2) >= 0.5, frame
        assert _iou(frame, result, 4) == 0.0


def test_a_jump_needs_both_place_and_depth():
    """:func:`consistency.jumped`: far from the prediction (more than JUMP_SHARE of the
    search radius) and more than DEPTH_JUMP from the track's disparity; either alone is not a
    jump (a real turn, a real depth swing)."""
    template = Template(np.zeros((4, 4, 3), np.float32), np.ones((4, 4), bool), (10, 10))
    track = Track(CENTER, template, velocity=(0.0, 3.0), disparity=0.0, sightings=3)
    far = consistency.JUMP_SHARE * search_radius(track) + 2  # from (10, 13), the prediction
    at = Template(template.image, template.mask, (round(10 + far), 13))
    near = Template(template.image, template.mask, (11, 13))
    depth = consistency.DEPTH_JUMP + 0.3
    assert consistency.jumped(track, CENTER, at, depth, CENTER)
    assert not consistency.jumped(track, CENTER, at, 0.2, CENTER)
    assert not consistency.jumped(track, CENTER, near, depth, CENTER)
    consistency.doubt(track)
    shadow = track.shadow
    assert shadow is not None and shadow.template is template and shadow.shadow is None
    consistency.doubt(track)  # an older shadow stays
    assert track.shadow is shadow


def test_a_far_answer_on_a_poorly_supported_match_is_a_jump_at_any_depth(monkeypatch):
    """:data:`consistency.POORLY_SUPPORTED`: an answer far from the prediction on a match
    supporting under VELOCITY_SUPPORT of the template (a sliver whose place is no measure of
    the motion) is a jump at the track's own depth; a well supported one is not, nor a poorly
    supported one near the prediction."""
    template = Template(np.zeros((4, 4, 3), np.float32), np.ones((4, 4), bool), (10, 10))
    track = Track(CENTER, template, velocity=(0.0, 3.0), disparity=0.0, sightings=3)
    far = consistency.JUMP_SHARE * search_radius(track) + 2
    at = Template(template.image, template.mask, (round(10 + far), 13))
    near = Template(template.image, template.mask, (11, 13))
    track.support = 0.9 * VELOCITY_SUPPORT
    assert consistency.jumped(track, CENTER, at, 0.2, CENTER)
    assert not consistency.jumped(track, CENTER, near, 0.2, CENTER)
    track.support = VELOCITY_SUPPORT
    assert not consistency.jumped(track, CENTER, at, 0.2, CENTER)
    track.support = 0.9 * VELOCITY_SUPPORT
    monkeypatch.setattr(consistency, "POORLY_SUPPORTED", False)
    assert not consistency.jumped(track, CENTER, at, 0.2, CENTER)


def _returned(frames, label: int, obj_id: int) -> float:
    """The least IoU of ``obj_id`` in the last frame's views where the object of ``label``
    shows at least 100 pixels (:func:`search_oracle.least_ious`)."""
    return least_ious(frames, {label: obj_id})[label]


@pytest.fixture(scope="module")
def behind_401():
    """Seed 401's first nine frames (5x5 views of 96x128, the hard cases): the object of
    label 6 (the fifth clicked) passes behind an occluder; at frame 7 it shows 5-97 pixels a
    view, at frame 8 up to 159 (100 or more in seven views)."""
    return list(itertools.islice(generate_video(grid=(5, 5), size=(96, 128), frames=12,
                                                seed=401, num_objects=5, hard=True), 9))


def test_an_object_matched_on_a_sliver_is_found_where_it_was_going(behind_401, monkeypatch):
    """Frame 7: the object's match in the corner view (4, 0), 81 of 485 carried pixels
    supported, lies 16 px from the prediction: a jump (the sliver's place is no measure of
    the motion), so the track before it is kept as a shadow; frame 8: the jumped track's
    prediction misses, the shadow's is found. Without the rule the velocity jumped to about
    (9.6, -14.3) px a frame and the object was hidden at frame 8 (found a frame late)."""
    shown = (behind_401[8].labels == 6).sum(axis=(2, 3))
    assert (behind_401[7].labels == 6).sum(axis=(2, 3)).max() < 100 and shown.max() >= 100
    assert _returned(behind_401, 6, 5) >= 0.5
    monkeypatch.setattr(consistency, "POORLY_SUPPORTED", False)
    assert _returned(behind_401, 6, 5) < 0.5


class _Predictor:
    """What :func:`consistency.look_again` asks of the frame's predictor."""

    def __init__(self):
        self.object_ids, self.set = [], []

    def remove_object(self, obj_id):
        self.object_ids.remove(obj_id)

    def set_object(self, prompts):
        self.set.append(prompts)


def test_a_shadow_found_takes_the_id_back_and_one_never_found_is_forgotten():
    """:func:`consistency.look_again`: where the shadow's search accepts an answer, the
    object's prompts become the shadow's (under its own id), the track becomes the updated
    shadow; a shadow not found for DOUBT_FRAMES frames is forgotten."""
    template = Template(np.zeros((4, 4, 3), np.float32), np.ones((4, 4), bool), (10, 10))
    track = Track(CENTER, template, velocity=(0.0, 3.0), sightings=3)
    consistency.doubt(track)
    tracks, predictor = {1: track}, _Predictor()
    mask = np.zeros(SIZE, bool)
    mask[10:14, 13:17] = True
    shadow_prompts = ObjectPrompts(consistency.SHADOW_ID + 1, (PointPrompt(14.0, 12.0),))

    def search(shadow_id, shadow):
        predictor.object_ids.append(shadow_id)
        return CENTER, mask, (0, 0), Template(template.image, template.mask, (10, 13))

    back = consistency.look_again(1, tracks, search, predictor, lambda: shadow_prompts,
                                  lambda v, m: 0.0, lambda v: np.zeros((*SIZE, 3)), CENTER)
    assert back is not None and back[0] == CENTER and back[1] is mask
    assert tracks[1] is not track and tracks[1].shadow is None
    assert tracks[1].template.origin == (10, 13) and tracks[1].state == "tracked"
    assert predictor.set == [ObjectPrompts(1, shadow_prompts.points)]
    assert predictor.object_ids == []  # the shadow's own id is gone

    consistency.doubt(track)
    tracks = {1: track}
    for _ in range(consistency.DOUBT_FRAMES):
        assert consistency.look_again(1, tracks, lambda i, s: None, predictor, lambda: None,
                                      lambda v, m: 0.0, lambda v: None, CENTER) is None
        assert track.shadow is not None
    consistency.look_again(1, tracks, lambda i, s: None, predictor, lambda: None,
                           lambda v, m: 0.0, lambda v: None, CENTER)
    assert track.shadow is None and tracks[1] is track
