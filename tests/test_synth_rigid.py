"""Rigid-box light-field videos (docs/design.md section 12): exact geometry and known motion.

The views must be photo-consistent with the ground-truth disparity (warping every view into the
center view leaves a small residual, the opposite sign a large one), every labelled pixel of
every view back-projected with its disparity must lie on its box's surface at the box's known
pose, and the motion between frames must be what the generator promises.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from lfsam.camera import back_project
from lfsam.cli.main import main
from lfsam.geometry import project_pixels, warp_to_reference
from lfsam.synth.rigid import (
    RIGID_CAMERA,
    box_surface_points,
    generate_rigid_video,
    render_rigid,
    rigid_scenes,
)

SMALL = {"boxes": 1, "grid": (5, 5), "size": (120, 160), "box_size_m": (0.08, 0.1),
         "texels": 64}


@pytest.fixture(scope="module")
def scene():
    return rigid_scenes(frames=3, seed=5, **SMALL)


@pytest.fixture(scope="module")
def frame(scene):
    return render_rigid(scene, 2)


def test_views_are_photo_consistent(frame):
    sc, tc = frame.center
    rows, cols = np.indices(frame.view_shape)
    d = frame.center_disparity
    for s, t in [(0, 0), (4, 4), (0, 4), (2, 0), (4, 2)]:
        pu, pv = project_pixels(rows, cols, d, s - sc, t - tc)
        iu, iv = np.rint(pu).astype(int), np.rint(pv).astype(int)
        inside = (iu >= 0) & (iu < d.shape[0]) & (iv >= 0) & (iv < d.shape[1])
        visible = np.zeros_like(inside)
        visible[inside] = np.abs(frame.disparity[s, t][iu[inside], iv[inside]]
                                 - d[inside]) < 0.05
        right = warp_to_reference(frame.views[s, t], d, s - sc, t - tc)
        wrong = warp_to_reference(frame.views[s, t], -d, s - sc, t - tc)
        center = frame.center_view.astype(np.float32)
        good = np.nanmean(np.abs(right - center).mean(axis=-1)[visible])
        bad = np.nanmean(np.abs(wrong - center).mean(axis=-1)[visible])
        assert good < 6.0, (s, t, good)
        assert bad > 2.5 * good, (s, t, good, bad)


def test_labels_and_disparity_agree_with_the_pose(scene, frame):
    box = scene.boxes[0]
    pose = box.poses[2]
    inverse = np.linalg.inv(pose)
    half = box.size_m / 2
    sc, tc = frame.center
    for s, t in [(2, 2), (0, 0), (4, 1)]:
        rows, cols = np.nonzero(frame.labels[s, t] == box.label)
        assert rows.size > 500
        xyz = back_project(rows, cols, frame.disparity[s, t][rows, cols], RIGID_CAMERA,
                           frame.view_shape, (s - sc, t - tc))
        local = xyz @ inverse[:3, :3].T + inverse[:3, 3]
        ratio = np.abs(local / half).max(axis=1)
        # float32 disparity: depth good to ~1e-6 m; every point on the box's surface
        assert np.abs(ratio - 1).max() < 1e-4, (s, t)
        wall = frame.labels[s, t] == 1
        z = RIGID_CAMERA.fb / (frame.disparity[s, t][wall] + RIGID_CAMERA.zero_disparity_offset)
        np.testing.assert_allclose(z, scene.background_z_m, rtol=1e-5)
    # the box's centre projects inside its label (a convex box covers its own centre)
    centre = pose[:3, 3]
    cx, cy = RIGID_CAMERA.principal_point(frame.view_shape)
    u = round(centre[1] / centre[2] * RIGID_CAMERA.focal_px + cy)
    v = round(centre[0] / centre[2] * RIGID_CAMERA.focal_px + cx)
    assert frame.labels[sc, tc, u, v] == box.label
    # and the projection of the visible box's surface points covers the labelled pixels
    points = box_surface_points(box.size_m, 0.002) @ pose[:3, :3].T + pose[:3, 3]
    pu = np.rint(points[:, 1] / points[:, 2] * RIGID_CAMERA.focal_px + cy).astype(int)
    pv = np.rint(points[:, 0] / points[:, 2] * RIGID_CAMERA.focal_px + cx).astype(int)
    covered = np.zeros(frame.view_shape, bool)
    covered[pu, pv] = True
    assert covered[frame.labels[sc, tc] == box.label].mean() > 0.97


def test_motion_is_as_promised():
    scene = rigid_scenes(frames=10, seed=3, boxes=3, texels=16)
    assert len(scene.boxes) == 3
    for box in scene.boxes:
        assert ((box.size_m >= 0.10) & (box.size_m <= 0.17)).all()
        assert 0.9 < box.poses[0][2, 3] < 1.1
        for a, b in zip(box.poses[:-1], box.poses[1:], strict=True):
            motion = b @ np.linalg.inv(a)
            angle = math.degrees(math.acos(np.clip((np.trace(motion[:3, :3]) - 1) / 2, -1, 1)))
            assert 2.0 - 1e-6 <= angle <= 4.0 + 1e-6
            shift = np.linalg.norm(b[:3, 3] - a[:3, 3])
            assert 0.004 - 1e-9 <= shift <= 0.012 + 1e-9
            np.testing.assert_allclose(b[:3, :3] @ b[:3, :3].T, np.eye(3), atol=1e-9)
    again = rigid_scenes(frames=10, seed=3, boxes=3, texels=16)
    np.testing.assert_array_equal(again.boxes[1].poses, scene.boxes[1].poses)


def test_cli_writes_a_video_every_command_reads(tmp_path, capsys):
    out = tmp_path / "boxes"
    assert main(["synth", str(out), "--rigid", "--frames", "2", "--grid", "3x3",
                 "--size", "120x160", "--objects", "1"]) == 0
    assert (out / "lfsam_video.json").is_file()
    described = json.loads((out / "frame_0001" / "lfsam_scene.json").read_text())
    assert described["camera"] == RIGID_CAMERA.to_json()
    (box,) = described["meta"]["rigid"]["objects"]
    assert np.asarray(box["pose"]).shape == (4, 4)
    direct = list(generate_rigid_video(boxes=1, frames=2, grid=(3, 3), size=(120, 160)))
    np.testing.assert_allclose(box["pose"], direct[1].meta["rigid"]["objects"][0]["pose"])
    assert main(["info", str(out)]) == 0
    assert "2 frames of 3 x 3 views of 120 x 160" in capsys.readouterr().out
    assert main(["synth", str(tmp_path / "x.npz"), "--rigid"]) == 2
