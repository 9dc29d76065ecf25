"""Which pixels of an imperfect mask a pose trusts (issue 64; docs/design.md section 12,
"Imperfect masks"; :mod:`lfsam.poses.rim`): properties of :func:`trusted_labels` on masks off by
a known number of pixels, and the tracker on a rigid-box video whose masks are all a pixel too
wide (what a real segmenter's boundary gives), against the exact ground truth."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

from lfsam.metrics.pose import add_error, rotation_error_deg
from lfsam.poses import PoseOptions, PoseTracker, ViewData
from lfsam.poses.rim import RimOptions, trusted_labels
from lfsam.spatial.registration import transform
from lfsam.synth.rigid import RIGID_CAMERA, box_surface_points


def _scene(top, left, height, width, off):
    """A (40, 50) view: a rectangle (label 2) in front of a wall (label 1), and its mask grown
    (``off`` > 0) or shrunk (``off`` < 0) by ``abs(off)`` pixels."""
    truth = np.ones((40, 50), np.int32)
    truth[top:top + height, left:left + width] = 2
    inside = truth == 2
    if off > 0:
        inside = ndimage.binary_dilation(inside, np.ones((3, 3), bool), iterations=off)
    elif off < 0:
        inside = ndimage.binary_erosion(inside, np.ones((3, 3), bool), iterations=-off)
    mask = np.where(inside, 2, 1).astype(np.int32)
    return truth, mask


boxes = st.tuples(st.integers(3, 20), st.integers(3, 25), st.integers(12, 17),
                  st.integers(12, 22), st.integers(-2, 2))


@settings(max_examples=40, deadline=None)
@given(box=boxes, object_d=st.floats(-1.0, 3.0), behind=st.floats(0.1, 0.5),
       slope=st.floats(-0.01, 0.01))
def test_a_mask_off_by_two_pixels_over_a_farther_wall_trusts_no_wall(box, object_d, behind,
                                                                     slope):
    """The wall lies 10-50 % of the object's depth behind it; the object's surface is slanted
    (its disparity changes along the columns); zero-disparity offset 4 (the rigid camera's)."""
    truth, mask = _scene(*box)
    offset = 4.0
    columns = np.arange(50)[None, :] * slope
    wall = (object_d + offset) / (1 + behind) - offset
    disparity = np.where(truth == 2, object_d + columns, wall).astype(np.float32)
    kept = trusted_labels(mask, disparity, zero_disparity_offset=offset)
    assert not ((kept == 2) & (truth != 2)).any()
    assert ((kept == 0) | (kept == mask)).all()
    if box[-1] == 0 and behind >= 0.25:
        # an exact mask over a wall clearly behind (more than the 5 % jump everywhere, the
        # slope included): kept whole, its silhouette too
        np.testing.assert_array_equal(kept == 2, mask == 2)
    # the object keeps its interior: everything over 2 pixels inside the mask and the truth
    deep = ndimage.binary_erosion(truth == 2, np.ones((3, 3), bool),
                                  iterations=3 + max(-box[-1], 0))
    assert (kept[deep] == 2).all()


@settings(max_examples=30, deadline=None)
@given(box=boxes)
def test_a_mask_off_by_two_pixels_at_the_objects_own_depth_trusts_no_neighbour(box):
    """No depth jump marks the rim (a box on a table): the interior test alone keeps the
    neighbour's pixels out."""
    truth, mask = _scene(*box)
    kept = trusted_labels(mask, np.full(truth.shape, 2.0), zero_disparity_offset=4.0)
    assert not ((kept == 2) & (truth != 2)).any()


def test_a_thin_object_is_kept_whole_and_the_tests_can_be_turned_off():
    labels = np.ones((30, 30), np.int32)
    labels[5:25, 14:17] = 3  # three pixels wide: the interior test leaves nothing
    disparity = np.full(labels.shape, 1.0, np.float32)
    kept = trusted_labels(labels, disparity)
    np.testing.assert_array_equal(kept == 3, labels == 3)
    off = RimOptions(inside_px=0, jump_px=0, min_left=0.0)
    np.testing.assert_array_equal(trusted_labels(labels, disparity, off), labels)
    # a non-finite disparity is a jump: its neighbours are not trusted
    disparity[15, 5] = np.nan
    kept = trusted_labels(labels, disparity, RimOptions(inside_px=0, min_left=0.0))
    assert (kept[14:17, 4:7] == 0).all() and kept[10, 5] == 1


@pytest.fixture(scope="module")
def wide_masks():
    """A 1-box video of 5x5 views of 120x160 whose masks are all one pixel too wide."""
    from lfsam.synth.rigid import generate_rigid_video

    video = list(generate_rigid_video(frames=5, seed=11, supersample=1, boxes=1, grid=(5, 5),
                                      size=(120, 160), box_size_m=(0.08, 0.1), texels=64))
    grown = [ndimage.grey_dilation(lf.labels * (lf.labels > 1), size=(1, 1, 3, 3))
             for lf in video]
    return video, grown


def _errors(video, grown, options):
    tracker = PoseTracker(RIGID_CAMERA, video[0].view_shape, options)
    s_c, t_c = video[0].center
    for index, (lf, labels) in enumerate(zip(video, grown, strict=True)):
        views = [ViewData((s - s_c, t - t_c), lf.views[s, t], labels[s, t], lf.disparity[s, t])
                 for s in range(lf.grid_shape[0]) for t in range(lf.grid_shape[1])]
        tracker.add_frame(views, frame=index)
    (box,) = [b for b in video[0].meta["rigid"]["objects"] if b["label"] == 2]
    pose0, size = np.asarray(box["pose"]), np.asarray(box["size_m"])
    model = transform(pose0, box_surface_points(size))
    (track,) = tracker.objects
    adds, rotations = [], []
    for entry in track.frames[1:]:
        (now,) = [b for b in video[entry.frame].meta["rigid"]["objects"] if b["label"] == 2]
        true = np.asarray(now["pose"]) @ np.linalg.inv(pose0)
        adds.append(add_error(model, entry.motion, true) / np.linalg.norm(size))
        rotations.append(rotation_error_deg(entry.motion, true))
    return np.array(adds), np.array(rotations)


def test_masks_a_pixel_too_wide_keep_the_pose(wide_masks):
    """With the rim trusted the wall's ring pulls the box towards standing still; left out, the
    pose is as good as with exact masks (ADD <= 2 % of the diameter, median rotation <= 0.5
    degree, none above 2: issue 64's targets for one pixel of mask error)."""
    adds, rotations = _errors(*wide_masks, PoseOptions())
    assert adds.max() <= 0.02, adds
    assert np.median(rotations) <= 0.5 and rotations.max() <= 2.0, rotations
    trusting, _ = _errors(*wide_masks, PoseOptions(rim=None))
    assert trusting.max() > 2 * adds.max(), (trusting, adds)


def _too_wide(labels):
    """Every mask 6 pixels too wide (13 x 13 dilation in every view)."""
    return ndimage.grey_dilation(labels, size=(1, 1, 13, 13))


def _statuses(video, changed):
    """A tracker trusting every pixel over ``video``'s box, the labels of frame ``i`` changed
    by ``changed[i]``; the tracker and the box's status per frame."""
    tracker = PoseTracker(RIGID_CAMERA, video[0].view_shape, PoseOptions(rim=None))
    s_c, t_c = video[0].center
    statuses = []
    for index, lf in enumerate(video):
        labels = lf.labels * (lf.labels > 1)
        if index in changed:
            labels = changed[index](labels)
        views = [ViewData((s - s_c, t - t_c), lf.views[s, t], labels[s, t], lf.disparity[s, t])
                 for s in range(lf.grid_shape[0]) for t in range(lf.grid_shape[1])]
        statuses.append(tracker.add_frame(views, frame=index)[0].status)
    return tracker, statuses


def test_a_fit_pulled_off_by_what_is_not_the_object_is_uncertain(wide_masks):
    """Frame 3's masks take in 6 pixels of the wall around the box in every view, with every
    pixel trusted: its fit is several times worse than the box's own (``uncertain``, a pose
    still given, its points kept out of the model); with exact masks again in frame 4 the box
    is ``tracked`` and within 2 % ADD."""
    video, _ = wide_masks
    tracker, statuses = _statuses(video, {3: _too_wide})
    assert statuses == ["tracked", "tracked", "tracked", "uncertain", "tracked"], statuses
    (track,) = tracker.objects
    assert track.frames[3].pose is not None
    (box,) = [b for b in video[0].meta["rigid"]["objects"] if b["label"] == 2]
    (last,) = [b for b in video[4].meta["rigid"]["objects"] if b["label"] == 2]
    pose0, size = np.asarray(box["pose"]), np.asarray(box["size_m"])
    true = np.asarray(last["pose"]) @ np.linalg.inv(pose0)
    model = transform(pose0, box_surface_points(size))
    assert add_error(model, track.frames[4].motion, true) / np.linalg.norm(size) <= 0.02


def test_a_poor_fit_on_the_frame_an_object_comes_back_is_uncertain(wide_masks):
    """Hidden in frame 3, the box comes back in frame 4 with masks 6 pixels too wide (every
    pixel trusted): its fit is poor, so it is ``uncertain``, not ``found again``."""
    video, _ = wide_masks
    _, statuses = _statuses(video, {3: np.zeros_like, 4: _too_wide})
    assert statuses == ["tracked", "tracked", "tracked", "lost", "uncertain"], statuses
