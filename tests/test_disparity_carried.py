"""One view's estimate carried to the other views (lfsam.disparity.carried; issue 65)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from lfsam.devices import view_workers
from lfsam.disparity import estimate_disparity
from lfsam.disparity.carried import LIGHT_ESTIMATE, carry_estimate, estimate_views
from lfsam.errors import LfsamError
from lfsam.synth import generate_scene


@settings(max_examples=25, deadline=None)
@given(
    d=st.floats(-2.0, 2.0).map(lambda x: round(x, 2)),
    ds=st.integers(-3, 3),
    dt=st.integers(-3, 3),
)
def test_a_plane_is_carried_unchanged_and_only_the_entering_strip_is_unsure(d, ds, dt):
    """A fronto-parallel plane keeps its disparity in every view; a view pixel is trusted where
    it comes from inside the reference view (the strip entering at the border is not)."""
    height, width = 12, 16
    reference = np.full((height, width), d, dtype=np.float32)
    trust = np.linspace(0.2, 1.0, height * width, dtype=np.float32).reshape(height, width)
    carried, confidence = carry_estimate(reference, trust, (ds, dt), device="cpu")
    np.testing.assert_allclose(carried, d, atol=1e-6)
    rows, cols = np.mgrid[0:height, 0:width]
    source_u = np.round(rows + d * ds).astype(int)
    source_v = np.round(cols + d * dt).astype(int)
    inside = (source_u >= 0) & (source_u < height) & (source_v >= 0) & (source_v < width)
    # on the pixels the reference sees, the confidence is the reference's at the source pixel
    # (forward and backward rounding agree for a constant shift, except exactly at .5)
    seen = confidence > 0
    assert seen.sum() >= 0.9 * inside.sum() - (height + width)
    assert not (seen & ~inside).any()
    np.testing.assert_allclose(
        confidence[seen], trust[source_u[seen], source_v[seen]], atol=1e-6
    )


def test_carried_ground_truth_matches_each_views_own_where_the_center_sees_it():
    """Carrying the center's exact disparity gives each view's exact disparity on the pixels
    the center view sees; the pixels it does not see are flagged with confidence 0."""
    lf = generate_scene(grid=(5, 5), size=(48, 64), seed=21, disparity_range=(-1.5, 1.5))
    center = lf.center
    for view in ((0, 0), (4, 4), (0, 2), (3, 1)):
        offset = (view[0] - center[0], view[1] - center[1])
        carried, confidence = carry_estimate(lf.disparity[center], None, offset, device="cpu")
        truth = lf.disparity[view]
        trusted = confidence > 0
        assert trusted.mean() > 0.8, trusted.mean()
        error = np.abs(carried - truth)[trusted]
        assert np.mean(error <= 0.1) > 0.97, np.mean(error <= 0.1)
        # untrusted pixels are exactly the ones with confidence 0; no other values appear
        assert set(np.unique(confidence)) <= {0.0, 1.0}


def test_estimate_views_carried_and_each():
    lf = generate_scene(grid=(3, 3), size=(32, 48), seed=5)
    views = [(1, 1), (0, 0), (2, 2)]
    carried = estimate_views(lf, views, mode="carried", device="cpu")
    each = estimate_views(lf, views, mode="own", device="cpu")
    assert list(carried) == views and list(each) == views
    for view in views:
        for d, c in (carried[view], each[view]):
            assert d.shape == c.shape == lf.view_shape
            assert d.dtype == c.dtype == np.float32
            assert ((c >= 0) & (c <= 1)).all()
    # the center is the one estimate both modes share
    np.testing.assert_array_equal(carried[(1, 1)][0], each[(1, 1)][0])
    # light: each view's own estimate with the light settings, not the defaults
    light = estimate_views(lf, views[1:], mode="light", device="cpu")
    span = estimate_disparity(lf, view=views[1], device="cpu").disparity_range
    for view in views[1:]:  # the first view's range serves every view
        alone = estimate_disparity(lf, span, view=view, device="cpu", **LIGHT_ESTIMATE)
        np.testing.assert_array_equal(light[view][0], alone.disparity)
        np.testing.assert_array_equal(light[view][1], alone.confidence)
        assert alone.meta["fusion"] is False and alone.meta["wide_feature_radius"] is None
    with pytest.raises(LfsamError, match="estimate mode must be one of"):
        estimate_views(lf, views, mode="all")


def test_views_estimated_two_at_a_time_are_those_of_one_at_a_time():
    """With two torch threads the views after the first are estimated in two threads at once
    (:func:`lfsam.devices.view_workers`): each estimate is the one made alone, in the order
    asked for."""
    lf = generate_scene(grid=(5, 5), size=(40, 56), seed=7)
    views = [(2, 2), (0, 0), (0, 4), (4, 0), (4, 4)]
    threads = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        assert view_workers(torch.device("cpu")) == 2
        together = estimate_views(lf, views, mode="light", device="cpu")
    finally:
        torch.set_num_threads(threads)
    assert list(together) == views
    span = estimate_disparity(lf, view=views[0], device="cpu",
                              **LIGHT_ESTIMATE).disparity_range
    for view in views:
        alone = estimate_disparity(lf, span, view=view, device="cpu", **LIGHT_ESTIMATE)
        np.testing.assert_array_equal(together[view][0], alone.disparity)
        np.testing.assert_array_equal(together[view][1], alone.confidence)
