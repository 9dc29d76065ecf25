"""Live light-field video (issue 35, docs/design.md section 10): online tracking one frame at a
time, a growing frames folder followed with ``lfsam segment FOLDER --follow``, the live result
folder, and one encoder pass per refined view per frame."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import torch

import lfsam
from hidden_status import check_hidden_lines
from lfsam.api import RunOptions, SegmentOptions
from lfsam.baseline.predictor import video_predictor_for
from lfsam.cli.main import main
from lfsam.errors import LfsamError
from lfsam.pipeline import PipelineConfig
from lfsam.prompts import ObjectPrompts, PointPrompt
from lfsam.segmenters import load_segmenter
from lfsam.video import read_video
from lfsam.video.io.live_result import live_video_result_writer
from lfsam.video.io.result import (
    RESULT_MARKER,
    hidden_spans,
    load_video_result,
)
from lfsam.video.io.synth import generate_video, write_video_frames
from lfsam.video.stream.follow import FrameFollower
from lfsam.video.stream.live import segment_stream
from lfsam.video.tracking.online import OnlineTracker
from lfsam.video.tracking.track import track_video
from stream_files import land_frame

QUIET = SegmentOptions(run=RunOptions(progress=False))
#: The ground-truth label of the object clicked (label 1 is the backdrop).
OBJECT = 3


@pytest.fixture(scope="module")
def clip(tmp_path_factory) -> Path:
    """5 frames of 3x3 views of 48x64, 3 objects moving (ground truth kept)."""
    folder = tmp_path_factory.mktemp("follow") / "clip"
    write_video_frames(generate_video(grid=(3, 3), size=(48, 64), frames=5, seed=0,
                                      num_objects=3), folder)
    return folder


def _click(lf, label: int, frame: int | None = None) -> PointPrompt:
    """A positive click at the deepest pixel of ``label`` in the center view."""
    from scipy import ndimage

    depth = ndimage.distance_transform_edt(lf.labels[lf.center] == label)
    row, col = np.unravel_index(int(np.argmax(depth)), depth.shape)
    return PointPrompt(float(col), float(row), True, None, frame)



def _wait_for(check, seconds: float = 60.0) -> None:
    deadline = time.monotonic() + seconds
    while not check():
        if time.monotonic() > deadline:
            raise AssertionError("timed out waiting")
        time.sleep(0.02)


def _frames_in(out: Path) -> int:
    try:
        return len(load_video_result(out))
    except LfsamError:
        return 0


# --- the Python API ------------------------------------------------------------------------
def test_online_tracker_equals_track_video_and_takes_prompts_at_later_frames(clip, tmp_path):
    video = read_video(clip)
    first = video.frame(0)
    objects = [ObjectPrompts(1, (_click(first, OBJECT),)),
               ObjectPrompts(2, (_click(video.frame(2), 6, frame=2),))]
    tracked = track_video(video, objects, tmp_path / "t", model="oracle", disparity="gt",
                          options=QUIET)
    tracker = OnlineTracker("oracle", disparity="gt", options=QUIET)
    tracker.add_prompts(objects[:1])
    for index in range(len(video)):
        if index == 2:  # the second object's click arrives with frame 2, not up front
            tracker.add_prompts([ObjectPrompts(2, (_click(video.frame(2), 6),))], frame=2)
        result = tracker.track(video.frame(index))
        assert result.meta["frame"] == index
        np.testing.assert_array_equal(result.labels, tracked.labels[index])
    assert (tracked.labels[1] == 2).sum() == 0 and (tracked.labels[2] == 2).any()
    assert tracker.frames_done == len(video) and tracker.object_ids == [1, 2]
    assert [o.obj_id for o in tracker.prompts] == [1, 2]
    with pytest.raises(LfsamError, match="frame 1 is tracked already"):
        tracker.add_prompts([ObjectPrompts(3, (PointPrompt(5, 5, True, None, 1),))])
    with pytest.raises(LfsamError, match="lies outside the view"):
        tracker.add_prompts([ObjectPrompts(3, (PointPrompt(500, 5),))], frame=9)


def test_a_frame_of_another_size_is_refused_and_the_stream_goes_on(clip):
    video = read_video(clip)
    tracker = OnlineTracker("oracle", disparity="gt", options=QUIET)
    tracker.add_prompts([ObjectPrompts(1, (_click(video.frame(0), OBJECT),))])
    tracker.track(video.frame(0))
    other = next(iter(generate_video(grid=(3, 3), size=(32, 40), frames=1, seed=3)))
    with pytest.raises(LfsamError, match="every frame needs the same grid"):
        tracker.track(other)
    assert tracker.frames_done == 1
    assert (tracker.track(video.frame(1)).labels == 1).any()


def test_memory_shares_the_center_encoding_one_encoder_pass_per_refined_view(clip):
    """SAM 2's memory and the pipeline share each frame's center view: with --refine-views 1
    the image encoder runs once per frame; memory stays within SAM 2's window."""
    segmenter = load_segmenter("sam2-tiny-test", random_weights=True, device="cpu",
                               keep_decoder_state=False)
    predictor = video_predictor_for(segmenter)
    head = predictor.sam_mask_decoder.pred_obj_score_head
    last = head.layers[-1] if hasattr(head, "layers") else head
    passes = []
    hooks = [model.image_encoder.register_forward_hook(lambda *_: passes.append(1))
             for model in (segmenter.model, predictor)]  # two modules, the same weights
    video = read_video(clip)
    options = SegmentOptions(pipeline=PipelineConfig(refine_views=1),
                             run=RunOptions(progress=False))
    with torch.no_grad():
        last.bias += 50.0  # random weights score every object absent; see test_video_memory
    try:
        tracker = OnlineTracker(segmenter, disparity="gt", options=options)
        tracker.add_prompts([ObjectPrompts(1, (_click(video.frame(0), OBJECT),))])
        for index in range(len(video)):
            before = len(passes)
            labels = tracker.track(video.frame(index)).labels
            assert len(passes) - before == 1, f"frame {index}: {len(passes) - before} passes"
            assert (labels == 1).any()
        assert tracker.tracking == "sam2-memory"
        memory = tracker._memory
        kept = memory.state["output_dict_per_obj"][0]["non_cond_frame_outputs"]
        assert all(memory.frame - memory.window <= f for f in kept)
    finally:
        for hook in hooks:
            hook.remove()
        with torch.no_grad():
            last.bias -= 50.0


# --- the live result folder ----------------------------------------------------------------
def test_live_writer_publishes_each_frame_and_leaves_nothing_without_frames(tmp_path):
    labels = np.zeros((1, 1, 4, 5), np.int32)
    out = tmp_path / "live"
    with live_video_result_writer(out, meta={"x": 1}) as writer:
        assert not (out / RESULT_MARKER).exists()
        for f in range(3):
            writer.write(lfsam.SegmentationResult(labels=labels + f))
            writer.flush()  # the files are written behind (issue 44)
            seen = lfsam.load_result(out)
            assert len(seen) == f + 1 and not seen.complete and int(seen.labels[f].max()) == f
    final = lfsam.load_result(out)
    assert final.complete and len(final) == 3 and final.meta["x"] == 1
    with pytest.raises(LfsamError, match="not empty"):
        with live_video_result_writer(out):
            pass
    with live_video_result_writer(tmp_path / "none"):
        pass
    assert not (tmp_path / "none").exists()


def test_follower_order_end_and_stop(tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    for name in ("f_10.npz", "f_2.npz", ".f_3.npz", "f_3.npz.part"):
        (folder / name).write_bytes(b"")
    (folder / "END").write_bytes(b"")
    follower = FrameFollower(folder, poll=0.01)
    assert [f.path.name for f in follower] == ["f_2.npz", "f_10.npz"]
    assert follower.ended_by == "END"
    (folder / "END").unlink()
    follower = FrameFollower(folder, timeout=0.2, poll=0.01)
    assert len(list(follower)) == 2 and follower.ended_by == "timeout"
    follower = FrameFollower(folder, poll=0.01)
    threading.Timer(0.1, follower.stop).start()
    assert [f.path.name for f in follower] == ["f_2.npz", "f_10.npz"]
    assert follower.ended_by == "stopped"
    with pytest.raises(LfsamError, match="does not exist"):
        FrameFollower(tmp_path / "missing")


def test_ctrl_c_mid_frame_keeps_the_frames_done(clip, tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    for source in sorted(clip.glob("frame_*"))[:3]:
        land_frame(source, folder)
    tracker = OnlineTracker("oracle", disparity="gt", options=QUIET)
    tracker.add_prompts([ObjectPrompts(1, (_click(read_video(clip).frame(0), OBJECT),))])
    real = tracker.track

    def interrupted(lf):
        if tracker.frames_done == 2:
            raise KeyboardInterrupt
        return real(lf)

    tracker.track = interrupted
    report = segment_stream(FrameFollower(folder, poll=0.01), tracker, tmp_path / "out")
    assert report.ended_by == "interrupted" and report.frames == 2
    result = lfsam.load_result(tmp_path / "out")
    assert result.complete and len(result) == 2 and result.meta["ended_by"] == "interrupted"
    assert all((labels == 1).any() for labels in result.labels)


# --- the command line ----------------------------------------------------------------------
def _follow_command(folder: Path, out: Path, click: PointPrompt) -> list[str]:
    return [sys.executable, "-m", "lfsam.cli.main", "segment", str(folder), "--follow",
            "--point", f"{click.x:g},{click.y:g}", "--model", "oracle", "--disparity", "gt",
            "--out", str(out), "--poll", "0.02"]


def test_follow_segments_frames_as_they_land_and_ends_at_END(clip, tmp_path):
    folder, out = tmp_path / "in", tmp_path / "out"
    folder.mkdir()
    lf0 = read_video(clip).frame(0)
    click = _click(lf0, OBJECT)
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    command = _follow_command(folder, out, click)
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env)
    try:
        frames = sorted(clip.glob("frame_*"))
        seen_live = []
        for index, source in enumerate(frames):
            land_frame(source, folder)
            # this frame's result is in the folder before the next frame exists
            _wait_for(lambda i=index: _frames_in(out) == i + 1 or proc.poll() is not None)
            seen_live.append(lfsam.load_result(out).complete)
        (folder / "END").write_bytes(b"")
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 0, stderr
    assert not any(seen_live)  # readable, not yet complete, while the run went on
    result = lfsam.load_result(out)
    assert result.complete and len(result) == len(frames)
    assert result.meta["ended_by"] == "END" and result.meta["follow"] is True
    for f in range(len(result)):
        truth = read_video(clip).frame(f).labels
        iou = ((result.labels[f] == 1) & (truth == OBJECT)).sum() / (
            (result.labels[f] == 1) | (truth == OBJECT)).sum()
        assert iou > 0.8, (f, iou)  # the object keeps its id in every frame
    lines = [line for line in stderr.splitlines() if line.startswith("frame ")]
    assert len(lines) == len(frames) and all("from arrival to result" in x for x in lines)
    summary = json.loads(stdout.strip().splitlines()[-1])
    assert summary["frames"] == len(frames) and summary["latency_worst_s"] is not None
    assert summary["hidden"] == hidden_spans(result.meta["tracks"]) == {}  # never lost
    assert result.stored_prompts()[0].points[0].x == click.x


def test_follow_timeout_and_a_corrupt_frame(clip, tmp_path, capsys):
    folder, out = tmp_path / "in", tmp_path / "out"
    folder.mkdir()
    frames = sorted(clip.glob("frame_*"))
    land_frame(frames[0], folder)
    (folder / "frame_0001.npz").write_bytes(b"not a light field")
    land_frame(frames[2], folder)
    click = _click(read_video(clip).frame(0), OBJECT)
    code = main(["segment", str(folder), "--follow", "--follow-timeout", "0.5", "--point",
                 f"{click.x:g},{click.y:g}", "--model", "oracle", "--disparity", "gt",
                 "--out", str(out), "--poll", "0.02"])
    assert code == 0
    err = capsys.readouterr().err
    assert len([x for x in err.splitlines() if "frame_0001.npz skipped" in x]) == 1
    result = lfsam.load_result(out)
    assert len(result) == 2 and result.meta["ended_by"] == "timeout"
    assert [s["name"] for s in result.meta["skipped"]] == ["frame_0001.npz"]
    assert [result.frame(f).meta["frame_source"] for f in range(2)] == [
        "frame_0000", "frame_0002"]
    assert all((labels == 1).any() for labels in result.labels)


def test_follow_lines_name_the_objects_searched_for(clip, tmp_path, capsys):
    """Issue 47: each frame's line names the objects not found there (searched for, under
    their ids, since the first frame of their run of hidden frames) and the end line their
    hidden frames, as the result's states (``meta["tracks"]``) say; in this clip the first
    object leaves the frame in frame 2 (the ground truth), so one is hidden there."""
    folder, out = tmp_path / "in", tmp_path / "out"
    folder.mkdir()
    frames = sorted(clip.glob("frame_*"))
    for frame in frames:
        land_frame(frame, folder)
    (folder / "END").write_text("")
    assert main(["segment", str(folder), "--follow", "--auto", "--model", "oracle",
                 "--disparity", "gt", "--out", str(out), "--poll", "0.02"]) == 0
    err = capsys.readouterr().err.splitlines()
    video = read_video(clip)
    assert not (video.frame(2).labels == 2).any()
    tracks = lfsam.load_result(out).meta["tracks"]
    hidden = check_hidden_lines(err, [f.name for f in frames], tracks, "stream ended")
    assert hidden[2]


def test_follow_refuses_bad_places_before_work(tmp_path, capsys):
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("")
    (tmp_path / "in").mkdir()
    cases = [
        (["segment", str(tmp_path / "nowhere"), "--follow", "--auto", "--out",
          str(tmp_path / "o")], "does not exist"),
        (["segment", str(tmp_path / "in"), "--follow", "--auto", "--out",
          str(tmp_path / "full")], "not empty"),
        (["segment", str(tmp_path / "in"), "--follow-timeout", "3", "--auto", "--out",
          str(tmp_path / "o")], "--follow-timeout goes with --follow"),
    ]
    for argv, message in cases:
        assert main(argv) != 0
        assert message in capsys.readouterr().err


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT to a child process")
def test_follow_ctrl_c_exits_130_with_a_valid_folder(clip, tmp_path):
    folder, out = tmp_path / "in", tmp_path / "out"
    folder.mkdir()
    frames = sorted(clip.glob("frame_*"))
    click = _click(read_video(clip).frame(0), OBJECT)
    # Ctrl-C as a terminal gives it: the child starts with SIGINT not ignored, whatever this
    # test process inherited (an ignored SIGINT passes across exec, a handler does not; a
    # child that ignores it rightly follows on, as a background job should)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        proc = subprocess.Popen(_follow_command(folder, out, click), stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True,
                                env={**os.environ, "OMP_NUM_THREADS": "1"})
    finally:
        signal.signal(signal.SIGINT, previous)
    try:
        land_frame(frames[0], folder)
        _wait_for(lambda: _frames_in(out) == 1 or proc.poll() is not None)
        land_frame(frames[1], folder)
        time.sleep(0.03)  # the second frame is (most likely) being segmented
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 130, stderr
    assert "Ctrl-C" in stderr
    result = lfsam.load_result(out)
    assert result.complete and len(result) in (1, 2)
    assert result.meta["ended_by"] == "interrupted"
    for labels in result.labels:  # every listed frame is there and readable
        assert labels.shape == (3, 3, 48, 64)


# --- frame faults and configuration faults (issue 46) ---------------------------------------
def _frames_without_labels(folder: Path, frames: int, keep_first: bool = False) -> None:
    """Frames as a camera writes them (no ground-truth labels), optionally the first with."""
    from dataclasses import replace as _replace

    from lfsam.io import write_lightfield

    folder.mkdir()
    for index, lf in enumerate(generate_video(grid=(3, 3), size=(48, 64), frames=frames,
                                              seed=0, num_objects=3)):
        bare = _replace(lf, labels=None, categories=None)
        write_lightfield(lf if keep_first and index == 0 else bare, folder / f"frame_{index:04d}")


def test_follow_with_the_oracle_on_frames_without_labels_stops_in_one_line(tmp_path):
    """A configuration fault (the oracle needs labels the frames lack) fails every frame the
    same way: exit 2 with one line at the first frame, not one line per frame and exit 0."""
    folder, out = tmp_path / "in", tmp_path / "out"
    _frames_without_labels(folder, 3)
    (folder / "END").write_bytes(b"")
    start = time.monotonic()
    proc = subprocess.run(
        [sys.executable, "-m", "lfsam.cli.main", "segment", str(folder), "--follow",
         "--model", "oracle", "--auto", "--out", str(out)],
        capture_output=True, text=True, timeout=120,
        env={**os.environ, "OMP_NUM_THREADS": "1"})
    seconds = time.monotonic() - start
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and lines[0].startswith("lfsam: error:"), proc.stderr
    assert "frame_0000" in lines[0] and "nothing was written" in lines[0]
    assert "skipped" not in proc.stderr
    assert not out.exists()
    assert seconds < 20


def test_a_configuration_fault_after_some_frames_keeps_them_in_a_valid_folder(tmp_path,
                                                                              capsys):
    folder, out = tmp_path / "in", tmp_path / "out"
    _frames_without_labels(folder, 3, keep_first=True)
    (folder / "END").write_bytes(b"")
    code = main(["segment", str(folder), "--follow", "--model", "oracle", "--auto",
                 "--disparity", "gt", "--out", str(out), "--poll", "0.02"])
    err = capsys.readouterr().err
    assert code == 2
    errors = [x for x in err.splitlines() if x.startswith("lfsam: error:")]
    assert len(errors) == 1 and "frame_0001" in errors[0] and "1 frame(s) done" in errors[0]
    assert "skipped" not in err
    result = lfsam.load_result(out)
    assert result.complete and len(result) == 1
    assert result.meta["ended_by"] == "error" and "labels" in result.meta["error"]
    assert (result.labels[0] > 0).any()


def test_follow_with_text_finds_the_phrase_in_the_first_frame_and_tracks_it(clip, tmp_path,
                                                                            capsys):
    """--text with --follow (issue 46): the oracle answers "tile" from the first frame's
    ground-truth categories; the object keeps its id through every later frame."""
    folder, out = tmp_path / "in", tmp_path / "out"
    folder.mkdir()
    frames = sorted(clip.glob("frame_*"))
    for source in frames:
        land_frame(source, folder)
    (folder / "END").write_bytes(b"")
    code = main(["segment", str(folder), "--follow", "--text", "tile", "--model", "oracle",
                 "--disparity", "gt", "--out", str(out), "--poll", "0.02"])
    assert code == 0, capsys.readouterr().err
    result = lfsam.load_result(out)
    assert len(result) == len(frames) and result.meta["prompt_mode"] == "text"
    [find] = result.meta["text"]
    assert find["phrase"] == "tile" and find["found"] == 1
    [obj_id] = find["ids"]
    video = read_video(clip)
    for f in range(len(result)):
        truth = video.frame(f).labels == OBJECT  # label 3 is the "noise tile"
        mine = result.labels[f] == obj_id
        assert (mine & truth).sum() / (mine | truth).sum() > 0.8, f
    assert "text" in result.frame(0).meta and "text" not in result.frame(1).meta
    capsys.readouterr()
    assert main(["segment", str(folder), "--follow", "--text", "tile", "--point", "3,3",
                 "--out", str(tmp_path / "o2")]) == 2  # --text with clicks: one line
    assert "not both" in capsys.readouterr().err
