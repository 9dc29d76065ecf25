"""``lfsam segment FOLDER --follow --poses`` (docs/design.md section 12): each frame's poses
written as it arrives, checked against the rigid-box ground truth."""

from __future__ import annotations

import json
import shutil

import numpy as np

import lfsam
from lfsam.cli.main import main
from lfsam.metrics.pose import add_error
from lfsam.spatial.registration import transform
from lfsam.synth.rigid import box_surface_points, generate_rigid_video
from lfsam.video.io.synth import write_video_frames


def test_follow_writes_poses_frame_by_frame(tmp_path, capsys):
    clip = write_video_frames(
        generate_rigid_video(boxes=1, frames=3, grid=(5, 5), size=(120, 160), seed=4,
                             box_size_m=(0.08, 0.1), texels=64, supersample=1),
        tmp_path / "clip")
    folder, out = tmp_path / "in", tmp_path / "out"
    folder.mkdir()
    for frame in sorted(clip.glob("frame_*")):
        shutil.copytree(frame, folder / frame.name)
    code = main(["segment", str(folder), "--follow", "--follow-timeout", "0.5", "--auto",
                 "--model", "oracle", "--disparity", "gt", "--out", str(out), "--poll", "0.02",
                 "--poses"])
    assert code == 0
    err = capsys.readouterr().err
    assert len([x for x in err.splitlines() if "poses of" in x]) == 3
    assert len(lfsam.load_result(out)) == 3  # the extra file leaves the result readable
    document = json.loads((out / "poses.json").read_text())
    assert document["frames"] == 3
    truth = [json.loads((clip / f"frame_{k:04d}" / "lfsam_scene.json").read_text())
             ["meta"]["rigid"]["objects"][0] for k in range(3)]
    pose0, size = np.asarray(truth[0]["pose"]), np.asarray(truth[0]["size_m"])
    model = transform(pose0, box_surface_points(size))
    (box,) = [o for o in document["objects"]
              if (np.abs(transform(np.linalg.inv(pose0),
                                   np.asarray(o["first_pose"])[None, :3, 3])) <= size / 2).all()]
    assert [f["frame"] for f in box["frames"]] == [0, 1, 2]
    for entry, true in zip(box["frames"], truth, strict=True):
        motion = np.asarray(true["pose"]) @ np.linalg.inv(pose0)
        assert add_error(model, np.asarray(entry["motion"]), motion) < 0.02 * np.linalg.norm(size)


def test_poses_and_camera_need_follow(tmp_path, capsys):
    assert main(["segment", str(tmp_path), "--poses", "--auto", "--model", "oracle",
                 "--out", str(tmp_path / "r.npz")]) == 2
    assert "--follow" in capsys.readouterr().err
    assert main(["segment", str(tmp_path), "--follow", "--camera", str(tmp_path / "c.json"),
                 "--auto", "--model", "oracle", "--out", str(tmp_path / "o")]) == 2
    assert "--poses" in capsys.readouterr().err
