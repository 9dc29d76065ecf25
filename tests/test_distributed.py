"""`lfsam evaluate --ray`: light fields as Ray tasks give the sequential run's output folder.

One local Ray cluster (2 CPUs) serves the whole module: starting Ray is the slow part. The scenes
are small synthetic light fields segmented by the oracle with ground-truth disparity (fast).
Result files cannot be byte-identical between two runs (each result holds the run's wall-clock
timings, and an .npz zip entry its write time), so the comparison is over every array of each
result (labels, packed masks, scores, ...) exactly, the metadata exactly, the timing dictionary's
keys, and every metric except the timing one (T, ``ms_per_mask_view``, and ``seconds``). A video's
result folder (issue 38) is compared file by file the same way.
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np
import pytest
import ray

from lfsam.cli.main import main
from lfsam.distributed import ray_mapper, task_resources
from lfsam.errors import LfsamError
from lfsam.io import write_lightfield
from lfsam.synth import generate_scene
from lfsam.video.io.synth import generate_video, write_video_frames

TIMING_FIELDS = {"seconds", "ms_per_mask_view"}


@pytest.fixture(scope="module")
def local_ray():
    """A local 2-CPU Ray cluster for the module (the code under test reuses the connection)."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    """Three small synthetic scenes and a file that is not a light field."""
    root = tmp_path_factory.mktemp("data")
    for seed in range(3):
        lf = generate_scene(grid=(3, 3), size=(32, 48), seed=seed, num_objects=3)
        write_lightfield(lf, root / f"scene{seed}.npz")
    (root / "README.md").write_text("not a scene\n")
    return root


@pytest.fixture(scope="module")
def mixed(tmp_path_factory) -> Path:
    """Two tiny light-field videos (3 frames of 3x3 views of 32x48) and one light field."""
    root = tmp_path_factory.mktemp("mixed")
    for seed, name in enumerate(("clip_a", "clip_b")):
        frames = generate_video(grid=(3, 3), size=(32, 48), frames=3, seed=seed, num_objects=2)
        write_video_frames(frames, root / name)
    write_lightfield(generate_scene(grid=(3, 3), size=(32, 48), seed=5, num_objects=3),
                     root / "scene.npz")
    return root


def _evaluate(dataset: Path, out: Path, *extra: str) -> int:
    return main(["evaluate", str(dataset), "--model", "oracle", "--disparity", "gt",
                 "--device", "cpu", "--out", str(out), *extra])


def _contents(out: Path, prefix: str = "") -> dict[str, object]:
    """Everything in an output folder except the timings (see the module docstring)."""
    found: dict[str, object] = {}
    for path in sorted(out.iterdir()):
        if path.is_dir():  # a video's result folder
            found[prefix + path.name + "/"] = oct(path.stat().st_mode & 0o777)
            found.update(_contents(path, f"{prefix}{path.name}/"))
        elif path.suffix == ".npz":
            with np.load(path) as npz:
                for key in npz.files:
                    value = npz[key]
                    if key == "timings":
                        value = sorted(json.loads(str(value)))
                    elif key == "meta":
                        value = json.loads(str(value))
                    found[f"{prefix}{path.name}:{key}"] = value
        elif path.name.endswith(".metrics.json"):
            record = json.loads(path.read_text())
            found[prefix + path.name] = {
                k: v for k, v in record.items() if k not in TIMING_FIELDS}
        elif path.suffix == ".json":  # a video result's manifest
            found[prefix + path.name] = json.loads(path.read_text())
        elif path.name == "metrics.csv":
            with open(path, newline="") as handle:
                rows = list(csv.DictReader(handle))
            found[prefix + path.name] = [
                {k: v for k, v in row.items() if k not in TIMING_FIELDS} for row in rows
            ]
        else:
            found[prefix + path.name] = _without_t_column(path.read_text())
    return found


def _without_t_column(markdown: str) -> list[str]:
    """The lines of a table.md with the cells of each table's T column (a timing) removed."""
    lines, t_index = [], None
    for line in markdown.splitlines():
        if not line.startswith("|"):
            t_index = None
            lines.append(line)
            continue
        cells = line.split("|")
        if t_index is None:  # a table's header row
            t_index = next((i for i, c in enumerate(cells) if c.strip().startswith("T")), -1)
        if t_index >= 0:
            del cells[t_index]
        lines.append("|".join(cells))
    return lines


def _assert_same(a: dict[str, object], b: dict[str, object]) -> None:
    assert sorted(a) == sorted(b)
    for key in a:
        if isinstance(a[key], np.ndarray):
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)
        else:
            assert a[key] == b[key], key


def test_ray_run_writes_the_sequential_results(local_ray, dataset, tmp_path, capsys):
    assert _evaluate(dataset, tmp_path / "seq") == 0
    assert _evaluate(dataset, tmp_path / "ray", "--ray") == 0
    seq, dist = _contents(tmp_path / "seq"), _contents(tmp_path / "ray")
    assert {f"scene{i}.npz:labels" for i in range(3)} <= set(seq)
    _assert_same(seq, dist)
    # Every scene was segmented and scored (the oracle's scores).
    rows = seq["metrics.csv"]
    assert [row["scene"] for row in rows] == ["scene0", "scene1", "scene2", "mean"]
    assert all(row["error"] == "" and float(row["siou"]) > 0.5 for row in rows)

    # Resumable the same way: a second run does nothing, a lost record reruns only its scene.
    record = tmp_path / "ray" / "scene1.metrics.json"
    record.unlink()
    capsys.readouterr()
    assert _evaluate(dataset, tmp_path / "ray", "--ray") == 0
    assert "(1 run now, 2 resumed)" in capsys.readouterr().err
    _assert_same(seq, _contents(tmp_path / "ray"))


def test_ray_run_of_videos_writes_the_sequential_results(local_ray, mixed, tmp_path, capsys):
    """Videos and a light field in one data set: each a Ray task, the sequential folder."""
    assert _evaluate(mixed, tmp_path / "seq") == 0
    assert _evaluate(mixed, tmp_path / "ray", "--ray") == 0
    seq, dist = _contents(tmp_path / "seq"), _contents(tmp_path / "ray")
    assert {"clip_a/frame_0002.npz:labels", "clip_b/lfsam_video_result.json",
            "scene.npz:labels"} <= set(seq)
    _assert_same(seq, dist)
    rows = {row["scene"]: row for row in seq["metrics.csv"]}
    assert list(rows) == ["clip_a", "clip_b", "scene", "mean"]
    for name in ("clip_a", "clip_b"):  # tracked and scored: the video columns F and IDsw
        assert rows[name]["error"] == "" and float(rows[name]["view_iou"]) >= 0.9
        assert (float(rows[name]["frames"]), float(rows[name]["identity_switches"])) == (3, 0)
    assert rows["scene"]["frames"] == "" and float(rows["scene"]["siou"]) > 0.5
    assert "IDsw" in "\n".join(seq["table.md"])

    # Resumed the same way: a lost record reruns its video alone, and its folder is replaced.
    (tmp_path / "ray" / "clip_b.metrics.json").unlink()
    capsys.readouterr()
    assert _evaluate(mixed, tmp_path / "ray", "--ray") == 0
    assert "(1 run now, 2 resumed)" in capsys.readouterr().err
    _assert_same(seq, _contents(tmp_path / "ray"))


def test_ray_video_errors_are_the_sequential_rows(local_ray, mixed, tmp_path):
    """A video that cannot be tracked, or whose result folder may not be written, is the same
    error row as in a sequential run, and nothing already in the output folder is lost."""
    from lfsam.evaluate import evaluate_dataset
    from lfsam.video.evaluate import VideoTracking
    from lfsam.video.tracking.track import track_video

    def track(video, folder):
        if "clip_a" in str(video.meta.get("source")):
            raise RuntimeError("no track")
        return track_video(video, None, folder, model="oracle", disparity="gt")

    def segment(lf):
        from lfsam.result import SegmentationResult

        return SegmentationResult(labels=lf.labels, timings={"total": 0.1})

    tables = {}
    for run, mapper in (("seq", None), ("ray", ray_mapper(device="cpu"))):
        (tmp_path / run / "clip_b").mkdir(parents=True)  # the user's, not a video result
        (tmp_path / run / "clip_b" / "mine.txt").write_text("keep me\n")
        tables[run] = evaluate_dataset(mixed, tmp_path / run, segment, method_label="gt",
                                       videos=VideoTracking(track, "gt"), map_scenes=mapper)
        assert (tmp_path / run / "clip_b" / "mine.txt").read_text() == "keep me\n"
        assert not (tmp_path / run / "clip_a").exists()
    errors = {run: [(r.scene, r.error) for r in table.failed] for run, table in tables.items()}
    assert [scene for scene, _ in errors["seq"]] == ["clip_a", "clip_b"]
    assert "no track" in errors["seq"][0][1] and "not a video result" in errors["seq"][1][1]
    assert errors["ray"] == [(s, e.replace("/seq/", "/ray/")) for s, e in errors["seq"]]
    assert [r.scene for r in tables["ray"].rows] == ["clip_a", "clip_b", "scene"]


def test_ray_refuses_a_result_folder_before_sending_its_task(local_ray, mixed, tmp_path):
    """A video whose result folder may not be replaced is not tracked at all (issue 46): the
    check runs before its Ray task, not after the worker has tracked the video."""
    from lfsam.evaluate import evaluate_dataset
    from lfsam.video.evaluate import VideoTracking
    from lfsam.video.tracking.track import track_video

    tracked = tmp_path / "tracked"
    tracked.mkdir()

    def track(video, folder):
        (tracked / Path(str(video.meta.get("source"))).name).touch()  # seen from the task
        return track_video(video, None, folder, model="oracle", disparity="gt")

    def segment(lf):
        from lfsam.result import SegmentationResult

        return SegmentationResult(labels=lf.labels, timings={"total": 0.1})

    out = tmp_path / "ray"
    (out / "clip_b").mkdir(parents=True)
    (out / "clip_b" / "mine.txt").write_text("keep me\n")
    table = evaluate_dataset(mixed, out, segment, method_label="gt",
                             videos=VideoTracking(track, "gt"),
                             map_scenes=ray_mapper(device="cpu"))
    assert [(r.scene, "not a video result" in r.error) for r in table.failed] == [
        ("clip_b", True)]
    assert sorted(p.name for p in tracked.iterdir()) == ["clip_a"]  # clip_b never tracked
    assert (out / "clip_b" / "mine.txt").read_text() == "keep me\n"


def test_ray_task_failure_is_a_failed_row(local_ray, dataset, tmp_path):
    """A light field that breaks in its task fails alone; the others are written."""
    from lfsam.evaluate import evaluate_dataset

    def segment(lf):
        if lf.meta.get("source", "").endswith("scene1.npz"):
            raise RuntimeError("boom")
        from lfsam.result import SegmentationResult

        return SegmentationResult(labels=lf.labels, timings={"total": 0.1})

    table = evaluate_dataset(dataset, tmp_path, segment, method_label="gt",
                             map_scenes=ray_mapper(device="cpu"))
    assert [row.scene for row in table.rows] == ["scene0", "scene1", "scene2"]
    assert [row.scene for row in table.failed] == ["scene1"]
    assert "boom" in table.failed[0].error
    assert not (tmp_path / "scene1.npz").exists() and (tmp_path / "scene2.npz").is_file()
    assert [name for name, _ in table.skipped] == ["README.md"]


def test_task_resources():
    assert task_resources(None, 0) == {"num_cpus": 1.0, "num_gpus": 0.0}
    assert task_resources(None, 4) == {"num_cpus": 1.0, "num_gpus": 1.0}
    assert task_resources("cuda", 4, 0.5, 2) == {"num_cpus": 2.0, "num_gpus": 0.5}
    assert task_resources("cpu", 4) == {"num_cpus": 1.0, "num_gpus": 0.0}
    with pytest.raises(LfsamError, match="has 0"):
        task_resources(None, 0, num_gpus=1)
    with pytest.raises(LfsamError, match="no GPUs"):
        task_resources("cuda", 0)
    with pytest.raises(LfsamError, match="--device cuda"):
        task_resources("cpu", 2, num_gpus=1)


def test_ray_missing_says_how_to_install(monkeypatch, dataset, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    assert main(["evaluate", str(dataset), "--model", "oracle", "--out", str(tmp_path),
                 "--ray"]) != 0
    err = capsys.readouterr().err
    assert "pip install 'lfsam[ray]'" in err
    assert not any(tmp_path.iterdir())
