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
        (["--point", "500,10"], "outside the center view"),
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


def test_missing_out_folder(scene_dir, tmp_path, capsys):
    code = main(["segment", str(scene_dir), "--auto", "--model", "oracle",
                 "--out", str(tmp_path / "no" / "r.npz")])
    assert code == 2 and "does not exist" in _error_line(capsys)


def test_interrupted_run_leaves_no_file(scene_dir, tmp_path, monkeypatch, capsys):
    import lfsam.pipeline.segment as segment_module

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(segment_module, "fuse_labels", interrupted)
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
