"""Metrics of a light-field video over time (issue 25, docs/design.md section 10): best
matches, identity switches and the mean IoU over frames and views, on hand-made labels."""

from __future__ import annotations

import json

import numpy as np
import pytest

from lfsam.cli.main import main
from lfsam.metrics.temporal import evaluate_frames, frame_matches, identity_switches
from lfsam.result import SegmentationResult
from lfsam.video.result import video_result_writer

F, S, T, U, V = 3, 3, 3, 4, 8


def test_best_match_is_by_iou_over_all_views():
    gt = np.zeros((1, 2, 2, 4), np.int32)
    gt[0, 0] = [1, 1, 2, 2]
    gt[0, 1] = [1, 1, 1, 2]
    pred = np.zeros_like(gt)
    pred[0, 0] = [4, 4, 4, 4]  # 4 covers all of 1 in view 0 and half of 2
    pred[0, 1] = [9, 9, 9, 9]  # 9 covers all of 1 in view 1
    # object 1: IoU with 4 = 2/(5+4-2), with 9 = 3/(5+4-3): 9 wins; object 2: 4 wins (2/3)
    assert frame_matches(pred, gt) == {1: 9, 2: 4}
    assert frame_matches(np.zeros_like(gt), gt) == {1: None, 2: None}


def test_switches_skip_hidden_and_missed_frames():
    frames = [{1: 3, 2: 4}, {1: 3}, {1: 4, 2: None}, {2: 5, 1: 4}, {1: 3, 2: 5, 7: None}]
    assert identity_switches(frames) == {1: 2, 2: 1, 7: 0}
    assert identity_switches([]) == {}


def _video():
    gt = np.zeros((F, S, T, U, V), np.int32)
    gt[..., :4] = 1
    gt[..., 4:] = 2
    pred = np.zeros_like(gt)
    pred[0][gt[0] == 1], pred[0][gt[0] == 2] = 10, 20
    pred[1][gt[1] == 1], pred[1][gt[1] == 2] = 20, 10  # ids swapped: two switches
    pred[2][..., :2] = 20  # object 1 half found, object 2 missed
    return gt, pred


def _lightfield(labels):
    from lfsam.lightfield import LightField

    views = np.zeros((*labels.shape, 3), np.uint8)
    return LightField(views, disparity=np.zeros(labels.shape, np.float32), labels=labels)


def test_evaluate_frames_exact():
    gt, pred = _video()
    scores = evaluate_frames(
        ((SegmentationResult(labels=pred[f]), _lightfield(gt[f])) for f in range(F)),
        device="cpu")
    assert [row["matches"] for row in scores["frames"]] == [
        {"1": 10, "2": 20}, {"1": 20, "2": 10}, {"1": 20, "2": None}]
    assert [row["view_iou"] for row in scores["frames"]] == [1.0, 1.0, 0.5]
    summary = scores["summary"]
    assert summary["frames"] == F
    assert summary["identity_switches"] == 2 and summary["switches"] == {"1": 1, "2": 1}
    assert summary["mean_view_iou"] == pytest.approx(2.5 / 3)
    assert summary["view_iou_worst"] == 0.5
    assert summary["recall"] == pytest.approx((1 + 1 + 0.5) / 3)  # frame 2: 1 of 2 objects


def test_cli_metrics_of_a_video_result(tmp_path, capsys):
    gt, pred = _video()
    np.savez(tmp_path / "clip.npz", views=np.zeros((*gt.shape, 3), np.uint8), labels=gt,
             disparity=np.zeros(gt.shape, np.float32))
    with video_result_writer(tmp_path / "result") as writer:
        for f in range(F):
            writer.write(SegmentationResult(labels=pred[f]))
    assert main(["metrics", str(tmp_path / "result"), "--gt", str(tmp_path / "clip.npz"),
                 "--device", "cpu"]) == 0
    scores = json.loads(capsys.readouterr().out)
    assert [row["frame"] for row in scores["frames"]] == [0, 1, 2]
    assert scores["summary"]["identity_switches"] == 2
    assert scores["summary"]["mean_view_iou"] == pytest.approx(2.5 / 3)
    np.savez(tmp_path / "short.npz", views=np.zeros((2, S, T, U, V, 3), np.uint8),
             labels=gt[:2], disparity=np.zeros(gt[:2].shape, np.float32))
    assert main(["metrics", str(tmp_path / "result"), "--gt", str(tmp_path / "short.npz")]) != 0
    assert "is a video of (2, 3, 3, 4, 8)" in capsys.readouterr().err
