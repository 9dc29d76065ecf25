"""SAM 2's video memory over the reference views (issue 25, docs/design.md section 10):
driven one frame at a time with a bounded window, it gives Meta's full-video tracking."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from lfsam.baseline.frames import init_video_state, video_frames
from lfsam.baseline.predictor import video_predictor_for
from lfsam.errors import LfsamError
from lfsam.segmenters import load_segmenter
from lfsam.video.io.synth import generate_video
from lfsam.video.memory.sam2_memory import ReferenceMemory, has_video_memory
from lfsam.video.tracking.track import track_video

SHAPE = (48, 64)


@pytest.fixture(scope="module")
def tiny():
    return load_segmenter("sam2-tiny-test", random_weights=True, device="cpu")


@pytest.fixture
def present(tiny):
    """Random weights score every object absent (masks all -1024): raise the object-score
    head's bias so the masks are real logits, as with trained weights."""
    head = video_predictor_for(tiny).sam_mask_decoder.pred_obj_score_head
    last = head.layers[-1] if hasattr(head, "layers") else head
    with torch.no_grad():
        last.bias += 50.0
    yield tiny
    with torch.no_grad():
        last.bias -= 50.0


def _stream(segmenter, images, first, window=None):
    memory = ReferenceMemory(segmenter, SHAPE)
    if window is not None:
        memory.window = window
    logits = []
    for f, image in enumerate(images):
        memory.next_frame(f, image)
        if f == 0:
            memory.add_mask(1, first)
        masks = memory.track()
        memory.forget()
        assert sorted(masks) == [1] and masks[1].shape == SHAPE
        logits.append(memory.logits)
        kept = memory.state["output_dict_per_obj"][0]["non_cond_frame_outputs"]
        assert all(f - memory.window <= k <= f for k in kept)
    return memory, np.stack(logits)


def test_one_frame_at_a_time_with_a_window_equals_the_full_video(present, monkeypatch):
    predictor = video_predictor_for(present)
    # a model that looks 1 frame back: the window keeps none behind the current one
    monkeypatch.setattr(predictor, "num_maskmem", 2)
    monkeypatch.setattr(predictor, "max_obj_ptrs_in_encoder", 2)
    rng = np.random.default_rng(0)
    images = rng.integers(0, 256, (4, *SHAPE, 3), dtype=np.uint8)
    images[:, 10:30, 12:40] = (220, 30, 30)
    first = np.zeros(SHAPE, bool)
    first[10:30, 12:40] = True

    memory, ours = _stream(present, images, first)
    assert memory.window == 0
    assert (ours[1:] > 0).any() and (ours[1:] < 0).any()  # real masks, not "absent"
    state = init_video_state(predictor, video_frames(images, predictor.image_size, "cpu",
                                                     "image"), SHAPE)
    predictor.add_new_mask(state, 0, 1, first)
    theirs = [logits[:, 0].float().numpy()
              for _, _, logits in predictor.propagate_in_video(state, start_frame_idx=0)]
    np.testing.assert_allclose(ours, np.stack(theirs), atol=1e-5)
    # one frame less is not enough: frame 2 no longer sees frame 1
    _, short = _stream(present, images[:3], first, window=-1)
    np.testing.assert_array_equal(short[:2], ours[:2])
    assert np.abs(short[2] - ours[2]).max() > 1e-3


def test_frames_go_forward_and_only_the_current_one_is_held(tiny):
    memory = ReferenceMemory(tiny, SHAPE)
    memory.next_frame(1, np.zeros((*SHAPE, 3), np.uint8))
    with pytest.raises(LfsamError, match="frames go forward"):
        memory.next_frame(0, np.zeros((*SHAPE, 3), np.uint8))
    with pytest.raises(LfsamError, match="only frame 1 is loaded"):
        memory.frames[0]


def test_which_segmenters_have_memory(tiny, tmp_path):
    assert has_video_memory(tiny)
    video = generate_video(grid=(3, 3), size=SHAPE, frames=2, seed=0, num_objects=2)
    oracle = load_segmenter("oracle", lightfield=next(iter(video)))
    assert not has_video_memory(oracle)


def test_tracking_with_memory_covers_every_frame_and_view(present, tmp_path):
    from lfsam.api import RunOptions, SegmentOptions
    from lfsam.prompts import ObjectPrompts, PointPrompt
    from lfsam.video import read_video
    from lfsam.video.io.synth import write_video_frames

    write_video_frames(generate_video(grid=(3, 3), size=SHAPE, frames=3, seed=0,
                                      num_objects=2), tmp_path / "clip")
    video = read_video(tmp_path / "clip")
    rows, cols = np.nonzero(video.frame(0).labels[1, 1] == 3)
    point = PointPrompt(float(cols[len(cols) // 2]), float(rows[len(rows) // 2]))
    options = SegmentOptions(run=RunOptions(progress=False))
    result = track_video(video, [ObjectPrompts(1, (point,))], tmp_path / "out", model=present,
                         disparity="gt", options=options)
    assert result.meta["tracking"] == "sam2-memory"
    assert result.shape == (3, 3, 3, *SHAPE) and result.object_ids == [1]
    for labels in result.labels:  # SAM 2's memory found it in every frame: every view has it
        assert (labels == 1).any(axis=(2, 3)).all()
    with pytest.raises(LfsamError, match="correction click at a later frame goes in the center"):
        track_video(video, [ObjectPrompts(1, (point, PointPrompt(3, 3, False, (0, 0), 1)))],
                    tmp_path / "bad", model=present, disparity="gt", options=options)
    assert not (tmp_path / "bad").exists()
    with pytest.raises(LfsamError, match="no video memory"):
        track_video(video, [ObjectPrompts(1, (point,))], tmp_path / "bad", model="oracle",
                    disparity="gt", options=options, memory=True)


def test_a_correction_click_changes_the_tracked_mask(present):
    rng = np.random.default_rng(1)
    images = rng.integers(0, 256, (2, *SHAPE, 3), dtype=np.uint8)
    first = np.zeros(SHAPE, bool)
    first[10:30, 12:40] = True
    memory = ReferenceMemory(present, SHAPE)
    memory.next_frame(0, images[0])
    memory.add_mask(1, first)
    memory.track()
    memory.next_frame(1, images[1])
    tracked = memory.track()[1]
    before = memory.logits.copy()
    corrected = memory.correct(1, [(20.0, 15.0)])[1]
    assert corrected.shape == tracked.shape == SHAPE
    assert np.abs(memory.logits - before).max() > 1e-3  # SAM 2 took the click into account
    inputs = memory.state["point_inputs_per_obj"][0][1]
    assert inputs["point_labels"].tolist() == [[0]]


def test_the_tracker_does_not_import_sam2s_image_predictor():
    """The video memory thresholds masks where the video baseline does, and importing the
    tracker brings in neither Meta's sam2, torchvision nor torch._dynamo (3-4 s)."""
    import subprocess
    import sys

    from lfsam.baseline import video
    from lfsam.video.memory import sam2_memory

    assert sam2_memory.MASK_THRESHOLD is video.MASK_THRESHOLD
    heavy = "('sam2', 'torchvision', 'torch._dynamo')"
    code = ("import sys, lfsam.video.tracking.online; "
            f"print(sorted(m for m in {heavy} if m in sys.modules))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == "[]"
