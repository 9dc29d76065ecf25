"""Glossy synthetic scenes (issue 27): a highlight that moves across views, deterministic."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from lfsam.cli.main import main
from lfsam.synth import generate_scene


def test_highlight_moves_across_views_and_changes_nothing_else():
    options = {"grid": (5, 5), "size": (48, 64), "seed": 4, "num_objects": 3}
    matte = generate_scene(**options)
    glossy = generate_scene(**options, specular=0.8)
    again = generate_scene(**options, specular=0.8)
    np.testing.assert_array_equal(glossy.views, again.views)  # deterministic per seed
    np.testing.assert_array_equal(glossy.disparity, matte.disparity)
    np.testing.assert_array_equal(glossy.labels, matte.labels)
    assert glossy.meta["generator"]["specular"] == 0.8 and "specular" not in matte.meta["generator"]
    brighter = glossy.views.astype(int) - matte.views.astype(int)
    assert brighter.min() >= 0  # a highlight only adds light
    spots = brighter.max(-1) > 20  # (S, T, U, V)
    # objects only: background pixels (more than a pixel away from an object, which the
    # anti-aliasing mixes in) are unchanged
    background = ndimage.binary_erosion(matte.labels == 1, np.ones((1, 1, 3, 3), bool))
    assert spots.any() and not spots[background].any()
    # the highlight lies elsewhere on the surface in the outer views: a Lambertian point would
    # keep its brightness, so the spot seen from view (2, 0) differs from view (2, 4)'s
    left, right = brighter[2, 0].max(-1), brighter[2, 4].max(-1)
    assert np.abs(left - right).max() > 40


def test_cli_specular_option(tmp_path, capsys):
    out = tmp_path / "glossy.npz"
    assert main(["synth", str(out), "--grid", "3x3", "--size", "24x32", "--specular", "0.5"]) == 0
    assert "specular 0.5" in capsys.readouterr().out and out.is_file()
    for bad in ["1.5", "-0.1", "shiny"]:
        with pytest.raises(SystemExit):
            main(["synth", str(tmp_path / "x.npz"), "--specular", bad])
        assert "expected a number in [0, 1]" in capsys.readouterr().err
