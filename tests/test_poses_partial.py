"""Poses from partial views (issue 64; docs/design.md section 12, "Poses through occlusions"):
what a strip of a surface leaves free is held by the predicted motion, wrong feature pairs do
not pull a fit the planes pin, a free body's motion is predicted through a gap, and a mask's
cover by a nearer object is seen whichever way the mask is off."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

from lfsam.poses.prediction import predict_motion
from lfsam.poses.rim import RimOptions, covered_share
from lfsam.spatial.registration import (
    estimate_normals,
    icp,
    plane_conditioning,
    transform,
)
from lfsam.synth.rigid import box_surface_points, rotation_about

vectors = st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda v: np.linalg.norm(v) > 0.1)


def _motion(axis, angle_deg, shift) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = rotation_about(axis, math.radians(angle_deg))
    out[:3, 3] = shift
    return out


def _plane(half_x: float, half_y: float, step: float = 0.002) -> np.ndarray:
    xs, ys = np.meshgrid(np.arange(-half_x, half_x + 1e-9, step),
                         np.arange(-half_y, half_y + 1e-9, step))
    return np.c_[xs.ravel(), ys.ravel(), np.ones(xs.size)]


@settings(max_examples=20, deadline=None)
@given(slide=st.tuples(st.floats(-0.01, 0.01), st.floats(-0.01, 0.01)),
       depth=st.floats(-0.002, 0.002), prior_off=st.floats(-0.002, 0.002))
def test_a_strip_of_one_face_takes_from_the_prior_only_what_it_leaves_free(slide, depth,
                                                                           prior_off):
    model = _plane(0.05, 0.05)
    normals = np.tile([0.0, 0.0, -1.0], (len(model), 1))
    strip = model[np.abs(model[:, 1]) <= 0.006]
    moved = np.eye(4)
    moved[:3, 3] = [slide[0], slide[1], depth]
    source = transform(moved, strip)  # the strip, where the frame sees it
    truth = np.linalg.inv(moved)  # frame -> model
    prior = truth.copy()
    prior[2, 3] += prior_off  # a prediction off along the normal, right in the plane
    gates = (0.008, 0.004, 0.003)
    plain = icp(source, model, normals, np.eye(4), gates=gates)
    held = icp(source, model, normals, np.eye(4), gates=gates, prior=prior, prior_weight=1e-4)
    # the planes pin the depth, whatever the prior says
    assert abs(plain.transform[2, 3] - truth[2, 3]) < 1e-6
    assert abs(held.transform[2, 3] - truth[2, 3]) < 1e-5
    # in the plane nothing pins the strip: without a prior it stays where it started, with
    # one it goes where the prior says
    np.testing.assert_allclose(plain.transform[:2, 3], 0.0, atol=1e-6)
    np.testing.assert_allclose(held.transform[:2, 3], truth[:2, 3], atol=1e-5)
    np.testing.assert_allclose(held.transform[:3, :3], np.eye(3), atol=1e-5)
    assert plain.conditioning < 1e-6 and held.conditioning < 1e-6


def _box_corner():
    box = box_surface_points(np.array([0.1, 0.12, 0.15]))
    seen = box[(box[:, 0] > 0.049) | (box[:, 1] > 0.059) | (box[:, 2] < -0.074)]
    return seen + np.array([0.0, 0.0, 1.0])


def test_plane_conditioning_tells_a_corner_from_a_face():
    corner = _box_corner()
    assert plane_conditioning(corner, estimate_normals(corner)) > 0.1
    face = _plane(0.05, 0.05)
    assert plane_conditioning(face, np.tile([0.0, 0.0, -1.0], (len(face), 1))) < 1e-9
    assert plane_conditioning(np.zeros((0, 3)), np.zeros((0, 3))) == 0.0


@settings(max_examples=15, deadline=None)
@given(axis=vectors, angle=st.floats(-4.0, 4.0),
       shift=st.tuples(*[st.floats(-0.008, 0.008)] * 3), wrong=st.integers(1, 8))
def test_wrong_feature_pairs_do_not_pull_a_fit_the_planes_pin(axis, angle, shift, wrong):
    corner = _box_corner()
    normals = estimate_normals(corner)
    motion = _motion(axis, angle, shift)
    source = transform(motion, corner)
    truth = np.linalg.inv(motion)
    rng = np.random.default_rng(wrong)
    picks = rng.choice(len(corner), 20, replace=False)
    pairs_model = corner[picks].copy()
    pairs_model[:wrong] += rng.normal(size=(wrong, 3)) * 0.006 + 0.006  # 7-20 mm off
    pairs = (transform(motion, corner[picks]), pairs_model)
    found = icp(source, corner, normals, np.eye(4), pairs=pairs, pair_weight=1.0)
    np.testing.assert_allclose(found.transform, truth, atol=2e-4)
    assert found.inliers > 0.99


@settings(max_examples=30, deadline=None)
@given(axis=vectors, angle=st.floats(-5.0, 5.0),
       velocity=st.tuples(*[st.floats(-0.02, 0.02)] * 3),
       centre=st.tuples(st.floats(-0.3, 0.3), st.floats(-0.3, 0.3), st.floats(0.5, 2.0)),
       seen=st.integers(2, 4), gap=st.integers(1, 6))
def test_a_free_body_is_predicted_through_any_gap(axis, angle, velocity, centre, seen, gap):
    """A body spinning about its own centre at a constant rate while its centre goes straight
    (how ``lfsam synth --rigid`` moves its boxes, and a thrown object flies)."""
    c0 = np.asarray(centre)
    turn = rotation_about(axis, math.radians(angle))

    def motion(k):  # first frame -> frame k
        out = np.eye(4)
        out[:3, :3] = np.linalg.matrix_power(turn, k)
        out[:3, 3] = c0 + k * np.asarray(velocity) - out[:3, :3] @ c0
        return out

    motions = [motion(k) for k in range(seen)]
    predicted = predict_motion(motions, list(range(seen)), seen - 1 + gap, centre=c0)
    np.testing.assert_allclose(predicted, motion(seen - 1 + gap), atol=1e-9)


def _scene(error: int):
    """A square (label 1) in front of a far wall, partly behind a nearer bar (label 2), its
    mask dilated (``error`` > 0) or eroded (< 0) by ``error`` pixels; and the same square with
    nothing in front."""
    size = 48
    disparity = np.full((size, size), 1.0)
    square = np.zeros((size, size), bool)
    square[12:36, 10:34] = True
    disparity[square] = 2.0
    bar = np.zeros((size, size), bool)
    bar[:, 28:36] = True
    covered = disparity.copy()
    covered[bar] = 4.0
    seen = square & ~bar
    if error > 0:
        grown = ndimage.binary_dilation(seen, iterations=error)
    elif error < 0:
        grown = ndimage.binary_erosion(seen, iterations=-error)
    else:
        grown = seen
    labels = np.where(bar, 2, 0)
    labels[grown] = 1
    alone = np.zeros((size, size), int)
    whole = (ndimage.binary_dilation(square, iterations=error) if error > 0
             else ndimage.binary_erosion(square, iterations=-error) if error < 0 else square)
    alone[whole] = 1
    return (labels, covered), (alone, disparity)


@given(error=st.integers(-2, 2))
def test_a_cover_by_a_nearer_object_is_seen_whichever_way_the_mask_is_off(error):
    (labels, disparity), (alone, background) = _scene(error)
    options = RimOptions(inside_px=2, jump_px=1)
    assert covered_share(labels, disparity, options)[1] > 0.15
    assert covered_share(alone, background, options)[1] == 0.0
    # the nearer bar itself is covered by nothing
    assert covered_share(labels, disparity, options)[2] == 0.0
