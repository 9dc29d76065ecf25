"""Result format: bit-packed masks, atomic save, loader."""

from __future__ import annotations

import numpy as np
import pytest

import lfsam.result
from lfsam.errors import LfsamError
from lfsam.result import PackedMasks, SegmentationResult, load_result, save_result


def _result(rng):
    masks = rng.random((3, 2, 3, 5, 7)) > 0.5
    packed = PackedMasks(masks.shape)
    for s in range(2):
        for t in range(3):
            packed.set_view(s, t, masks[:, s, t])
    labels = rng.integers(0, 4, size=(2, 3, 5, 7)).astype(np.int32)
    result = SegmentationResult(
        labels=labels, masks=packed, scores=np.array([0.9, 0.8, 0.7], dtype=np.float32),
        fallback=masks[:, :, :, 0, 0], refine_iou=rng.random((3, 2, 3)).astype(np.float32),
        timings={"total": 1.5, "encode": 1.0}, meta={"method": "lfsam", "t_sim": 0.7},
    )
    return result, masks


def test_packed_masks_round_trip_with_odd_sizes():
    rng = np.random.default_rng(1)
    result, masks = _result(rng)
    for s in range(2):
        for t in range(3):
            assert np.array_equal(result.masks.view(s, t), masks[:, s, t])
    assert np.array_equal(result.masks.mask(2), masks[2])
    assert np.array_equal(result.masks.areas(), masks.sum(axis=(3, 4)))


def test_save_load_round_trip_and_no_temp_files(tmp_path):
    rng = np.random.default_rng(2)
    result, masks = _result(rng)
    path = save_result(result, tmp_path / "r.npz")
    loaded = load_result(path)
    assert np.array_equal(loaded.labels, result.labels)
    assert np.array_equal(loaded.masks.mask(1), masks[1])
    assert loaded.meta == result.meta and loaded.timings == result.timings
    assert np.array_equal(loaded.fallback, result.fallback)
    # T = 1.5 s / (3 masks x 6 views) = 83.33 ms
    assert abs(loaded.ms_per_mask_view - 1500 / 18) < 1e-9
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.npz"]


def test_failed_save_leaves_nothing(tmp_path, monkeypatch):
    rng = np.random.default_rng(3)
    result, _ = _result(rng)

    def boom(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(lfsam.result, "write_npz", boom)
    with pytest.raises(KeyboardInterrupt):
        save_result(result, tmp_path / "r.npz")
    assert list(tmp_path.iterdir()) == []


def test_missing_output_folder_is_a_clear_error(tmp_path):
    rng = np.random.default_rng(4)
    result, _ = _result(rng)
    with pytest.raises(LfsamError, match="does not exist"):
        save_result(result, tmp_path / "nope" / "r.npz")


def test_foreign_npz_with_labels_only(tmp_path):
    labels = np.zeros((1, 2, 3, 3), dtype=np.int64)
    labels[0, 1, 1, 1] = 4
    np.savez(tmp_path / "x.npz", labels=labels)
    loaded = load_result(tmp_path / "x.npz")
    assert loaded.num_masks == 4 and loaded.ms_per_mask_view is None
    np.savez(tmp_path / "y.npz", other=labels)
    with pytest.raises(LfsamError, match="no 'labels'"):
        load_result(tmp_path / "y.npz")
    with pytest.raises(LfsamError, match="not found"):
        load_result(tmp_path / "z.npz")


def test_saved_file_has_ordinary_permissions(tmp_path):
    import os
    import stat

    rng = np.random.default_rng(5)
    result, _ = _result(rng)
    path = save_result(result, tmp_path / "r.npz")
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask
