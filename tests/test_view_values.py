"""Floating-point views: the [0, 1] / [0, 255] rule, non-finite and out-of-range values, and the
threshold options (issue 17: inputs that used to run to the end and write nonsense)."""

from __future__ import annotations

import numpy as np
import pytest

from lfsam.cli.main import main
from lfsam.errors import LfsamError
from lfsam.io import read_lightfield
from lfsam.lightfield import LightField
from lfsam.pipeline import PipelineConfig


def _unit_views(seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).random((3, 3, 8, 10, 3)).astype(np.float32)


def test_unit_range_with_a_value_slightly_above_one_reads_correctly():
    views = _unit_views()
    views[1, 2, 3, 4, 0] = 1.02  # overshoot after processing
    lf = LightField(views)
    expected = np.clip(np.rint(views.astype(np.float64) * 255), 0, 255).astype(np.uint8)
    np.testing.assert_array_equal(lf.views, expected)
    assert lf.views.mean() > 100  # not read as 0..255 (that would be nearly black)
    note = lf.meta["value_range"]
    assert "[0, 1]" in note and "1 values above 1 clipped" in note


def test_round_off_below_zero_reads_as_zero():
    views = _unit_views(5)
    views[0, 0, 0, 0] = -1e-6
    lf = LightField(views)
    assert lf.views[0, 0, 0, 0].tolist() == [0, 0, 0] and lf.views.mean() > 100


def test_many_bright_outliers_still_read_as_unit_range():
    views = _unit_views(1)
    flat = views.reshape(-1)
    flat[:: 2000] = 1.5  # 0.05% of the values, far above 1
    lf = LightField(views)
    assert lf.views.mean() > 100


def test_0_255_floats_read_as_they_are():
    views = _unit_views(2) * 255
    lf = LightField(views)
    np.testing.assert_array_equal(lf.views, np.rint(views).astype(np.uint8))
    assert "[0, 255]" in lf.meta["value_range"]


def test_value_range_option_settles_a_dark_0_255_light_field(tmp_path, capsys):
    dark = _unit_views(3) * 2  # a 0..255 light field darker than 2/255: the documented case
    assert np.array_equal(LightField(dark, value_range=255).views, np.rint(dark).astype(np.uint8))
    assert LightField(dark).views.max() > 200  # the automatic rule reads it as [0, 1]
    np.save(tmp_path / "dark.npy", dark)
    assert main(["convert", str(tmp_path / "dark.npy"), str(tmp_path / "d.npz"),
                 "--value-range", "255"]) == 0
    assert read_lightfield(tmp_path / "d.npz").views.max() <= 2
    assert read_lightfield(tmp_path / "dark.npy", value_range=255).views.max() <= 2
    with pytest.raises(LfsamError, match="value range must be 1 or 255"):
        LightField(dark, value_range=100)


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (np.nan, "1 view values are NaN or infinite"),
        (np.inf, "1 view values are NaN or infinite"),
        (300.0, r"outside \[0, 255\]"),
        (-0.5, r"outside \[0, 255\]"),
        (-0.01, r"outside \[0, 255\]"),
    ],
)
def test_bad_float_values_are_one_line_errors(value, message, tmp_path, capsys):
    views = _unit_views(4) * 255
    views[0, 1, 2, 3, 1] = value
    with pytest.raises(LfsamError, match=message):
        LightField(views)
    np.save(tmp_path / "lf.npy", views)
    out = tmp_path / "out.npz"
    assert main(["convert", str(tmp_path / "lf.npy"), str(out)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize("value", [5, -3, float("nan"), 1.0001])
def test_thresholds_outside_unit_interval(value):
    with pytest.raises(LfsamError, match=r"t_sim must be a number in \[0, 1\]"):
        PipelineConfig(t_sim=value)
    with pytest.raises(LfsamError, match=r"t_iou must be a number in \[0, 1\]"):
        PipelineConfig(t_iou=value)
    assert PipelineConfig(t_sim=0.0, t_iou=1.0).t_iou == 1.0


@pytest.mark.parametrize("option", ["--t-sim", "--t-iou"])
@pytest.mark.parametrize("value", ["5", "-3", "nan", "abc"])
def test_threshold_options_are_checked(option, value, tmp_path, capsys):
    out = tmp_path / "r.npz"
    with pytest.raises(SystemExit) as info:
        main(["segment", str(tmp_path), "--auto", "--model", "oracle", option, value,
              "--out", str(out)])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {option}: expected a number in [0, 1]" in err and "Traceback" not in err
    assert not out.exists()
