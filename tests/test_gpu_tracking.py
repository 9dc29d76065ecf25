"""Tracking on CUDA (issue 47; runs only on a CUDA GPU, `make gpu-check`).

The constrained-prompt tracker with its search for lost objects (docs/design.md section 3.9,
"Videos") is torch on the hot path; this checks that on a CUDA device it tracks what it tracks on
the CPU: a hard synthetic video (objects passing behind others, leaving and coming back), the
oracle, ground-truth disparity, each object clicked once in the first frame.
"""

from __future__ import annotations

import os

import numpy as np
import pytest
from scipy import ndimage

from lfsam.api import ModelOptions, RunOptions, SegmentOptions
from lfsam.prompts import ObjectPrompts, PointPrompt
from lfsam.video.io.synth import generate_video
from lfsam.video.tracking.online import OnlineTracker

pytestmark = pytest.mark.cuda

#: ``LFSAM_TEST_TRACK_DEVICE=cpu`` runs the check CPU against CPU (to try the test itself here).
DEVICE = os.environ.get("LFSAM_TEST_TRACK_DEVICE", "cuda")


def _first_frame_clicks(labels: np.ndarray, min_pixels: int = 100) -> list[ObjectPrompts]:
    """One click at the deepest pixel of every object showing ``min_pixels`` in the view."""
    prompts = []
    for label in np.unique(labels[labels > 1]):  # label 1 is the background
        mask = labels == label
        if mask.sum() < min_pixels:
            continue
        depth = ndimage.distance_transform_edt(np.pad(mask, 1))[1:-1, 1:-1]
        row, col = np.unravel_index(int(np.argmax(depth)), depth.shape)
        prompts.append(ObjectPrompts(len(prompts) + 1, (PointPrompt(float(col), float(row)),)))
    return prompts


def _track(frames, prompts, device: str) -> list[np.ndarray]:
    options = SegmentOptions(run=RunOptions(progress=False),
                             model=ModelOptions(name="oracle", device=device, seed=0))
    tracker = OnlineTracker("oracle", disparity="gt", options=options, search=True, memory=False)
    tracker.add_prompts(prompts)
    return [np.asarray(tracker.track(lf).labels) for lf in frames]


def test_search_tracking_on_cuda_matches_cpu():
    frames = list(generate_video(grid=(5, 5), size=(64, 96), frames=8, seed=1301,
                                 num_objects=5, hard=True))
    prompts = _first_frame_clicks(frames[0].labels[frames[0].center])
    assert len(prompts) >= 3
    cpu, gpu = _track(frames, prompts, "cpu"), _track(frames, prompts, DEVICE)
    for frame, (a, b) in enumerate(zip(cpu, gpu, strict=True)):
        assert set(np.unique(a)) == set(np.unique(b)), f"frame {frame}: other objects tracked"
        agree = float(np.mean(a == b))
        assert agree > 0.999, f"frame {frame}: labels agree on only {agree:.4%} of the pixels"
    assert any((cpu[-1] == p.obj_id).any() for p in prompts), "nothing tracked to the end"
