"""Tracks that come back (issue 47, docs/design.md section 10): the hard synthetic videos, an
object hidden for several frames found again under its own id, each object's state per frame
in the frames' meta and the manifest, and the same bookkeeping with SAM 2's and EdgeTAM's
video memory (tiny random models: ids and states, not mask quality)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy import ndimage

from lfsam.api import ModelOptions, RunOptions, SegmentOptions
from lfsam.prompts import ObjectPrompts, PointPrompt
from lfsam.video.io.result import record_states
from lfsam.video.io.synth import HARD_SPEED, generate_video, video_specs
from lfsam.video.tracking.online import OnlineTracker, memory_states
from lfsam.video.tracking.search import Track, looks_alike, near_support, predicted, search_radius

QUIET = SegmentOptions(run=RunOptions(progress=False))


def _deepest(mask):
    depth = ndimage.distance_transform_edt(np.pad(mask, 1))[1:-1, 1:-1]
    row, col = np.unravel_index(int(np.argmax(depth)), depth.shape)
    return float(col), float(row)


@pytest.fixture(scope="module")
def hard():
    """12 frames of 3x3 views of 96x128 with the hard cases (seed 7)."""
    return list(generate_video(grid=(3, 3), size=(96, 128), frames=12, seed=7, num_objects=4,
                               hard=True))


def test_hard_videos_have_the_hard_cases(hard):
    spec = video_specs(grid=(3, 3), size=(96, 128), frames=12, seed=7, num_objects=4, hard=True)
    pair = hard[0].meta["generator"]["hard"]
    hidden = pair["hidden"]
    center = [int((lf.labels[1, 1] == hidden).sum()) for lf in hard]
    everywhere = [int((lf.labels == hidden).sum()) for lf in hard]
    assert center[0] >= 100 and center[-1] > 0  # seen at the start, back at the end
    gone = [f for f, n in enumerate(center) if n == 0]
    assert len(gone) >= 3 and gone == list(range(gone[0], gone[-1] + 1))  # hidden for frames
    assert everywhere[gone[0] - 1] > center[gone[0] - 1]  # the outer views see it longer
    for obj in range(1, len(spec[0].objects)):
        steps = [np.hypot(*np.subtract(spec[f + 1].objects[obj].center,
                                       spec[f].objects[obj].center)) for f in range(11)]
        if spec[0].objects[obj].label != 2:  # the first object leaves and comes back
            assert max(steps) <= HARD_SPEED + 1e-9
    swings = [spec[f].objects[1].plane[0] for f in range(12)]
    assert max(swings) > min(swings)
    # defaults unchanged: hard=False draws exactly the scenes it drew before issue 47
    plain = video_specs(grid=(3, 3), size=(96, 128), frames=4, seed=7, num_objects=4)
    assert "hard" not in plain[0].meta
    assert plain[0].objects == video_specs(grid=(3, 3), size=(96, 128), frames=4, seed=7,
                                           num_objects=4)[0].objects


def test_hidden_object_found_again_under_its_own_id(hard):
    hidden = hard[0].meta["generator"]["hard"]["hidden"]
    labels0 = hard[0].labels[1, 1]
    truth = {}
    prompts = []
    for label in np.unique(labels0[labels0 > 1]):
        if (labels0 == label).sum() >= 100:
            obj_id = len(prompts) + 1
            prompts.append(ObjectPrompts(obj_id, (PointPrompt(*_deepest(labels0 == label)),)))
            truth[obj_id] = int(label)
    ours = next(i for i, label in truth.items() if label == hidden)
    tracker = OnlineTracker("oracle", disparity="gt", options=QUIET)
    tracker.add_prompts(prompts)
    states, shown, found = [], [], []
    for lf in hard:
        result = tracker.track(lf)
        states.append(result.meta["tracks"][str(ours)])
        gt = lf.labels == hidden
        shown.append(int(gt.sum(axis=(2, 3)).max()))
        mine = result.labels == ours
        found.append(bool(mine.any()))
        if mine.any():  # never on another object
            assert (gt & mine).sum() >= 0.5 * mine.sum()
        for obj_id, label in truth.items():  # every object keeps its id where it shows well
            g, p = lf.labels == label, result.labels == obj_id
            big = g.sum(axis=(2, 3)) >= 100
            inter = (g & p).sum(axis=(2, 3))[big]
            union = (g | p).sum(axis=(2, 3))[big]
            assert (inter / union >= 0.5).all(), (obj_id, result.meta["frame"])
    assert states[0] == "prompted" and "hidden" in states
    gone = states.index("hidden")
    assert max(shown[gone:gone + 3]) < 100  # it was hidden, not lost
    back = next(f for f in range(gone, len(hard)) if shown[f] >= 100)
    assert found[back]  # in the first frame it shows 100 pixels again (in some view) ...
    assert "found" in states[gone:back + 1]  # ... or earlier, from fewer
    assert all(s == "hidden" for s, f in zip(states, found, strict=True) if not f)
    assert all(found[back:])


def test_search_off_is_the_tracking_before_issue_47(hard):
    """``search=False`` keeps the earlier tracking (the benchmark's baseline)."""
    lf = hard[0]
    mask = lf.labels[1, 1] == int(np.unique(lf.labels[1, 1])[-1])
    prompts = [ObjectPrompts(1, (PointPrompt(*_deepest(mask)),))]
    labels = []
    for search in (True, False):
        tracker = OnlineTracker("oracle", disparity="gt", options=QUIET, search=search)
        tracker.add_prompts(prompts)
        labels.append([tracker.track(f).labels for f in hard[:3]])
        assert tracker.carry_seconds > 0
    np.testing.assert_array_equal(labels[0][0], labels[1][0])  # frame 0: the same prompts


def test_the_search_grows_while_unseen_and_predicts_constant_velocity():
    from lfsam.video.tracking.carry import Template

    image = np.zeros((40, 50, 3), np.float32)
    template = Template(np.full((4, 4, 3), 200, np.float32), np.ones((4, 4), bool), (10, 10))
    track = Track((1, 1), template, velocity=(2.0, -1.0), disparity=1.0, disparity_rate=0.5)
    assert predicted(track, (1, 1), (1, 1)).origin == (12, 9)
    # two frames later (one unseen); another view: parallax of the predicted disparity 2
    track.unseen = 1
    assert predicted(track, (2, 1), (1, 1)).origin == (14 - 2, 8)
    radii = []
    for unseen in range(3):
        track.unseen = unseen
        radii.append(search_radius(track))
    assert radii[0] < radii[1] < radii[2]
    image[20:24, 30:34] = 200  # found by its visible part, half of it covered
    image[20:22, 30:34] = 90
    cost, du, dv = near_support(replace_origin(template, (19, 28)), image, 3)
    best = np.unravel_index(int(np.argmin(cost)), cost.shape)
    assert (du[best], dv[best]) == (1, 2)
    assert looks_alike(np.full((5, 3), 200), np.full((7, 3), 200)) == 1.0
    assert looks_alike(np.full((5, 3), 200), np.full((7, 3), 10)) == 0.0


def replace_origin(template, origin):
    from dataclasses import replace

    return replace(template, origin=origin)


def test_states_are_recorded_per_object_and_frame_in_the_manifest(tmp_path, hard):
    from lfsam.video import read_video
    from lfsam.video.io.synth import write_video_frames
    from lfsam.video.tracking.track import track_video

    write_video_frames(iter(hard[:4]), tmp_path / "clip")
    video = read_video(tmp_path / "clip")
    lf = hard[1]
    big = max(np.unique(lf.labels[1, 1]), key=lambda g: (lf.labels[1, 1] == g).sum())
    prompts = [ObjectPrompts(1, (PointPrompt(*_deepest(hard[0].labels[1, 1] == big)),)),
               ObjectPrompts(2, (PointPrompt(*_deepest(lf.labels[1, 1] == big), frame=1),))]
    result = track_video(video, prompts, tmp_path / "out", model="oracle", disparity="gt",
                         options=QUIET)
    tracks = result.meta["tracks"]
    assert set(tracks) == {"1", "2"} and all(len(v) == 4 for v in tracks.values())
    assert tracks["1"][0] == "prompted" and tracks["2"][0] == "waiting"
    assert tracks["2"][1] in ("prompted", "hidden")
    assert set(tracks["1"][1:]) <= {"tracked", "hidden", "found"}
    history: dict[str, list[str]] = {}
    record_states(history, {"1": "prompted"}, 0)
    record_states(history, {"2": "prompted"}, 1)
    assert history == {"1": ["prompted", "waiting"], "2": ["waiting", "prompted"]}


def test_memory_states_keep_ids_of_absent_objects():
    empty, full = np.zeros((2, 2), bool), np.ones((2, 2), bool)
    objects = {1: ObjectPrompts(1, (PointPrompt(0, 0),)),
               3: ObjectPrompts(3, (PointPrompt(0, 0, frame=5),))}
    first = memory_states({}, {1}, {}, objects)
    assert first == {1: "prompted", 3: "waiting"}
    absent = memory_states(first, set(), {1: empty}, objects)
    assert absent[1] == "hidden"
    back = memory_states(absent, set(), {1: full}, objects)
    assert back[1] == "found"
    assert memory_states(back, set(), {1: full}, objects)[1] == "tracked"


def _absent_then_back(segmenter, bias, frames=4):
    """Track one object with a video memory; the object score says absent at frame 1 (bias
    lowered), present again from frame 2: its id and states."""
    video = list(generate_video(grid=(3, 3), size=(48, 64), frames=frames, seed=0,
                                num_objects=2))
    mask = video[0].labels[1, 1] == 3
    tracker = OnlineTracker(segmenter, disparity="gt", options=QUIET)
    tracker.add_prompts([ObjectPrompts(1, (PointPrompt(*_deepest(mask)),))])
    states, present = [], []
    for f, lf in enumerate(video):
        with torch.no_grad():
            bias += 50.0 if f != 1 else -50.0
        try:
            result = tracker.track(lf)
        finally:
            with torch.no_grad():
                bias -= 50.0 if f != 1 else -50.0
        states.append(result.meta["tracks"]["1"])
        present.append(bool((result.labels == 1).any()))
    assert tracker.object_ids == [1]
    return tracker, states, present


def test_sam2_memory_keeps_an_absent_objects_id_and_brings_it_back():
    from lfsam.baseline.predictor import video_predictor_for
    from lfsam.segmenters import load_segmenter

    tiny = load_segmenter("sam2-tiny-test", random_weights=True, device="cpu")
    head = video_predictor_for(tiny).sam_mask_decoder.pred_obj_score_head
    last = head.layers[-1] if hasattr(head, "layers") else head
    tracker, states, present = _absent_then_back(tiny, last.bias)
    assert tracker.tracking == "sam2-memory"
    assert states == ["prompted", "hidden", "found", "tracked"]
    assert present == [True, False, True, True]


def test_edgetam_memory_keeps_an_absent_objects_id_and_brings_it_back():
    from lfsam.segmenters import load_segmenter
    from lfsam.segmenters.transformers.video_build import video_model_for

    tiny = load_segmenter("edgetam-tiny-test", device="cpu")
    model = video_model_for(tiny.model)
    tracker, states, present = _absent_then_back(
        tiny, model.mask_decoder.pred_obj_score_head.proj_out.bias)
    assert tracker.tracking == "edgetam-memory"
    assert states == ["prompted", "hidden", "found", "tracked"]
    assert present == [True, False, True, True]


def test_jitter_option_reaches_the_oracle(hard):
    options = SegmentOptions(run=RunOptions(progress=False),
                             model=ModelOptions(name="oracle", oracle={"boundary_jitter": 1}))
    tracker = OnlineTracker("oracle", disparity="gt", options=options)
    mask = hard[0].labels[1, 1] == int(np.unique(hard[0].labels[1, 1])[-1])
    tracker.add_prompts([ObjectPrompts(1, (PointPrompt(*_deepest(mask)),))])
    for lf in hard[:3]:
        assert tracker.track(lf).meta["tracks"]["1"] in ("prompted", "tracked", "found")
