"""The SAM 2 video-tracking baseline of the paper (section 4; docs/design.md section 4).

- :func:`video_baseline` — views in snake order as video frames, SAM 2 tracking of the start
  view's masks, the same result format as LFSAM;
- :func:`video_frames` / :func:`init_video_state` — in-memory views as SAM 2 video frames and
  the predictor's inference state around them;
- :func:`video_predictor_for` — Meta's video predictor with a segmenter's own weights;
- :func:`transfer_prompts` — center-view prompts carried to another view by disparity.

Each name is imported from its module on first use (PEP 562): importing one light module of this
package (:mod:`lfsam.baseline.predictor`, which the video memory needs to ask whether a
segmenter has SAM 2's memory) does not import Meta's image predictor, torchvision and
``torch._dynamo`` (3-4 s) for a run that never uses them (the oracle, EdgeTAM).
"""

from __future__ import annotations

import importlib
from typing import Any

_HOMES = {
    "BASELINE_STARTS": "lfsam.baseline.video",
    "FRAME_TRANSFORMS": "lfsam.baseline.frames",
    "init_video_state": "lfsam.baseline.frames",
    "transfer_prompts": "lfsam.baseline.prompts",
    "video_baseline": "lfsam.baseline.video",
    "video_frames": "lfsam.baseline.frames",
    "video_predictor_for": "lfsam.baseline.predictor",
}

__all__ = sorted(_HOMES)


def __getattr__(name: str) -> Any:
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module 'lfsam.baseline' has no attribute {name!r}")
    return getattr(importlib.import_module(home), name)
