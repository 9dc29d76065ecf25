"""A poorly supported match moves an object's velocity only by its share (issue 47, sixth
pass; docs/design.md section 10, "Tracking", step 1): under the oracle's jitter a match
showing a seventh of the template gave a velocity tens of pixels off and lost the object a
few frames later; the place is still taken from the match."""

from __future__ import annotations

import numpy as np
import pytest

from lfsam.video.tracking.carry import Template
from lfsam.video.tracking.motion import VELOCITY_SUPPORT, Track, update
from search_oracle import CENTER, label_answer, search_one_image


def _track(support: float) -> Track:
    look = np.full((10, 10, 3), 200.0, np.float32)
    template = Template(look, np.ones((10, 10), bool), (20, 30))
    return Track(CENTER, template, velocity=(2.0, 1.0), area=100, sightings=3,
                 support=support, state="tracked")


@pytest.mark.parametrize("support", [0.14, 1.0])
def test_a_poorly_supported_match_moves_the_velocity_by_its_share(support):
    track = _track(support)
    image = np.zeros((60, 80, 3), np.float32)
    mask = np.zeros((60, 80), bool)
    mask[42:52, 31:41] = True  # found 22 rows and 1 column on: 20 rows off the prediction
    located = Template(track.template.image, track.template.mask, (42, 31))
    update(track, CENTER, mask, located, image, 0.0, CENTER)
    weight = min(1.0, support / VELOCITY_SUPPORT)
    assert track.velocity == pytest.approx((2.0 + weight * 20.0, 1.0))
    if support < VELOCITY_SUPPORT:
        assert track.velocity[0] < 12.0  # before: the measured 22 rows a frame
    assert track.template.origin == (42, 31)  # the place is the match's
    assert track.unseen == 0 and track.state == "tracked"


def test_the_search_records_the_share_of_the_template_its_match_supports():
    rng = np.random.default_rng(5)
    look = rng.uniform(130, 255, (14, 14, 3)).astype(np.float32)
    image = rng.uniform(40, 100, (60, 80, 3)).astype(np.float32)
    labels = np.ones((60, 80), np.int64)
    image[20:34, 30:44] = look
    labels[20:34, 30:44] = 2
    image[25:40, 26:48] = 0.0  # a cover over all but its top 5 rows
    labels[25:40, 26:48] = 3

    track = Track(CENTER, Template(look, np.ones((14, 14), bool), (20, 30)), area=196,
                  sightings=3, state="tracked")
    found = search_one_image(track, image, label_answer(labels, CENTER))
    assert found is not None and found[1].sum() == 5 * 14
    assert track.support == pytest.approx(5 / 14, abs=0.05)
