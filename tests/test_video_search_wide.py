"""The search's widening stage (issue 47, fifth pass; docs/design.md section 10,
"Tracking", step 2): an object whose predicted place missed it (it turned while hidden, or
was hidden before its velocity was known) and that shows only a band of itself beside a cover
over its prediction is found within the search radius by the likely shifts of
:func:`lfsam.video.tracking.match.likely_shifts`, its motion kept; the likely map leaves out objects
placed already and pixels at another depth."""

from __future__ import annotations

import numpy as np
import pytest

from lfsam.video.tracking.carry import Template
from lfsam.video.tracking.match import likely_shifts, robust_costs, with_depth
from lfsam.video.tracking.motion import Track, update
from search_oracle import label_answer, search_one_image

SIZE, CENTER = (60, 80), (2, 2)


def _scene(shift=(13, -16), rows=4):
    """A textured 14x14 object predicted at (20, 30), covered there by a dark occluder; it
    is really at ``shift`` from the prediction with only its top ``rows`` rows showing (the
    rest behind the occluder's lower part): the masked SSD prefers the plain background
    elsewhere to the true place, mostly over the dark cover."""
    rng = np.random.default_rng(3)
    look = rng.uniform(130, 255, (14, 14, 3)).astype(np.float32)
    image = rng.uniform(40, 100, (*SIZE, 3)).astype(np.float32)
    labels = np.ones(SIZE, np.int64)
    r, c = 20 + shift[0], 30 + shift[1]
    image[r:r + rows, c:c + 14] = look[:rows]
    labels[r:r + rows, c:c + 14] = 2
    image[r + rows:r + rows + 14, c - 3:c + 17] = (0.0, 0.0, 0.0)  # the cover below
    labels[r + rows:r + rows + 14, c - 3:c + 17] = 3
    image[16:38, 29:47] = (0.0, 0.0, 0.0)  # and over the prediction
    labels[16:38, 29:47] = 3
    template = Template(look, np.ones((14, 14), bool), (20, 30))
    return image, labels, template


def _search(image, labels, track, placed=None):
    return search_one_image(track, image, label_answer(labels), placed=placed,
                            disparities=lambda v: np.ones(SIZE, np.float32),
                         depth=lambda v, m: 1.0)


@pytest.mark.parametrize("shift, unseen, sightings", [
    ((13, -16), 1, 3),  # it turned while hidden for a frame
    ((14, -27), 3, 1),  # hidden since frame 1, no velocity: back 30 px from where it was
])
def test_an_object_whose_prediction_missed_is_found_by_its_band_within_the_radius(
        shift, unseen, sightings):
    image, labels, template = _scene(shift)
    track = Track(CENTER, template, area=196, sightings=sightings, unseen=unseen,
                  disparity=1.0, velocity=(0.0, 0.0))
    found = _search(image, labels, track)
    assert found is not None  # before: hidden (the SSD led astray by the cover)
    view, mask, shift, located = found
    np.testing.assert_array_equal(mask, labels == 2)
    # a band of the object: its place is no measure of the motion, the prediction is kept
    assert shift is None and located.origin == template.origin
    update(track, view, mask, located, image, 1.0, CENTER, shift is not None)
    assert track.velocity == (0.0, 0.0) and track.unseen == 0 and track.state == "found"


def test_the_widening_stage_keeps_off_placed_objects_and_other_depths():
    image, labels, template = _scene()
    track = Track(CENTER, template, area=196, sightings=3, unseen=1, disparity=1.0)
    # the band belongs to an object placed earlier in this frame: not this one
    assert _search(image, labels, track, placed=labels == 2) is None
    gated = with_depth(template, image, np.where(labels == 2, -3.0, 1.0).astype(np.float32),
                       1.0, 1.2)
    du, dv = likely_shifts(*gated, 16, 400)
    assert du.size == 0  # the band lies at another depth: no pixel could be the object
    du, dv = likely_shifts(*with_depth(template, image, np.ones(SIZE, np.float32), 1.0, 1.2),
                           16, 400)
    _, counts = robust_costs(template, image, du, dv)
    assert counts.max() == 56  # at its depth: the band's 4 rows of 14, all supported


def test_likely_shifts_rank_the_true_shift_first_on_a_plain_view():
    """All shifts at once: the template pasted whole at (7, -5) in a view of other colours
    is the likeliest shift, ahead of every other within the radius."""
    rng = np.random.default_rng(1)
    look = rng.uniform(130, 255, (10, 12, 3)).astype(np.float32)
    image = rng.uniform(0, 110, (*SIZE, 3)).astype(np.float32)
    image[27:37, 25:37] = look
    template = Template(look, np.ones((10, 12), bool), (20, 30))
    du, dv = likely_shifts(template, image, 12, 5)
    assert (int(du[0]), int(dv[0])) == (7, -5)


def test_the_ring_views_masked_ssd_from_one_batch_gives_each_views_numbers():
    """:func:`lfsam.video.tracking.match.cost_maps` (one object predicted in several views, the
    template's transform once, windows cut at the frame and given one shape) against
    :func:`lfsam.video.tracking.match.cost_map` of each view alone, shift by shift."""
    from lfsam.video.tracking.match import cost_map, cost_maps

    rng = np.random.default_rng(7)
    look = rng.uniform(0, 255, (9, 11, 4)).astype(np.float32)
    mask = rng.random((9, 11)) > 0.3
    origins = [(12, 15), (1, 2), (50, 70), (-4, 44)]
    templates = [Template(look, mask, o) for o in origins]
    images = [rng.uniform(0, 255, (*SIZE, 4)).astype(np.float32) for _ in origins]
    for radius in (6, 20):
        batch = cost_maps(templates, images, radius)
        for template, image, (cost, du, dv) in zip(templates, images, batch, strict=True):
            alone, du1, dv1 = cost_map(template, image, radius)
            at = {(a, b): x for a, b, x in zip(du.ravel(), dv.ravel(), cost.ravel(),
                                                strict=True)}
            got = np.array([at[(a, b)] for a, b in zip(du1.ravel(), dv1.ravel(),
                                                        strict=True)])
            assert np.array_equal(np.isfinite(got), np.isfinite(alone.ravel()))
            finite = np.isfinite(got)
            np.testing.assert_allclose(got[finite], alone.ravel()[finite], rtol=1e-4,
                                       atol=0.5)
            assert abs(du1).max() <= radius and abs(dv1).max() <= radius


def test_the_batched_ffts_give_the_same_numbers_on_any_thread_count():
    """:func:`lfsam.video.tracking.match.fft_threads` hands scipy PyTorch's thread count: the masked
    SSD of several views and the likely shifts are bit for bit those of one thread (the
    search's answers do not depend on the machine's cores)."""
    import torch

    from lfsam.video.tracking.match import cost_maps, likely_shifts_many

    rng = np.random.default_rng(11)
    look = rng.uniform(0, 255, (9, 11, 4)).astype(np.float32)
    mask = rng.random((9, 11)) > 0.3
    templates = [Template(look, mask, o) for o in [(12, 15), (1, 2), (50, 70), (-4, 44)]]
    images = [rng.uniform(0, 255, (*SIZE, 4)).astype(np.float32) for _ in templates]
    before = torch.get_num_threads()
    runs = []
    try:
        for threads in (1, 3):
            torch.set_num_threads(threads)
            runs.append((cost_maps(templates, images, 20),
                         likely_shifts_many(templates, images, 20, 40, [None] * 4)))
    finally:
        torch.set_num_threads(before)
    (maps_1, likely_1), (maps_3, likely_3) = runs
    for one, three in zip([*maps_1, *likely_1], [*maps_3, *likely_3], strict=True):
        for a, b in zip(one[:2], three[:2], strict=True):
            assert np.array_equal(a, b)
