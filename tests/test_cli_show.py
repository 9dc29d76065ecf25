"""Tests of ``lfsam show``: every kind of output, comparisons, light-field mode and user errors."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image, ImageSequence

from lfsam.cli.main import main
from lfsam.result import PackedMasks, SegmentationResult, save_result
from lfsam.viz import animation
from lfsam.viz.compare import compare_grid, match_labels
from lfsam.viz.epi import epi_figure
from lfsam.viz.grid import view_grid
from test_viz_scene import make_scene

GRID, SIZE = (3, 5), (48, 64)


@pytest.fixture
def files(tmp_path):
    """A light field (.npz with views and labels) and a result computed 'on' it."""
    lf = make_scene(grid=GRID, size=SIZE)
    lf_path = tmp_path / "scene.npz"
    np.savez(lf_path, views=lf.views, labels=lf.labels)
    result = SegmentationResult(labels=np.where(lf.labels == 3, 0, lf.labels), meta={"method": "x"})
    result_path = save_result(result, tmp_path / "result.npz")
    return lf, lf_path, result, result_path


def _read(path) -> np.ndarray:
    with Image.open(path) as image:
        return np.asarray(image.convert("RGB"))


def _gif_frames(path) -> int:
    with Image.open(path) as image:
        return sum(1 for _ in ImageSequence.Iterator(image))


def test_grid_figure(files, tmp_path):
    lf, lf_path, result, result_path = files
    out = tmp_path / "grid.png"
    argv = ["show", str(result_path), "--lightfield", str(lf_path), "--out", str(out), "--quiet"]
    assert main([*argv, "--views", "corners"]) == 0
    expected = view_grid(lf.views, result.labels, which="corners", captions=True)
    np.testing.assert_array_equal(_read(out), expected)
    assert main([*argv, "--views", "all", "--no-captions", "--scale", "0.5"]) == 0
    full = view_grid(lf.views, result.labels, which="all", captions=False)
    assert _read(out).shape == (round(full.shape[0] / 2), round(full.shape[1] / 2), 3)


def test_epi_figure(files, tmp_path):
    lf, lf_path, result, result_path = files
    out = tmp_path / "epi.png"
    rc = main(
        ["show", str(result_path), "--lightfield", str(lf_path), "--out", str(out), "--kind",
         "epi", "--row", "30", "--col", "12", "--upsample", "5", "--quiet"]
    )  # fmt: skip
    assert rc == 0
    image = _read(out)
    s_count, t_count = GRID
    assert image.shape == (48 + 4 + t_count * 5, 64 + 4 + s_count * 5, 3)
    np.testing.assert_array_equal(
        image, epi_figure(lf.views, result.labels, row=30, col=12, upsample=5)
    )


def test_animation_has_one_frame_per_view(files, tmp_path):
    _, lf_path, _, result_path = files
    out = tmp_path / "views.gif"  # --kind follows the suffix
    assert main(["show", str(result_path), "--lightfield", str(lf_path), "--out", str(out)]) == 0
    assert _gif_frames(out) == GRID[0] * GRID[1]


def test_kind_all_into_a_folder_and_with_a_prefix(files, tmp_path, capsys):
    _, lf_path, _, result_path = files
    folder = tmp_path / "figs"
    base = ["show", str(result_path), "--lightfield", str(lf_path)]
    assert main([*base, "--out", f"{folder}/"]) == 0
    names = sorted(p.name for p in folder.iterdir())
    assert names == ["anim.gif", "epi.png", "grid.png"]
    printed = capsys.readouterr().out.split()
    assert sorted(printed) == sorted(str(folder / n) for n in names)
    assert main([*base, "--out", str(tmp_path / "fig.png"), "--kind", "all", "--quiet"]) == 0
    for name in ("fig_grid.png", "fig_epi.png", "fig_anim.gif"):
        assert (tmp_path / name).is_file()


def test_compare_with_a_second_result_and_with_ground_truth(files, tmp_path):
    lf, lf_path, result, result_path = files
    other = SegmentationResult(labels=np.where(lf.labels == 1, 0, lf.labels) * 2)
    other_path = save_result(other, tmp_path / "other.npz")
    base = [
        "show",
        str(result_path),
        "--lightfield",
        str(lf_path),
        "--quiet",
        "--views",
        "diagonal",
    ]
    out = tmp_path / "cmp.png"
    assert main([*base, "--compare", str(other_path), "--out", str(out), "--names", "a,b"]) == 0
    expected = compare_grid(
        lf.views, result.labels, other.labels, names=("a", "b"), which="diagonal", captions=True
    )
    np.testing.assert_array_equal(_read(out), expected)
    # --match-colors renumbers the second result's ids to the first's best-overlapping ones.
    assert main([*base, "--compare", str(other_path), "--match-colors", "--out", str(out)]) == 0
    matched = match_labels(result.labels, other.labels)
    assert not np.array_equal(matched, other.labels)
    expected = compare_grid(
        lf.views, result.labels, matched, names=("x (result.npz)", "other.npz"),
        which="diagonal", captions=True,
    )  # fmt: skip
    np.testing.assert_array_equal(_read(out), expected)
    assert main([*base, "--compare", "gt", "--kind", "epi", "--out", str(out)]) == 0
    single = epi_figure(lf.views, result.labels)
    assert _read(out).shape[1] == 2 * single.shape[1] + 8


def test_light_field_alone_and_with_its_ground_truth(files, tmp_path):
    lf, lf_path, _, _ = files
    plain, gt = tmp_path / "plain.png", tmp_path / "gt.png"
    assert main(["show", str(lf_path), "--out", str(plain), "--quiet", "--no-captions"]) == 0
    assert main(["show", str(lf_path), "--out", str(gt), "--gt-labels", "--no-captions"]) == 0
    np.testing.assert_array_equal(_read(plain), view_grid(lf.views, None))
    np.testing.assert_array_equal(_read(gt), view_grid(lf.views, lf.labels))


def test_result_recording_its_source_needs_no_lightfield(files, tmp_path):
    lf, lf_path, result, _ = files
    recorded = save_result(
        SegmentationResult(labels=result.labels, meta={"source": str(lf_path)}),
        tmp_path / "recorded.npz",
    )
    out = tmp_path / "r.png"
    assert main(["show", str(recorded), "--out", str(out), "--quiet"]) == 0
    assert _read(out).shape == view_grid(lf.views, None, captions=True).shape


def test_mp4_without_ffmpeg_writes_gif_and_says_so(files, tmp_path, monkeypatch, capsys):
    _, lf_path, _, result_path = files
    monkeypatch.setattr(animation, "ffmpeg_available", lambda: False)
    out = tmp_path / "v.mp4"
    assert main(["show", str(result_path), "--lightfield", str(lf_path), "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "imageio-ffmpeg" in captured.err and "lfsam: note:" in captured.err
    assert not out.exists() and _gif_frames(tmp_path / "v.gif") == GRID[0] * GRID[1]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--row", "48"], "--row 48 is outside"),
        (["--col", "-1"], "--col -1 is outside"),
        (["--kind", "anim"], "--kind anim writes .gif/.mp4"),
        (["--upsample", "0"], "--upsample must be in 1..64"),
        (["--compare", "missing.npz"], "not found"),
        (["--match-colors"], "--match-colors needs --compare"),
        (["--gt-labels"], "--compare gt"),
    ],
)
def test_user_errors_are_one_line_and_leave_no_file(files, tmp_path, capsys, extra, message):
    _, lf_path, _, result_path = files
    out = tmp_path / "x.png"
    rc = main(["show", str(result_path), "--lightfield", str(lf_path), "--out", str(out), *extra])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert err.startswith("lfsam: error:") and message in err and "\n" not in err
    assert not out.exists()


def test_mismatched_result_and_missing_light_field(files, tmp_path, capsys):
    _, lf_path, _, _ = files
    wrong = save_result(
        SegmentationResult(labels=np.zeros((3, 5, 40, 64), np.int32)), tmp_path / "w.npz"
    )
    out = tmp_path / "x.png"
    assert main(["show", str(wrong), "--lightfield", str(lf_path), "--out", str(out)]) == 2
    assert "do not match the light field" in capsys.readouterr().err
    assert main(["show", str(wrong), "--out", str(out)]) == 2
    assert "--lightfield PATH" in capsys.readouterr().err
    assert not out.exists()


def test_unknown_kind_and_help(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["show", "x.npz", "--out", "y.png", "--kind", "movie"])
    assert exc.value.code == 2
    assert "invalid choice" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["show", "--help"])
    assert exc.value.code == 0
    assert "lfsam show result.npz --lightfield scene" in capsys.readouterr().out


def test_mask_outlines_and_center_only_ground_truth(files, tmp_path, capsys):
    lf, lf_path, _, _ = files
    masks = PackedMasks((2, *GRID, *SIZE))
    labels = np.zeros(lf.labels.shape, dtype=np.int32)
    for s, t in lf.view_indices():
        pair = np.stack([lf.labels[s, t] >= 1, lf.labels[s, t] == 2])  # mask 2 inside mask 1
        masks.set_view(s, t, pair)
        labels[s, t] = np.where(pair[1], 2, np.where(pair[0], 1, 0))
    with_masks = save_result(SegmentationResult(labels=labels, masks=masks), tmp_path / "m.npz")
    out = tmp_path / "m.png"
    base = ["show", str(with_masks), "--lightfield", str(lf_path), "--out", str(out), "--quiet"]
    assert main([*base, "--mask-outlines", "--no-captions"]) == 0
    np.testing.assert_array_equal(_read(out), view_grid(lf.views, labels, masks=masks))
    assert not np.array_equal(_read(out), view_grid(lf.views, labels))  # hidden edges drawn
    assert main([*base, "--mask-outlines", "--compare", "gt"]) == 2
    assert "--mask-outlines needs" in capsys.readouterr().err
    # A light field with center-view labels only: the other views show no labels.
    center_only = tmp_path / "center.npz"
    np.savez(center_only, views=lf.views, labels=lf.labels[lf.center])
    assert main(["show", str(center_only), "--gt-labels", "--out", str(out), "--no-captions"]) == 0
    full = np.zeros_like(lf.labels)
    full[lf.center] = lf.labels[lf.center]
    np.testing.assert_array_equal(_read(out), view_grid(lf.views, full))


def test_outputs_are_checked_before_anything_is_made(files, tmp_path, capsys):
    _, lf_path, _, result_path = files
    base = ["show", str(result_path), "--lightfield", str(lf_path)]
    assert main([*base, "--out", f"{tmp_path}/new/", "--row", "99"]) == 2
    assert not (tmp_path / "new").exists()  # the folder is only made once all checks pass
    assert main([*base, "--out", str(tmp_path / "missing" / "g.png")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main([*base, "--out", str(tmp_path / "missing" / "deeper") + "/"]) == 2
    assert not (tmp_path / "missing").exists()
