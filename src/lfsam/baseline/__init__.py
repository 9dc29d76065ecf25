"""The SAM 2 video-tracking baseline of the paper (section 4; docs/design.md section 4).

- :func:`video_baseline` — views in snake order as video frames, SAM 2 tracking of the start
  view's masks, the same result format as LFSAM;
- :func:`video_frames` / :func:`init_video_state` — in-memory views as SAM 2 video frames and
  the predictor's inference state around them;
- :func:`video_predictor_for` — Meta's video predictor with a segmenter's own weights;
- :func:`transfer_prompts` — center-view prompts carried to another view by disparity.
"""

from lfsam.baseline.frames import FRAME_TRANSFORMS, init_video_state, video_frames
from lfsam.baseline.predictor import video_predictor_for
from lfsam.baseline.prompts import transfer_prompts
from lfsam.baseline.video import BASELINE_STARTS, video_baseline

__all__ = [
    "BASELINE_STARTS",
    "FRAME_TRANSFORMS",
    "init_video_state",
    "transfer_prompts",
    "video_baseline",
    "video_frames",
    "video_predictor_for",
]
