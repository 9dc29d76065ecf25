"""Live streams: a growing frames folder, followed and segmented as frames land (issue 35).

- :mod:`~lfsam.video.stream.follow` — :class:`FrameFollower`: which frames have arrived;
- :mod:`~lfsam.video.stream.feed` — :class:`FrameFeed`: the frames to segment next, in order
  or the newest only (``--latest``);
- :mod:`~lfsam.video.stream.live` — :func:`segment_stream`: each frame tracked as it lands, its
  result written right behind it;
- :mod:`~lfsam.video.stream.hidden_lines` — what a live run says about objects not found.

May import: :mod:`lfsam.video.tracking` (a stream drives the tracker), :mod:`lfsam.video.io`
and the rest of :mod:`lfsam` below the video floor. The tracker never imports a stream.
"""
