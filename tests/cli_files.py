"""Tiny inputs of every kind the commands take, for tests/test_cli_outputs.py and
tests/test_cli_inputs.py: a light field (a scene folder and an .npz), a result, a light-field
video (a folder of frames and an [F, S, T, U, V, 3] .npz), a video's result folder and a data
set folder."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from lfsam.io import write_lightfield
from lfsam.result import SegmentationResult, save_result
from lfsam.synth import generate_scene
from lfsam.video.io.result import video_result_writer
from lfsam.video.io.synth import generate_video, write_video_frames

GRID, SIZE = (3, 3), (24, 32)


def make_inputs(root: Path) -> dict[str, Path]:
    """Write one input of each kind under ``root``; their paths by name."""
    lf = generate_scene(grid=GRID, size=SIZE, num_objects=1, supersample=1)
    scene = write_lightfield(lf, root / "scene")
    scene_npz = write_lightfield(lf, root / "scene.npz")
    result = save_result(SegmentationResult(labels=lf.labels, meta={"input": str(scene)}),
                         root / "result.npz")
    frames = list(generate_video(grid=GRID, size=SIZE, frames=2, num_objects=1, supersample=1))
    clip = write_video_frames(iter(frames), root / "clip")
    video_npz = root / "video.npz"
    np.savez(video_npz, views=np.stack([f.views for f in frames]),
             disparity=np.stack([f.disparity for f in frames]),
             labels=np.stack([f.labels for f in frames]))
    with video_result_writer(root / "tracked", meta={"input": str(clip)}) as writer:
        for frame in frames:
            writer.write(SegmentationResult(labels=frame.labels))
    dataset = root / "dataset"
    dataset.mkdir()
    shutil.copytree(scene, dataset / "scene")
    return {"SCENE": scene, "SCENE_NPZ": scene_npz, "RESULT": result, "CLIP": clip,
            "VIDEO_NPZ": video_npz, "TRACKED": root / "tracked", "DATASET": dataset}
