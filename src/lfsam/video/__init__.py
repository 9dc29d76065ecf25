"""Light-field video: sequences of light fields (docs/design.md section 10).

Four rooms, each a sub-package that says what it is and what it may import; their order is an
import-linter contract (``pyproject.toml``, docs/architecture.md):

- :mod:`lfsam.video.stream` — live streams: a growing frames folder followed and segmented as
  frames land (:func:`segment_stream`, issue 35); it drives the tracker;
- :mod:`lfsam.video.tracking` — tracking objects through the frames: :class:`OnlineTracker`
  (one frame at a time), :func:`track_video` (a whole video), the frame-tagged prompts, the
  search for an object's place in the next frame with its checks, and its rules in one place
  (:class:`TrackerConfig`);
- :mod:`lfsam.video.memory` — the models' video memory over the center views (SAM 2's and the
  ``transformers`` backend's);
- :mod:`lfsam.video.io` — videos in and results out: :class:`LightFieldVideo` and
  :func:`read_video` / :func:`is_video` (every input form: ``[F, S, T, U, V, 3]`` arrays, a
  folder of frames, per-view video files), synthetic videos with exact ground truth, and the
  chunked result (one file per frame), read lazily;

and beside them :mod:`lfsam.video.evaluate`, which scores tracked videos against their ground
truth.

This package only imports light modules at import time (``lfsam info`` stays fast); tracking
loads torch and the pipeline when first used (``lfsam.video.OnlineTracker`` imports it then).
"""

from typing import Any

from lfsam.video.io.detect import is_video, read_video
from lfsam.video.io.source import LightFieldVideo

__all__ = ["LightFieldVideo", "OnlineTracker", "TrackerConfig", "is_video", "read_video",
           "segment_stream", "track_video"]

_LAZY = {"OnlineTracker": "lfsam.video.tracking.online",
         "segment_stream": "lfsam.video.stream.live",
         "track_video": "lfsam.video.tracking.track",
         "TrackerConfig": "lfsam.video.tracking.config"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'lfsam.video' has no attribute {name!r}")
