"""Light-field video: sequences of light fields (docs/design.md section 10).

- :mod:`lfsam.video.source` — :class:`LightFieldVideo`, frames read on demand;
- :mod:`lfsam.video.detect` — :func:`read_video` / :func:`is_video`: every input form;
- :mod:`lfsam.video.arrays`, :mod:`lfsam.video.frames_folder`, :mod:`lfsam.video.view_files` —
  the readers (``[F, S, T, U, V, 3]`` arrays, a folder of frames, per-view video files);
- :mod:`lfsam.video.synth` — synthetic videos with exact ground truth;
- :mod:`lfsam.video.prompts` — prompts tagged with a frame;
- :mod:`lfsam.video.result` — the chunked result (one file per frame), read lazily;
- :mod:`lfsam.video.carry`, :mod:`lfsam.video.track` — tracking objects through the frames.

This package only imports light modules at import time (``lfsam info`` stays fast); tracking
loads torch and the pipeline when imported.
"""

from lfsam.video.detect import is_video, read_video
from lfsam.video.source import LightFieldVideo

__all__ = ["LightFieldVideo", "is_video", "read_video"]
