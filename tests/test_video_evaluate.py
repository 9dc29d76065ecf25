"""`lfsam evaluate` on data sets of light-field videos (issue 25; docs/design.md section 10)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest

from lfsam.cli.main import main
from lfsam.evaluate import evaluate_dataset
from lfsam.video.evaluate import VideoTracking
from lfsam.video.io.result import is_video_result, load_video_result
from lfsam.video.io.synth import generate_video, write_video_frames
from lfsam.video.tracking.track import track_video

GRID, SIZE, FRAMES = (3, 3), (32, 48), 3


def _write(root: Path, name: str, seed: int) -> Path:
    frames = generate_video(grid=GRID, size=SIZE, frames=FRAMES, seed=seed, num_objects=2)
    return write_video_frames(frames, root / name)


@pytest.fixture(scope="module")
def clips(tmp_path_factory) -> Path:
    """Two tiny synthetic videos with exact ground truth, and a README that is no scene."""
    root = tmp_path_factory.mktemp("clips")
    _write(root, "clip_a", 0)
    _write(root, "clip_b", 1)
    (root / "README.md").write_text("two clips\n")
    return root


def _rows(out: Path) -> dict[str, dict[str, str]]:
    with open(out / "metrics.csv", newline="", encoding="utf-8") as handle:
        return {row["scene"]: row for row in csv.DictReader(handle)}


def test_cli_evaluates_videos_like_lfsam_metrics(clips, tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["evaluate", str(clips), "--model", "oracle", "--disparity", "gt",
                 "--out", str(out)])
    assert code == 0
    rows = _rows(out)
    assert set(rows) == {"clip_a", "clip_b", "mean"}
    for name in ("clip_a", "clip_b"):
        row = rows[name]
        assert row["error"] == ""
        assert int(float(row["frames"])) == FRAMES
        assert int(float(row["identity_switches"])) == 0
        assert float(row["view_iou"]) >= 0.9
        assert is_video_result(out / name)
        result = load_video_result(out / name)
        assert result.meta["tracking"] == "constrained-prompts"
        # the same scores as `lfsam metrics` prints for that folder
        capsys.readouterr()
        assert main(["metrics", str(out / name), "--gt", str(clips / name)]) == 0
        summary = json.loads(capsys.readouterr().out)["summary"]
        assert math.isclose(float(row["view_iou"]), summary["mean_view_iou"], rel_tol=1e-9)
        assert math.isclose(float(row["siou"]), summary["siou"], rel_tol=1e-9)
        assert float(row["view_iou_worst"]) == pytest.approx(summary["view_iou_worst"])
    assert int(float(rows["mean"]["frames"])) == 2 * FRAMES  # totals in the mean row
    assert int(float(rows["mean"]["identity_switches"])) == 0
    table = (out / "table.md").read_text()
    assert "IDsw" in table and "clip_a" in table and "README.md" in table  # skipped with a note


def test_rerun_skips_finished_videos_and_a_broken_one_is_a_row(clips, tmp_path):
    calls = []

    def track(video, folder):
        calls.append(folder.name)
        return track_video(video, None, folder, model="oracle", disparity="gt")

    out = tmp_path / "run"
    videos = VideoTracking(track, "oracle video")
    evaluate_dataset(clips, out, _never, method_label="oracle video", videos=videos)
    assert sorted(calls) == ["clip_a", "clip_b"]
    calls.clear()
    evaluate_dataset(clips, out, _never, method_label="oracle video", videos=videos)
    assert calls == []  # both resumed
    # a video whose last frame is cut off: an error row, the others still scored
    broken = tmp_path / "broken"
    broken.mkdir()
    _write(broken, "clip_ok", 2)
    _write(broken, "clip_bad", 3)
    for part in sorted((broken / "clip_bad" / "frame_0002").iterdir()):
        part.write_bytes(b"not an image")
    table = evaluate_dataset(broken, tmp_path / "run2", _never, method_label="oracle video",
                             videos=videos)
    errors = {row.scene: row.error for row in table.rows}
    assert errors["clip_ok"] is None
    assert errors["clip_bad"]
    assert "\n" not in errors["clip_bad"]
    assert not (tmp_path / "run2" / "clip_bad").exists()  # no partial result folder


def _never(lightfield):
    raise AssertionError("a video must not reach the single light field's method")


def test_without_video_tracking_a_video_is_skipped(clips, tmp_path):
    table = evaluate_dataset(clips, tmp_path / "run", _never, method_label="x")
    assert table.rows == []
    assert {name for name, _ in table.skipped} >= {"clip_a", "clip_b"}


@pytest.mark.parametrize("mode, expected", [("prompts", "constrained-prompts"),
                                            ("auto", "constrained-prompts")])
def test_tracking_switch_reaches_track_video(clips, tmp_path, monkeypatch, mode, expected):
    seen = []
    real = track_video

    def spy(*args, **kwargs):
        seen.append(kwargs.get("memory"))
        return real(*args, **kwargs)

    monkeypatch.setattr("lfsam.video.tracking.track.track_video", spy)
    out = tmp_path / "run"
    assert main(["evaluate", str(clips), "--model", "oracle", "--disparity", "gt",
                 "--tracking", mode, "--out", str(out)]) == 0
    assert seen == [{"prompts": False, "auto": None}[mode]] * 2
    assert load_video_result(out / "clip_a").meta["tracking"] == expected


def test_tracking_memory_with_the_oracle_is_one_line(clips, tmp_path, capsys):
    code = main(["evaluate", str(clips), "--model", "oracle", "--tracking", "memory",
                 "--out", str(tmp_path / "run")])
    assert code != 0
    err = capsys.readouterr().err.strip()
    assert "--tracking memory" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "run").exists()


def test_segment_tracking_switch(clips, tmp_path, capsys):
    out = tmp_path / "tracked"
    assert main(["segment", str(clips / "clip_a"), "--auto", "--model", "oracle",
                 "--disparity", "gt", "--tracking", "prompts", "--out", str(out), "--quiet"]) == 0
    assert load_video_result(out).meta["tracking"] == "constrained-prompts"
    code = main(["segment", str(clips / "clip_a"), "--auto", "--model", "oracle",
                 "--tracking", "memory", "--out", str(tmp_path / "m")])
    assert code != 0
    assert "video memory" in capsys.readouterr().err
    capsys.readouterr()
    code = main(["segment", str(clips / "clip_a" / "frame_0000"), "--auto", "--model", "oracle",
                 "--tracking", "prompts", "--out", str(tmp_path / "x.npz")])
    assert code != 0
    assert "applies to light-field videos" in capsys.readouterr().err
    assert not (tmp_path / "x.npz").exists()


def test_a_scoring_failure_leaves_no_result_folder(clips, tmp_path, monkeypatch):
    import lfsam.video.evaluate as video_evaluate

    def broken_scores(pairs, device=None):
        raise ValueError("scores went wrong")

    monkeypatch.setattr(video_evaluate, "evaluate_frames", broken_scores)
    videos = VideoTracking(
        lambda video, folder: track_video(video, None, folder, model="oracle", disparity="gt"),
        "oracle video",
    )
    row = videos.run("clip_a", clips / "clip_a", tmp_path / "clip_a")
    assert row.error == "ValueError: scores went wrong"
    assert not (tmp_path / "clip_a").exists()  # a resumed run tracks it again
