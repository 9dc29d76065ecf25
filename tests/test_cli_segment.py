"""`lfsam segment`: bad input gives one-line errors and no partial result file."""

from __future__ import annotations

import numpy as np
import pytest

from lfsam.cli.main import main
from lfsam.io import write_lightfield
from lfsam.result import load_result
from lfsam.synth import generate_scene


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    path = tmp_path_factory.mktemp("scene") / "scene"
    write_lightfield(generate_scene(grid=(3, 3), size=(40, 56), seed=5, num_objects=3), path)
    return path


def _error_line(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("lfsam: error:"), err
    return err[0]


def test_oracle_auto_writes_a_loadable_result(scene_dir, tmp_path, capsys):
    out = tmp_path / "r.npz"
    code = main(
        ["segment", str(scene_dir), "--auto", "--model", "oracle", "--disparity", "gt",
         "--out", str(out), "--quiet"]
    )
    assert code == 0
    result = load_result(out)
    assert result.labels.shape == (3, 3, 40, 56) and result.num_masks >= 3
    assert result.meta["method"] == "lfsam" and result.meta["disparity_source"] == "gt"


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--point", "500,10"], "object 1: point 1 X,Y = 500,10 lies outside the view"),
        (["--point", "5,5@3,0"], "object 1: point 1 is tagged with view 3,0 outside the 3x3"),
        (["--neg", "5,5", "--point", "6,6"], "--neg X,Y belongs to the object started"),
        (["--box", "10,10,10,30"], "empty"),
        ([], "give prompts"),
        (["--auto", "--point", "5,5"], "give prompts"),
    ],
)
def test_bad_prompts_are_one_line_errors(scene_dir, tmp_path, capsys, extra, message):
    out = tmp_path / "r.npz"
    code = main(["segment", str(scene_dir), "--model", "oracle", "--disparity", "gt",
                 "--out", str(out), "--quiet", *extra])
    assert code == 2
    assert message in _error_line(capsys)
    assert not out.exists()


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--point", "5,5@1"], "the view after @ must be S,T"),
        (["--point", "5"], "expected X,Y or X,Y@S,T"),
        (["--point", "5,5", "--oracle-merge", "2"], "expected a probability in [0, 1]"),
    ],
)
def test_bad_prompt_syntax_is_a_usage_error(scene_dir, tmp_path, capsys, extra, message):
    out = tmp_path / "r.npz"
    with pytest.raises(SystemExit) as info:
        main(["segment", str(scene_dir), "--out", str(out), *extra])
    assert info.value.code == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_missing_out_folder(scene_dir, tmp_path, capsys):
    code = main(["segment", str(scene_dir), "--auto", "--model", "oracle",
                 "--out", str(tmp_path / "no" / "r.npz")])
    assert code == 2 and "does not exist" in _error_line(capsys)


def test_interrupted_run_leaves_no_file(scene_dir, tmp_path, monkeypatch, capsys):
    import lfsam.pipeline.fusion as fusion_module

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    # the labels are fused view by view during the run (fusion.ViewLabels) or at its end
    monkeypatch.setattr(fusion_module, "fuse_labels", interrupted)
    out = tmp_path / "r.npz"
    code = main(["segment", str(scene_dir), "--auto", "--model", "oracle", "--disparity", "gt",
                 "--out", str(out), "--quiet"])
    assert code == 130
    assert list(tmp_path.iterdir()) == []


def test_gt_disparity_missing_is_a_clear_error(tmp_path, capsys):
    lf = generate_scene(grid=(3, 3), size=(40, 56), seed=6, num_objects=2)
    path = tmp_path / "views.npz"
    np.savez(path, views=lf.views)
    code = main(["segment", str(path), "--point", "10,10", "--model", "sam2-tiny-test",
                 "--random-weights", "--disparity", "gt", "--out", str(tmp_path / "r.npz")])
    assert code == 2 and "disparity" in _error_line(capsys)


def _run(scene_dir, out, *extra):
    return main(["segment", str(scene_dir), "--model", "oracle", "--disparity", "gt",
                 "--out", str(out), "--quiet", *extra])


def test_point_neg_point_is_two_objects_with_views(scene_dir, tmp_path):
    out = tmp_path / "r.npz"
    code = _run(scene_dir, out, "--point", "20,15", "--neg", "40,30@0,2", "--point", "30,20@2,0",
                "--box", "1,1,20,20@1,1")
    assert code == 0
    objects = load_result(out).meta["objects"]
    assert [o["id"] for o in objects] == [1, 2, 3]
    assert objects[0]["points"] == [
        {"xy": [20.0, 15.0], "label": 1, "view": [1, 1]},
        {"xy": [40.0, 30.0], "label": 0, "view": [0, 2]},
    ]
    assert objects[1]["reference_view"] == [2, 0]
    assert objects[2]["box"] == {"xyxy": [1.0, 1.0, 20.0, 20.0], "view": [1, 1]}


def test_prompt_file_and_its_errors(scene_dir, tmp_path, capsys):
    import json

    good = tmp_path / "p.json"
    good.write_text(json.dumps([{"id": 4, "points": [[20, 15], [40, 30]], "labels": [1, 0]}]))
    out = tmp_path / "r.npz"
    assert _run(scene_dir, out, "--prompts", str(good), "--point", "30,20") == 0
    result = load_result(out)
    assert result.meta["object_ids"] == [4, 5]
    assert set(np.unique(result.labels)) <= {0, 4, 5}
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps([{"id": 2, "points": [[20, 15]], "colour": "red"}]))
    out2 = tmp_path / "r2.npz"
    assert _run(scene_dir, out2, "--prompts", str(bad)) == 2
    assert "object 2: unknown key(s) colour" in _error_line(capsys)
    assert not out2.exists()


def test_cache_second_run_encodes_nothing(scene_dir, tmp_path):
    import json

    runs = []
    for name in ("a", "b"):
        out = tmp_path / f"{name}.npz"
        code = main(["segment", str(scene_dir), "--model", "sam2-tiny-test", "--random-weights",
                     "--device", "cpu", "--disparity", "gt", "--point", "20,15",
                     "--cache", str(tmp_path / "cache"), "--out", str(out), "--quiet"])
        assert code == 0
        runs.append(load_result(out))
    assert runs[0].meta["views_encoded"] == 9 and runs[1].meta["views_encoded"] == 0
    assert np.array_equal(runs[0].labels, runs[1].labels)
    assert json.dumps(runs[0].meta["objects"]) == json.dumps(runs[1].meta["objects"])


def test_oracle_merge_and_a_negative_click(scene_dir, tmp_path):
    from lfsam.io import read_lightfield

    lf = read_lightfield(scene_dir)
    center = lf.labels[lf.center]
    ids, counts = np.unique(center[center > 1], return_counts=True)
    target = int(ids[np.argmax(counts)])
    rows, cols = np.nonzero(center == target)
    k = np.argmin((rows - rows.mean()) ** 2 + (cols - cols.mean()) ** 2)
    click = f"{cols[k]},{rows[k]}"
    merged_out = tmp_path / "merged.npz"
    assert _run(scene_dir, merged_out, "--point", click, "--oracle-merge", "1") == 0
    merged = load_result(merged_out).labels[lf.center] == 1
    neighbours = set(np.unique(center[merged])) - {target}
    assert len(neighbours) == 1
    (neighbour,) = neighbours
    n_rows, n_cols = np.nonzero(center == neighbour)
    j = len(n_rows) // 2
    fixed_out = tmp_path / "fixed.npz"
    assert _run(scene_dir, fixed_out, "--point", click, "--neg", f"{n_cols[j]},{n_rows[j]}",
                "--oracle-merge", "1") == 0
    fixed = load_result(fixed_out).labels[lf.center] == 1
    assert np.array_equal(fixed, center == target)
