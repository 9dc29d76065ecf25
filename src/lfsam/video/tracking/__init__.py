"""Tracking objects through the frames of a light-field video (docs/design.md section 10).

The drivers:

- :mod:`~lfsam.video.tracking.online` — :class:`OnlineTracker`, one frame at a time;
- :mod:`~lfsam.video.tracking.track` — :func:`track_video`, a whole video;
- :mod:`~lfsam.video.tracking.prompts` — prompts tagged with a frame;
- :mod:`~lfsam.video.tracking.frame_search` — every object of one frame: its constrained
  prompts, or its search when the memory lost it.

The tracker's rules in one place: :mod:`~lfsam.video.tracking.config`
(:class:`TrackerConfig`, each rule's meaning, default and case, and its off switch).

The search for one object's place in the next frame, and its checks:

- :mod:`~lfsam.video.tracking.carry` — the template carried from frame to frame and the
  constrained prompts;
- :mod:`~lfsam.video.tracking.motion` — the track: velocity, prediction, search radius;
- :mod:`~lfsam.video.tracking.search` — the search itself (:func:`search_object`), the rules it
  applies in :mod:`~lfsam.video.tracking.rules`, its acceptance in
  :mod:`~lfsam.video.tracking.accept`;
- :mod:`~lfsam.video.tracking.match`, :mod:`~lfsam.video.tracking.placement`,
  :mod:`~lfsam.video.tracking.union`, :mod:`~lfsam.video.tracking.neighbour`,
  :mod:`~lfsam.video.tracking.contest`, :mod:`~lfsam.video.tracking.claims`,
  :mod:`~lfsam.video.tracking.consistency` — the checks: template matching in each view, the
  placed answer, the union over views, the neighbour's depth, two objects contesting one place,
  claims of one pixel by two objects, the jump between frames.

May import: :mod:`lfsam.video.memory`, :mod:`lfsam.video.io` and the rest of :mod:`lfsam` below
the video floor (the pipeline, the segmenters). Never :mod:`lfsam.video.stream` (a stream drives
the tracker, not the other way round) nor :mod:`lfsam.video.evaluate`.
"""
