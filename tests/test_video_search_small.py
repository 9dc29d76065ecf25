"""A small answer in the object's own view waits for the ring's views (issue 47, seventeenth
pass; docs/design.md section 10, "Tracking", step 2;
:data:`lfsam.video.tracking.rules.SMALL_ANSWER`). Seed 1401 under the oracle's jitter, frame 2:
object 2, a thin object mostly hidden in the center view (its own), showed 42 pixels there and 118
in the corner view (0, 0); its answer in the center view, eroded by the jitter, held 9 pixels of a
match supported on 32, and every view's refinement, prompted with boxes cut from it, came out a
sliver (IoU 0.05-0.45 in the views showing 100 pixels). Held back, the corner view's answer (118
pixels) is taken."""

from __future__ import annotations

import itertools

from lfsam.api import ModelOptions, RunOptions, SegmentOptions
from lfsam.video.io.synth import generate_video
from lfsam.video.tracking import rules
from search_oracle import least_ious


def test_an_eroded_answer_in_its_own_view_gives_way_to_a_view_that_shows_more(monkeypatch):
    frames = list(itertools.islice(generate_video(grid=(5, 5), size=(96, 128), frames=12,
                                                  seed=1401, num_objects=5, hard=True), 3))
    jitter = SegmentOptions(run=RunOptions(progress=False),
                            model=ModelOptions(name="oracle", oracle={"boundary_jitter": 1},
                                               seed=1401))
    assert (frames[2].labels == 3).sum(axis=(2, 3)).max() >= 100
    assert least_ious(frames, {3: 2}, jitter)[3] >= 0.5
    monkeypatch.setattr(rules, "SMALL_ANSWER", False)
    assert least_ious(frames, {3: 2}, jitter)[3] < 0.5
