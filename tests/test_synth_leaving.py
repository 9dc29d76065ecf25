"""A box that leaves the view and comes back (issue 64: tracks and poses across a gap;
docs/design.md section 12, "Poses through occlusions"): ``lfsam synth --rigid --leaving``."""

from __future__ import annotations

import numpy as np
import pytest

from lfsam.cli.main import main
from lfsam.errors import LfsamError
from lfsam.synth.rigid import LEAVING_DEPTH, LEAVING_GAP, render_rigid, rigid_scenes

SMALL = dict(boxes=1, frames=LEAVING_GAP + 4, grid=(3, 3), size=(96, 128),
             box_size_m=(0.06, 0.08), texels=16)


@pytest.fixture(scope="module")
def leaving():
    return rigid_scenes(seed=5, leaving=True, **SMALL)


def test_the_leaving_box_is_out_of_every_view_for_the_gap_and_comes_back(leaving):
    stay, away = leaving.boxes
    assert away.label == 3  # the next label
    assert abs(stay.poses[0][2, 3] - away.poses[0][2, 3] - LEAVING_DEPTH) < 0.06
    shown = np.array([(render_rigid(leaving, k, supersample=1).labels == away.label)
                      .sum(axis=(2, 3)) for k in range(leaving.frames)])  # (frames, S, T)
    out = shown.sum(axis=(1, 2)) == 0
    # out of every view for exactly LEAVING_GAP frames in a row, inside at the start and end
    assert out.sum() == LEAVING_GAP, shown.sum(axis=(1, 2))
    first = int(np.argmax(out))
    assert out[first:first + LEAVING_GAP].all()
    assert (shown[0] > 0).all() and (shown[-1] > 0).all()
    # it leaves and comes back on the same side, and turns all the while
    xs = away.poses[:, 0, 3]
    assert np.sign(xs[first] - xs[0]) == np.sign(xs[first] - xs[-1]) != 0
    turns = [np.degrees(np.arccos(np.clip((np.trace(a[:3, :3].T @ b[:3, :3]) - 1) / 2, -1, 1)))
             for a, b in zip(away.poses[:-1], away.poses[1:], strict=True)]
    assert min(turns) > 1.9
    # the box that stays is inside the view in every frame
    assert all((render_rigid(leaving, k, supersample=1).labels[1, 1] == stay.label).any()
               for k in range(leaving.frames))
    again = rigid_scenes(seed=5, leaving=True, **SMALL)
    np.testing.assert_array_equal(again.boxes[-1].poses, away.poses)


def test_leaving_needs_enough_frames_and_rigid(tmp_path, capsys):
    with pytest.raises(LfsamError, match="at least 7 frames"):
        rigid_scenes(seed=0, leaving=True, **{**SMALL, "frames": 6})
    out = tmp_path / "x"
    assert main(["synth", str(out), "--rigid", "--leaving", "--frames", "6"]) == 2
    assert "--leaving needs at least 7 frames" in capsys.readouterr().err
    assert not out.exists()
    assert main(["synth", str(out), "--leaving", "--frames", "8"]) == 2
    assert "--leaving adds a box to a --rigid video" in capsys.readouterr().err
    assert not out.exists()
