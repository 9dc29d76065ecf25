"""The data-set harness (lfsam.evaluate) and the `lfsam evaluate` command."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from lfsam.cli.main import main
from lfsam.errors import LfsamError
from lfsam.evaluate import compare_runs, evaluate_dataset, read_metrics_csv
from lfsam.io import write_lightfield
from lfsam.lightfield import LightField
from lfsam.metrics import evaluate_labels
from lfsam.result import SegmentationResult, load_result
from lfsam.synth import generate_scene

GRID = (3, 3)
SIZE = (48, 64)


@pytest.fixture(scope="module")
def scenes() -> list[LightField]:
    """Three small synthetic scenes with exact ground truth (made once per module)."""
    return [generate_scene(grid=GRID, size=SIZE, seed=seed) for seed in range(3)]


def oracle(lf: LightField) -> SegmentationResult:
    """Answers with the ground truth (ids changed: any ids will do), taking a known time."""
    return SegmentationResult(labels=lf.labels * 10, timings={"total": 0.45})


def one_view_relabelled(lf: LightField) -> SegmentationResult:
    """The ground truth with the top-left view's ids changed: inconsistent across views."""
    labels = lf.labels.copy()
    labels[0, 0][labels[0, 0] > 0] += 100
    return SegmentationResult(labels=labels, timings={"total": 0.9})


@pytest.fixture
def dataset(tmp_path: Path, scenes) -> Path:
    """The three scenes as .npz files in lfsam's format, plus a README that is not a scene."""
    root = tmp_path / "data"
    root.mkdir()
    for seed, lf in enumerate(scenes):
        write_lightfield(lf, root / f"scene{seed}.npz")
    (root / "README.md").write_text("three synthetic scenes\n")
    return root


class Counting:
    """A segment_fn that counts its calls."""

    def __init__(self, fn):
        self.fn, self.calls = fn, []

    def __call__(self, lf):
        self.calls.append(lf.meta["source"])
        return self.fn(lf)


def test_dataset_run_writes_csv_table_and_results(dataset, scenes, tmp_path):
    out = tmp_path / "run"
    fn = Counting(oracle)
    table = evaluate_dataset(dataset, out, fn, method_label="oracle")
    assert len(fn.calls) == 3
    assert [row.scene for row in table.rows] == ["scene0", "scene1", "scene2"]
    assert [name for name, _ in table.skipped] == ["README.md"]

    rows = read_metrics_csv(out / "metrics.csv")
    assert [r["scene"] for r in rows] == ["scene0", "scene1", "scene2", "mean"]
    assert {r["method"] for r in rows} == {"oracle"}
    for r, lf in zip(rows[:3], scenes, strict=True):
        direct = evaluate_labels(lf.labels, lf, device="cpu")
        masks = len(np.unique(lf.labels[lf.labels > 0]))
        # The ground truth itself: AA 1, UE 0, C 1 (the generator labels every pixel); SIoU and
        # LPP as the metrics give them directly; T = 1000 * 0.45 s / (N masks * 9 views).
        assert r["aa"] == pytest.approx(1.0) and r["ue"] == pytest.approx(0.0)
        assert r["coverage"] == pytest.approx(1.0)
        assert r["siou"] == pytest.approx(direct["siou"])
        assert r["lpp"] == pytest.approx(direct["lpp"])
        assert r["ms_per_mask_view"] == pytest.approx(450 / (masks * 9))
        assert r["num_masks"] == masks and r["error"] is None
        assert load_result(out / f"{r['scene']}.npz").labels.shape == (*GRID, *SIZE)
    mean = rows[3]
    for key in ("siou", "lpp", "aa", "ue", "coverage", "ms_per_mask_view"):
        assert mean[key] == pytest.approx(sum(r[key] for r in rows[:3]) / 3)
    assert 0.5 < mean["siou"] < 1.0 and mean["lpp"] > 1.0  # borders and occlusions: not ideal

    md = (out / "table.md").read_text()
    assert "| Method | SIoU↑ | LPP↓ | AA↑ | UE↓ | C↑ | T↓ |" in md
    means = f"{mean['siou']:.3f} | {mean['lpp']:.3f}"
    time = f"{mean['ms_per_mask_view']:.1f}"
    assert f"| oracle | {means} | 1.000 | 0.000 | 1.000 | {time} |" in md
    assert "README.md" in md


def test_rerun_skips_finished_scenes_unless_forced(dataset, tmp_path):
    out = tmp_path / "run"
    evaluate_dataset(dataset, out, oracle, method_label="oracle")
    first = (out / "metrics.csv").read_text()
    fn = Counting(oracle)
    table = evaluate_dataset(dataset, out, fn, method_label="oracle")
    assert fn.calls == [] and table.resumed == ["scene0", "scene1", "scene2"]
    assert (out / "metrics.csv").read_text() == first
    (out / "scene1.npz").unlink()  # a scene without its result is run again
    table = evaluate_dataset(dataset, out, fn, method_label="oracle")
    assert table.ran == ["scene1"] and len(fn.calls) == 1
    table = evaluate_dataset(dataset, out, fn, method_label="oracle", force=True)
    assert len(fn.calls) == 4 and table.ran == ["scene0", "scene1", "scene2"]


def test_failing_scenes_are_reported_and_the_rest_still_run(dataset, scenes, tmp_path):
    (dataset / "broken.npz").write_bytes(b"not a zip archive")  # readable format, bad content
    write_lightfield(LightField(scenes[0].views), dataset / "no_truth.npz")

    def flaky(lf):
        if Path(lf.meta["source"]).stem == "scene1":
            raise RuntimeError("segmenter crashed\nwith a second line")
        return oracle(lf)

    out = tmp_path / "run"
    fn = Counting(flaky)
    table = evaluate_dataset(dataset, out, fn, method_label="oracle")
    errors = {row.scene: row.error for row in table.rows}
    assert errors["scene0"] is None and errors["scene2"] is None
    assert "RuntimeError: segmenter crashed with a second line" == errors["scene1"]
    assert "cannot read" in errors["broken"]
    assert "no disparity" in errors["no_truth"]
    assert len(fn.calls) == 3  # the scene without ground truth is not segmented

    rows = {r["scene"]: r for r in read_metrics_csv(out / "metrics.csv")}
    assert rows["scene1"]["error"].startswith("RuntimeError") and rows["scene1"]["siou"] is None
    assert rows["mean"]["siou"] == pytest.approx(
        (rows["scene0"]["siou"] + rows["scene2"]["siou"]) / 2
    )
    md = (out / "table.md").read_text()
    assert "## Failed scenes" in md and "segmenter crashed" in md
    assert "2 scene(s); 3 failed" in md

    # A rerun retries only the failed scenes.
    fn2 = Counting(oracle)
    table = evaluate_dataset(dataset, out, fn2, method_label="oracle")
    assert sorted(table.resumed) == ["scene0", "scene2"]
    assert {Path(c).name for c in fn2.calls} == {"scene1.npz"}


def test_resuming_with_another_method_is_refused(dataset, tmp_path):
    out = tmp_path / "run"
    evaluate_dataset(dataset, out, oracle, method_label="oracle")
    with pytest.raises(LfsamError, match="holds results of method 'oracle'"):
        evaluate_dataset(dataset, out, oracle, method_label="other")
    table = evaluate_dataset(dataset, out, oracle, method_label="other", force=True)
    assert {row.method for row in table.rows} == {"other"}


def test_missing_total_time_is_measured(dataset, tmp_path):
    table = evaluate_dataset(
        dataset, tmp_path / "run", lambda lf: SegmentationResult(lf.labels), method_label="x"
    )
    for row in table.rows:
        # T = 1000 * seconds / (N masks * 9 views), seconds being the measured call time.
        expected = 1000 * row.seconds / (row.num_masks * 9)
        assert row.metrics["ms_per_mask_view"] == pytest.approx(expected)


def test_compare_marks_the_best_value_per_column(tmp_path):
    # Paper Table 1's numbers, written as two runs' mean rows: the bold cells must be the
    # paper's (baseline's C; ours everywhere else).
    paper = {
        "baseline": (0.765, 1.452, 0.970, 0.038, 0.329, 108.5),
        "ours": (0.768, 1.408, 0.973, 0.032, 0.309, 15.2),
    }
    dirs = []
    for name, values in paper.items():
        folder = tmp_path / name
        folder.mkdir()
        with open(folder / "metrics.csv", "w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(
                ["scene", "method", "siou", "lpp", "aa", "ue", "coverage", "ms_per_mask_view",
                 "num_masks", "seconds", "error"]
            )
            writer.writerow(["mean", name, *values, 100, 1.0, ""])
        dirs.append(folder)
    text = compare_runs(dirs)
    assert "| baseline | 0.765 | 1.452 | 0.970 | 0.038 | **0.329** | 108.5 |" in text
    assert "| ours | **0.768** | **1.408** | **0.973** | **0.032** | 0.309 | **15.2** |" in text
    with pytest.raises(LfsamError, match="not found"):
        compare_runs([tmp_path / "nowhere"])


def test_compare_runs_of_two_methods(dataset, tmp_path):
    evaluate_dataset(dataset, tmp_path / "a", oracle, method_label="oracle")
    evaluate_dataset(dataset, tmp_path / "b", one_view_relabelled, method_label="relabelled")
    text = compare_runs([tmp_path / "a", tmp_path / "b"])
    lines = {line.split(" | ")[0].strip("| "): line for line in text.splitlines()}
    oracle_cells = lines["oracle"].split(" | ")
    relabelled_cells = lines["relabelled"].split(" | ")
    assert oracle_cells[1].startswith("**")  # SIoU: consistent beats inconsistent
    assert oracle_cells[2].startswith("**")  # LPP
    assert not relabelled_cells[1].startswith("**")


def test_cli_evaluate_and_compare(dataset, tmp_path, monkeypatch, capsys):
    import lfsam.api

    seen = {}

    def fake_segment(lf, **kwargs):
        seen.update(kwargs)
        return oracle(lf)

    monkeypatch.setattr(lfsam.api, "segment", fake_segment)
    out = tmp_path / "cli"
    status = main(["evaluate", str(dataset), "--model", "oracle", "--disparity", "gt",
                   "--ablation", "ref", "--out", str(out)])
    assert status == 0
    options = seen["options"]
    assert options.run.method == "lfsam" and options.model.name == "oracle"
    assert seen["disparity"] == "gt" and options.pipeline.ablation == "ref"
    assert seen.get("prompts") is None  # automatic
    printed = capsys.readouterr()
    assert "| lfsam ref (oracle, gt disparity) |" in printed.out
    assert "3 scene(s) scored" in printed.err
    assert (out / "metrics.csv").is_file() and (out / "table.md").is_file()

    assert main(["evaluate", "--compare", str(out), str(out)]) == 0
    text = capsys.readouterr().out
    assert text.count("lfsam ref (oracle, gt disparity)") == 2

    assert main(["evaluate", str(dataset)]) == 2
    assert "needs DATASET_DIR and --out" in capsys.readouterr().err
    assert main(["evaluate", str(tmp_path / "missing"), "--out", str(out / "x")]) == 2
    assert "not a folder" in capsys.readouterr().err


def test_cli_evaluate_help_teaches(capsys):
    with pytest.raises(SystemExit):
        main(["evaluate", "--help"])
    text = capsys.readouterr().out
    assert "--compare" in text and "examples:" in text and "Table 2" in text


def test_nan_metrics_are_blank_in_csv(dataset, tmp_path):
    empty = evaluate_dataset(
        dataset, tmp_path / "e", lambda lf: SegmentationResult(np.zeros_like(lf.labels)),
        method_label="empty",
    )
    rows = read_metrics_csv(tmp_path / "e" / "metrics.csv")
    assert all(r["siou"] is None and r["aa"] is None for r in rows)
    assert all(r["coverage"] == 0.0 for r in rows)
    assert all(math.isclose(r["ue"], 0.0) for r in rows)
    assert empty.mean["siou"] is None
    assert "n/a" in (tmp_path / "e" / "table.md").read_text()
