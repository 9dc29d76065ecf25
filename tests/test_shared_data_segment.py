"""The pipeline runs on every real light field in ../shared/data (issue 5).

SAM 2 here is the tiny randomly initialised model built from Meta's classes (masks are
meaningless, the code path is the real one); disparity is estimated from the views since these
scenes have no ground truth for every view. None of these scenes has ground-truth labels, so the
oracle cannot run on them.
"""

from __future__ import annotations

import pytest

from lfsam.cli.main import main
from lfsam.result import load_result

SCENES = {
    "hci_antinous": (9, 9, 512, 512),
    "lytro_2067": (9, 9, 383, 552),
    "t_rex_5x5": (5, 5, 525, 840),
    "translucent_7x7": (7, 7, 430, 619),
    "stanford_legoknights_3x3": (3, 3, 1024, 1024),
    "dolls_3x3": (3, 3, 1024, 1024),
}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_segment_runs_on_real_scene(shared_data, tmp_path, name):
    s, t, u, v = SCENES[name]
    out = tmp_path / f"{name}.npz"
    code = main(
        ["segment", str(shared_data / name), "--point", f"{v // 2},{u // 2}",
         "--point", f"{v // 4},{u // 4}", "--model", "sam2-tiny-test", "--random-weights",
         "--out", str(out), "--quiet"]
    )
    assert code == 0
    result = load_result(out)
    assert result.labels.shape == (s, t, u, v)
    assert result.masks.shape == (2, s, t, u, v)
    assert result.meta["random_weights"] is True
    assert result.meta["views_encoded"] == s * t
