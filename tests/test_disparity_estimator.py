"""The disparity estimator (issue 3; since issue 27 the default is the occlusion-aware cost
volume, the structure tensor is ``method="structure-tensor"``): exact planes, sign, confidence,
grids, CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from lfsam.disparity import estimate_disparity
from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.synth import generate_scene


def _texture(height, width, seed=0, flat_right=False):
    """Band-limited random texture (smooth enough for sub-pixel interpolation)."""
    rng = np.random.default_rng(seed)
    noise = torch.as_tensor(rng.random((1, 3, height, width)), dtype=torch.float32)
    kernel = torch.exp(-0.5 * (torch.arange(-4, 5, dtype=torch.float32) / 1.5) ** 2)
    kernel = (kernel / kernel.sum()).view(1, 1, 1, -1).repeat(3, 1, 1, 1)
    smooth = F.conv2d(F.pad(noise, (4, 4, 0, 0), mode="reflect"), kernel, groups=3)
    smooth = F.conv2d(F.pad(smooth, (0, 0, 4, 4), mode="reflect"), kernel.transpose(2, 3), groups=3)
    smooth = (smooth - smooth.min()) / (smooth.max() - smooth.min())
    if flat_right:
        smooth[..., width // 2 :] = 0.5
    return smooth


def _plane(d, grid=(5, 5), size=(48, 64), flat_right=False):
    """A fronto-parallel textured plane at disparity d, in the package convention."""
    s_count, t_count = grid
    height, width = size
    margin = int(abs(d) * max(s_count, t_count)) + 8
    tex = _texture(height + 2 * margin, width + 2 * margin, flat_right=flat_right)
    views = np.empty((s_count, t_count, height, width, 3), dtype=np.uint8)
    rows = torch.arange(height, dtype=torch.float32)[:, None]
    cols = torch.arange(width, dtype=torch.float32)[None, :]
    for s in range(s_count):
        for t in range(t_count):
            # View pixel (u', v') shows center pixel (u' + d ds, v' + d dt).
            src_u = rows + d * (s - s_count // 2) + margin
            src_v = cols + d * (t - t_count // 2) + margin
            src_u, src_v = torch.broadcast_tensors(src_u, src_v)
            grid_xy = torch.stack(
                [2 * src_v / (tex.shape[-1] - 1) - 1, 2 * src_u / (tex.shape[-2] - 1) - 1], -1
            )
            img = F.grid_sample(tex, grid_xy[None], mode="bicubic", align_corners=True)[0]
            views[s, t] = np.clip(np.rint(img.permute(1, 2, 0).numpy() * 255), 0, 255)
    return LightField(views, disparity=np.full(size, d, np.float32))


@pytest.mark.parametrize("d", [-4.0, -2.3, -0.6, 0.0, 1.0, 2.7, 4.0])
def test_fronto_parallel_plane_is_recovered_within_005(d):
    lf = _plane(d)
    est = estimate_disparity(lf)
    inner = est.disparity[10:-10, 10:-10]
    assert np.median(np.abs(inner - d)) < 0.05
    assert np.mean(np.abs(inner - d) < 0.05) > 0.8


@pytest.mark.parametrize("d", [-2.3, 4.0])
def test_structure_tensor_method_still_recovers_planes(d):
    est = estimate_disparity(_plane(d), method="structure-tensor")
    assert est.meta["method"] == "sheared structure tensor"
    inner = est.disparity[10:-10, 10:-10]
    assert np.median(np.abs(inner - d)) < 0.05
    assert np.mean(np.abs(inner - d) < 0.05) > 0.8


def test_sign_convention_matches_generated_ground_truth():
    lf = generate_scene(grid=(7, 7), size=(96, 128), seed=4, disparity_range=(-2.0, 2.0))
    est = estimate_disparity(lf).disparity
    gt = lf.center_disparity
    inner = (slice(8, -8), slice(8, -8))
    assert np.corrcoef(est[inner].ravel(), gt[inner].ravel())[0, 1] > 0.8  # wrong sign: < -0.8
    assert np.median(np.abs(est[inner] - gt[inner])) < 0.1
    negated = LightField(lf.views[::-1, ::-1].copy())  # flipping both view axes negates d
    assert np.median(estimate_disparity(negated).disparity[inner] + gt[inner]) < 0.15


def test_confidence_is_low_where_there_is_no_texture():
    lf = _plane(1.0, flat_right=True)
    conf = estimate_disparity(lf).confidence
    left, right = conf[10:-10, 8:24], conf[10:-10, 44:-8]
    assert np.median(left) > 0.5 > 5 * np.median(right)


def test_too_small_grid_is_a_clear_error_and_one_direction_works():
    tiny = LightField(np.zeros((2, 2, 16, 16, 3), dtype=np.uint8))
    with pytest.raises(LfsamError, match="at least 3 views in a row or column"):
        estimate_disparity(tiny)
    plane = _plane(1.5, grid=(5, 5))
    row_only = LightField(plane.views[2:3])  # 1 x 5: horizontal EPIs only
    col_only = LightField(plane.views[:, 2:3])  # 5 x 1: vertical EPIs only
    for lf in (row_only, col_only):
        inner = estimate_disparity(lf).disparity[10:-10, 10:-10]
        assert np.median(np.abs(inner - 1.5)) < 0.05


def test_cli_writes_npy_and_preview(tmp_path, capsys):
    from lfsam.cli.main import main

    lf = _plane(1.0)
    np.savez(tmp_path / "plane.npz", views=lf.views)
    out, preview = tmp_path / "d.npy", tmp_path / "d.png"
    assert main(["disparity", str(tmp_path / "plane.npz"), "--out", str(out),
                 "--preview", str(preview)]) == 0
    disp = np.load(out)
    assert disp.shape == (48, 64) and np.median(np.abs(disp[10:-10, 10:-10] - 1.0)) < 0.05
    assert preview.is_file()
    printed = json.loads(capsys.readouterr().out)
    assert printed["method"] == "occlusion-aware" and printed["edge_refinement"] is False
    tensor = tmp_path / "st.npy"
    assert main(["disparity", str(tmp_path / "plane.npz"), "--out", str(tensor),
                 "--method", "structure-tensor"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["method"] == "structure-tensor" and printed["edge_refinement"] is True
    np.testing.assert_array_equal(
        np.load(tensor), estimate_disparity(lf, method="structure-tensor").disparity
    )
    raw = tmp_path / "raw.npy"
    assert main(["disparity", str(tmp_path / "plane.npz"), "--out", str(raw), "--range=0,2",
                 "--no-edge-refinement"]) == 0
    assert json.loads(capsys.readouterr().out)["edge_refinement"] is False
    expected = estimate_disparity(lf, (0.0, 2.0), edge_refinement=False).disparity
    np.testing.assert_array_equal(np.load(raw), expected)
    assert main(["disparity", str(tmp_path / "plane.npz"), "--out", str(tmp_path / "x.txt")]) == 2
    assert "must end in .npy" in capsys.readouterr().err
