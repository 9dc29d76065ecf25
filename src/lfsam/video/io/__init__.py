"""Videos in and results out: the bottom room of :mod:`lfsam.video`.

- :mod:`~lfsam.video.io.source` — :class:`LightFieldVideo`, frames read on demand;
- :mod:`~lfsam.video.io.detect` — :func:`read_video` / :func:`is_video`: every input form;
- :mod:`~lfsam.video.io.arrays`, :mod:`~lfsam.video.io.frames_folder`,
  :mod:`~lfsam.video.io.view_files` — the readers (``[F, S, T, U, V, 3]`` arrays, a folder of
  frames, per-view video files);
- :mod:`~lfsam.video.io.synth` — synthetic videos with exact ground truth;
- :mod:`~lfsam.video.io.result` — the chunked result (one file per frame), read lazily.

May import: the core and building blocks of :mod:`lfsam` (light fields, readers, synthetic
scenes, results). Never :mod:`lfsam.video.memory`, :mod:`lfsam.video.tracking` or
:mod:`lfsam.video.stream`: every other room reads and writes videos through this one.
"""
