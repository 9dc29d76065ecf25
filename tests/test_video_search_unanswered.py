"""An object whose prompts were never answered is asked them again (issue 47, seventeenth
pass; docs/design.md section 10, "Tracking"; :data:`lfsam.video.tracking.frame_search.
RETRY_UNANSWERED`). A user clicks, in frame 0, where an object is hidden behind another: the
answer is the one in front, placed already, so the clicked object is hidden. Before, it then
waited for good ("waiting" in every later frame, never searched: it had no template); now its
click is asked again every frame after the others are placed, and where the object comes out
it is found under its own id and tracked from there."""

from __future__ import annotations

import numpy as np

from lfsam.api import RunOptions, SegmentOptions
from lfsam.lightfield import LightField
from lfsam.prompts import ObjectPrompts, PointPrompt
from lfsam.video.tracking import frame_search
from lfsam.video.tracking.online import OnlineTracker

GRID, SIZE = (3, 3), (44, 60)
#: The front object (label 2): rows 15-24, its first column per frame.
FRONT = [20, 40, 42]
#: The hidden object (label 3): rows 16-23, columns 22-29, behind the front one in frame 0.
BACK = (slice(16, 24), slice(22, 30))


def _frame(index: int) -> LightField:
    """Every view alike (disparity 0): a dark random background, the hidden object, and the
    front object over it where :data:`FRONT` puts it."""
    rng = np.random.default_rng(5)
    image = rng.uniform(0, 60, (*SIZE, 3))
    label = np.ones(SIZE, np.int32)
    image[BACK] = rng.uniform(150, 255, (8, 8, 3)) * [1.0, 0.3, 0.3]
    label[BACK] = 3
    c = FRONT[index]
    image[15:25, c:c + 14] = rng.uniform(150, 255, (10, 14, 3)) * [0.3, 0.3, 1.0]
    label[15:25, c:c + 14] = 2
    views = np.broadcast_to(image.astype(np.uint8), (*GRID, *SIZE, 3))
    return LightField(views.copy(), np.zeros((*GRID, *SIZE), np.float32),
                      np.broadcast_to(label, (*GRID, *SIZE)).copy())


def _tracked() -> list:
    tracker = OnlineTracker("oracle", disparity="gt",
                            options=SegmentOptions(run=RunOptions(progress=False)))
    tracker.add_prompts([ObjectPrompts(1, (PointPrompt(31.0, 20.0),)),
                         ObjectPrompts(2, (PointPrompt(25.0, 19.0),))])  # on the front one
    return [(frame, tracker.track(frame)) for frame in map(_frame, range(len(FRONT)))]


def test_an_object_clicked_behind_another_is_found_where_it_comes_out():
    frames = _tracked()
    assert [r.meta["tracks"]["2"] for _, r in frames] == ["hidden", "found", "tracked"]
    for frame, result in frames[1:]:
        truth, ours = frame.labels == 3, result.labels == 2
        assert (truth & ours).sum() / (truth | ours).sum() >= 0.9
        assert ((result.labels == 1) == (frame.labels == 2)).all()  # the front one's own


def test_without_the_retry_it_waits_for_good(monkeypatch):
    monkeypatch.setattr(frame_search, "RETRY_UNANSWERED", False)
    frames = _tracked()
    assert [r.meta["tracks"]["2"] for _, r in frames] == ["hidden", "waiting", "waiting"]
    assert not any((r.labels == 2).any() for _, r in frames)
