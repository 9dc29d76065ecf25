"""6D poses (docs/design.md section 12) against the exact ground truth of rigid-box videos.

The registration pieces are checked on random transforms (Kabsch, RANSAC with outliers,
point-to-plane ICP on a box's surface); the tracker on a small video of a box under known motion
with the ground-truth disparity and ground-truth or oracle masks (ADD and rotation error per
frame); the CLI for its outputs and its one-line errors.
"""

from __future__ import annotations

import csv
import io
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lfsam.cli.main import main
from lfsam.errors import LfsamError
from lfsam.metrics.pose import add_error, add_recall, rotation_error_deg
from lfsam.poses import (
    PoseTracker,
    VideoPoses,
    ViewData,
    bop_csv,
    default_pose_views,
    first_pose,
    poses_csv,
    poses_of_video,
)
from lfsam.result import SegmentationResult
from lfsam.spatial.registration import estimate_normals, icp, kabsch, ransac_rigid, transform
from lfsam.synth.rigid import RIGID_CAMERA, box_surface_points, rotation_about
from lfsam.video.io.synth import write_video_frames

SMALL = {"boxes": 1, "grid": (5, 5), "size": (120, 160), "box_size_m": (0.08, 0.1),
         "texels": 64}


def _motion(axis, angle, shift) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = rotation_about(axis, angle)
    out[:3, 3] = shift
    return out


vectors = st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda v: np.linalg.norm(v) > 0.1)


@settings(max_examples=25, deadline=None)
@given(axis=vectors, angle=st.floats(-3.0, 3.0), shift=st.tuples(*[st.floats(-1, 1)] * 3))
def test_kabsch_recovers_any_rigid_motion(axis, angle, shift):
    points = np.random.default_rng(1).normal(size=(20, 3))
    truth = _motion(axis, angle, shift)
    np.testing.assert_allclose(kabsch(points, transform(truth, points)), truth, atol=1e-9)


def test_ransac_ignores_wrong_pairs():
    rng = np.random.default_rng(2)
    src = rng.uniform(-0.1, 0.1, size=(60, 3)) + np.array([0.0, 0.0, 1.0])
    truth = _motion([1, 2, 3], 0.05, [0.01, -0.02, 0.005])
    dst = transform(truth, src)
    dst[:20] += rng.uniform(-0.05, 0.05, size=(20, 3))  # a third of the pairs wrong
    found, inliers = ransac_rigid(src, dst, 0.002)
    assert inliers[20:].all() and inliers[:20].sum() <= 1
    np.testing.assert_allclose(found, truth, atol=1e-9)
    assert ransac_rigid(src[:2], dst[:2], 0.002)[0] is None


def test_point_to_plane_icp_on_a_box_surface():
    size = np.array([0.12, 0.1, 0.15])
    model = box_surface_points(size, 0.003) + np.array([0.0, 0.0, 1.0])
    normals = estimate_normals(model, viewpoint=np.array([0.0, 0.0, 1.0]))
    truth = _motion([0.3, -1, 0.2], math.radians(3), [0.004, -0.006, 0.008])
    seen = transform(np.linalg.inv(truth), model)  # the model moved back by the truth
    found = icp(seen, model, normals, np.eye(4))
    assert rotation_error_deg(found.transform, truth) < 0.05
    assert add_error(model, found.transform, truth) < 2e-4
    assert found.inliers > 0.99


def test_first_pose_is_a_right_handed_principal_frame():
    rng = np.random.default_rng(3)
    points = rng.normal(size=(800, 3)) * [0.01, 0.04, 0.02]
    turn = _motion([1, 1, 0], 0.7, [0.1, 0.0, 1.0])
    pose = first_pose(transform(turn, points))
    assert abs(np.linalg.det(pose[:3, :3]) - 1) < 1e-9
    np.testing.assert_allclose(pose[:3, 3], transform(turn, points).mean(axis=0))
    assert abs(pose[:3, 0] @ turn[:3, 1]) > 0.99  # largest variance: the points' y axis


@pytest.fixture(scope="module")
def video():
    from lfsam.synth.rigid import generate_rigid_video

    return list(generate_rigid_video(frames=4, seed=11, supersample=1, **SMALL))


def _truth(lf, label=2):
    (box,) = [b for b in lf.meta["rigid"]["objects"] if b["label"] == label]
    return np.asarray(box["pose"]), np.asarray(box["size_m"])


def _scores(video, objects, label=2):
    pose0, size = _truth(video[0], label)
    model = transform(pose0, box_surface_points(size))
    diameter = float(np.linalg.norm(size))
    (track,) = [o for o in objects if o.object_id == label]
    adds, rotations = [], []
    for entry in track.frames:
        if entry.motion is None:
            adds.append(np.nan)
            rotations.append(np.nan)
            continue
        true = _truth(video[entry.frame], label)[0] @ np.linalg.inv(pose0)
        adds.append(add_error(model, entry.motion, true) / diameter)
        rotations.append(rotation_error_deg(entry.motion, true))
    return np.array(adds), np.array(rotations)


def test_tracks_a_box_with_ground_truth_disparity(video):
    frames = [(SegmentationResult(labels=lf.labels * (lf.labels > 1)), lf) for lf in video]
    camera, objects = poses_of_video(frames, disparity="gt", views="all")
    assert camera == RIGID_CAMERA
    adds, rotations = _scores(video, objects)
    assert len(adds) == 4 and adds[0] < 1e-12 and rotations[0] < 1e-6
    assert adds.max() < 0.02, adds  # ADD <= 2 % of the diameter in every frame
    assert np.median(rotations[1:]) < 0.5, rotations
    assert add_recall(adds) == 1.0
    (track,) = objects
    assert [f.status for f in track.frames] == ["tracked"] * 4
    for entry in track.frames:
        np.testing.assert_allclose(entry.pose, entry.motion @ track.first_pose, atol=1e-12)
        assert entry.inliers > 0.9 and entry.rmse_m < 0.002


def test_fewer_views_and_a_single_light_field(video):
    frames = [(SegmentationResult(labels=lf.labels * (lf.labels > 1)), lf) for lf in video]
    _, objects = poses_of_video(frames, disparity="gt", views="center")
    adds, _ = _scores(video, objects)
    assert adds.max() < 0.05, adds
    _, objects = poses_of_video(frames, disparity="gt", views="corners")
    adds, _ = _scores(video, objects)
    assert adds.max() < 0.02, adds
    with pytest.raises(LfsamError, match="views must be one of"):
        poses_of_video(frames, disparity="gt", views="ring")
    _, single = poses_of_video(frames[2:3], disparity="gt")
    (track,) = single
    (entry,) = track.frames
    assert entry.frame == 0 and entry.status == "tracked"
    np.testing.assert_array_equal(entry.motion, np.eye(4))
    np.testing.assert_allclose(entry.pose, track.first_pose)
    # the first pose's origin is the centroid of the box's visible points: near its centre
    assert np.linalg.norm(track.first_pose[:3, 3] - _truth(video[2])[0][:3, 3]) < 0.05


def test_the_next_frame_prepared_ahead_gives_the_poses_of_one_frame_at_a_time(video):
    """`poses_of_video` estimates the next frame's views while it registers one (issue 65):
    the poses, their frames and the calls of ``on_frame`` are those of :class:`VideoPoses`
    fed frame after frame; a bad frame's error names that frame."""
    frames = [(SegmentationResult(labels=lf.labels * (lf.labels > 1)), lf) for lf in video[:2]]
    seen = []
    _, ahead = poses_of_video(frames, views="center",
                              on_frame=lambda k, entries: seen.append((k, len(entries))))
    session = VideoPoses(views="center")
    calls = [(k, len(session.add(*frame))) for k, frame in enumerate(frames)]
    assert seen == calls and [k for k, _ in seen] == [0, 1]
    assert len(ahead) == len(session.objects) > 0
    for mine, theirs in zip(ahead, session.objects, strict=True):
        assert [f.frame for f in mine.frames] == [f.frame for f in theirs.frames]
        for a, b in zip(mine.frames, theirs.frames, strict=True):
            assert a.status == b.status
            np.testing.assert_array_equal(a.motion, b.motion)
    wrong = SegmentationResult(labels=frames[1][0].labels[:, :, :-1])
    with pytest.raises(LfsamError, match="the result of frame 1"):
        poses_of_video([frames[0], (wrong, frames[1][1])], disparity="gt")


def test_too_few_points_is_lost_then_found_again(video):
    tracker = PoseTracker(RIGID_CAMERA, video[0].view_shape)
    centre = video[0].center
    statuses = []
    for index, lf in enumerate(video):
        labels = lf.labels[centre] * (lf.labels[centre] > 1)
        if index == 2:  # the object shrinks to a few pixels
            rows, cols = np.nonzero(labels)
            labels = np.zeros_like(labels)
            labels[rows[:10], cols[:10]] = 2
        view = ViewData((0, 0), lf.views[centre], labels, lf.disparity[centre])
        (entry,) = tracker.add_frame([view])
        statuses.append(entry.status)
        if entry.status == "lost":
            assert entry.motion is None and entry.pose is None
    assert statuses == ["tracked", "tracked", "lost", "found again"]
    adds, _ = _scores(video, tracker.objects)
    assert np.isnan(adds[2]) and np.nanmax(adds) < 0.05, adds


def test_csv_and_bop_rows(video):
    frames = [(SegmentationResult(labels=lf.labels * (lf.labels > 1)), lf) for lf in video[:2]]
    _, objects = poses_of_video(frames, disparity="gt", views="center")
    rows = list(csv.DictReader(io.StringIO(poses_csv(objects))))
    assert [int(r["frame"]) for r in rows] == [0, 1]
    q = np.array([float(rows[1][k]) for k in ("qw", "qx", "qy", "qz")])
    assert abs(np.linalg.norm(q) - 1) < 1e-6
    bop = list(csv.DictReader(io.StringIO(bop_csv(objects, scene_id=5))))
    assert list(bop[0]) == ["scene_id", "im_id", "obj_id", "score", "R", "t", "time"]
    rot = np.array(bop[1]["R"].split(), float).reshape(3, 3)
    t_mm = np.array(bop[1]["t"].split(), float)
    np.testing.assert_allclose(rot, objects[0].frames[1].pose[:3, :3], atol=1e-8)
    np.testing.assert_allclose(t_mm, objects[0].frames[1].pose[:3, 3] * 1000, atol=1e-3)
    assert bop[1]["scene_id"] == "5" and bop[1]["im_id"] == "1"


@pytest.fixture(scope="module")
def folders(tmp_path_factory, video):
    base = tmp_path_factory.mktemp("poses")
    write_video_frames(iter(video), base / "boxes")
    assert main(["segment", str(base / "boxes"), "--auto", "--model", "oracle",
                 "--disparity", "gt", "--out", str(base / "result")]) == 0
    return base


def test_cli_on_oracle_masks(folders, capsys):
    out = folders
    assert main(["poses", str(out / "result"), "--lightfield", str(out / "boxes"),
                 "--disparity", "gt", "--json", str(out / "p.json"), "--csv",
                 str(out / "p.csv"), "--bop", str(out / "b.csv")]) == 0
    printed = capsys.readouterr().out
    assert "over 4 frames" in printed
    document = json.loads((out / "p.json").read_text())
    assert document["camera"] == RIGID_CAMERA.to_json()
    video = [json.loads((out / "boxes" / f"frame_{k:04d}" / "lfsam_scene.json").read_text())
             for k in range(4)]
    pose0 = np.asarray(video[0]["meta"]["rigid"]["objects"][0]["pose"])
    size = np.asarray(video[0]["meta"]["rigid"]["objects"][0]["size_m"])
    model = transform(pose0, box_surface_points(size))
    # the oracle's object on the box: the one whose first centroid lies inside the box
    inside = [o for o in document["objects"]
              if (np.abs(transform(np.linalg.inv(pose0), np.asarray(o["first_pose"])[None, :3, 3]))
                  <= size / 2).all()]
    (box,) = inside
    for entry in box["frames"]:
        pose_k = np.asarray(video[entry["frame"]]["meta"]["rigid"]["objects"][0]["pose"])
        true = pose_k @ np.linalg.inv(pose0)
        assert add_error(model, np.asarray(entry["motion"]), true) < 0.02 * np.linalg.norm(size)
        assert set(entry) >= {"frame", "motion", "pose", "inliers", "rmse_m", "status"}
    assert (out / "p.csv").read_text().startswith("id,category,frame,status,qw")
    assert (out / "b.csv").read_text().startswith("scene_id,im_id,obj_id,score,R,t,time")


def test_cli_one_line_errors(folders, tmp_path, capsys, video):
    out = folders
    # no camera: a copy of the video without one
    stripped = []
    for lf in video[:2]:
        lf2 = type(lf)(lf.views, disparity=lf.disparity, labels=lf.labels,
                       meta={k: v for k, v in lf.meta.items() if k != "camera"})
        stripped.append(lf2)
    write_video_frames(iter(stripped), tmp_path / "nocam")
    assert main(["segment", str(tmp_path / "nocam"), "--auto", "--model", "oracle",
                 "--disparity", "gt", "--out", str(tmp_path / "nocam_result")]) == 0
    capsys.readouterr()
    code = main(["poses", str(tmp_path / "nocam_result"), "--lightfield",
                 str(tmp_path / "nocam"), "--disparity", "gt"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--camera" in err[0], err
    # a result that does not match the light field (2 frames against 4)
    code = main(["poses", str(tmp_path / "nocam_result"), "--lightfield", str(out / "boxes"),
                 "--disparity", "gt"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert not (tmp_path / "x.json").exists()


def test_estimated_depth_by_default_uses_the_center_and_corner_views(tmp_path, capsys, video):
    """`lfsam poses` with its defaults estimates 5 views per frame, not every view (issue 65):
    it says so before the work, and the poses hold (ADD within 5 % of the diameter)."""
    write_video_frames(iter(video[:2]), tmp_path / "boxes")
    assert main(["segment", str(tmp_path / "boxes"), "--auto", "--model", "oracle",
                 "--disparity", "gt", "--out", str(tmp_path / "result")]) == 0
    capsys.readouterr()
    assert main(["poses", str(tmp_path / "result"), "--lightfield", str(tmp_path / "boxes"),
                 "--json", str(tmp_path / "p.json")]) == 0
    captured = capsys.readouterr()
    assert "estimating 5 views' disparity in every frame" in captured.err
    document = json.loads((tmp_path / "p.json").read_text())
    assert document["views"] == "corners" and document["estimate"] == "light"
    assert VideoPoses().estimate == "light"
    assert default_pose_views("estimate") == "corners" and default_pose_views("gt") == "all"
    assert VideoPoses().views == "corners" and VideoPoses(disparity="gt").views == "all"
    with pytest.raises(LfsamError, match="estimate must be one of"):
        VideoPoses(estimate="each")
    pose0, size = _truth(video[0])
    model = transform(pose0, box_surface_points(size))
    (box,) = [o for o in document["objects"]  # the oracle's object on the box
              if (np.abs(transform(np.linalg.inv(pose0), np.asarray(o["first_pose"])[None, :3, 3]))
                  <= size / 2).all()]
    motion = np.asarray(box["frames"][1]["motion"])
    true = _truth(video[1])[0] @ np.linalg.inv(pose0)
    assert add_error(model, motion, true) < 0.05 * np.linalg.norm(size)


def test_the_estimate_line_says_what_each_choice_costs(capsys):
    """Before the work `lfsam poses` says how many views it estimates per frame, and a user who
    asks for the full estimator (--estimate own) or every view is told what that costs."""
    import argparse

    from lfsam.cli.poses import _say_estimating

    def said(**chosen) -> str:
        args = argparse.Namespace(**{"disparity": "estimate", "estimate": "light",
                                     "views": "corners", **chosen})
        _say_estimating(args, (7, 7))
        return capsys.readouterr().err

    assert "estimating 5 views' disparity" in said() and "times" not in said()
    assert "3.5 times the time of --estimate light" in said(estimate="own")
    every = said(views="all", estimate="own")
    assert "49 views'" in every and "10 times the time of --views corners" in every
    assert "3.5 times" in every
    assert "center view's disparity" in said(estimate="carried")
    assert said(disparity="gt") == ""
