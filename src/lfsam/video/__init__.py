"""Light-field video: sequences of light fields (docs/design.md section 10).

- :mod:`lfsam.video.source` — :class:`LightFieldVideo`, frames read on demand;
- :mod:`lfsam.video.detect` — :func:`read_video` / :func:`is_video`: every input form;
- :mod:`lfsam.video.arrays`, :mod:`lfsam.video.frames_folder`, :mod:`lfsam.video.view_files` —
  the readers (``[F, S, T, U, V, 3]`` arrays, a folder of frames, per-view video files);
- :mod:`lfsam.video.synth` — synthetic videos with exact ground truth;
- :mod:`lfsam.video.prompts` — prompts tagged with a frame;
- :mod:`lfsam.video.result` — the chunked result (one file per frame), read lazily;
- :mod:`lfsam.video.carry`, :mod:`lfsam.video.memory`, :mod:`lfsam.video.online`,
  :mod:`lfsam.video.track` — tracking objects through the frames: constrained prompts, the
  video memory, :class:`OnlineTracker` (one frame at a time) and :func:`track_video` (a whole
  video);
- :mod:`lfsam.video.follow`, :mod:`lfsam.video.live` — live streams: a growing frames folder
  followed and segmented as frames land (:func:`segment_stream`, issue 35).

This package only imports light modules at import time (``lfsam info`` stays fast); tracking
loads torch and the pipeline when first used (``lfsam.video.OnlineTracker`` imports it then).
"""

from typing import Any

from lfsam.video.detect import is_video, read_video
from lfsam.video.source import LightFieldVideo

__all__ = ["LightFieldVideo", "OnlineTracker", "is_video", "read_video", "segment_stream",
           "track_video"]

_LAZY = {"OnlineTracker": "lfsam.video.online", "segment_stream": "lfsam.video.live",
         "track_video": "lfsam.video.track"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'lfsam.video' has no attribute {name!r}")
