"""resolve_disparity: estimated, ground-truth or file disparity, with clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from lfsam.disparity import resolve_disparity
from lfsam.errors import LfsamError
from lfsam.lightfield import LightField


def _lf(with_gt=True):
    views = np.zeros((3, 3, 8, 10, 3), dtype=np.uint8)
    disparity = np.arange(80, dtype=np.float32).reshape(8, 10) if with_gt else None
    return LightField(views, disparity=disparity)


def test_gt_and_file(tmp_path):
    lf = _lf()
    disp, source = resolve_disparity("gt", lf)
    assert source == "gt" and np.array_equal(disp, lf.center_disparity)
    path = tmp_path / "d.npy"
    np.save(path, np.ones((8, 10)))
    disp, source = resolve_disparity(str(path), lf)
    assert disp.dtype == np.float32 and disp.sum() == 80 and source == f"file:{path}"


def test_errors(tmp_path):
    with pytest.raises(LfsamError, match="no ground-truth disparity"):
        resolve_disparity("gt", _lf(with_gt=False))
    with pytest.raises(LfsamError, match="not found"):
        resolve_disparity(str(tmp_path / "missing.npy"), _lf())
    np.save(tmp_path / "bad.npy", np.ones((4, 4)))
    with pytest.raises(LfsamError, match=r"shape \(4, 4\)"):
        resolve_disparity(str(tmp_path / "bad.npy"), _lf())
    with pytest.raises(LfsamError, match=r"'estimate', 'gt' or a \.npy"):
        resolve_disparity("bogus", _lf())
