"""``lfsam show`` on a light-field video's result (issue 25, docs/design.md section 10): an
animation over time of one view or of the grid."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image, ImageSequence

from lfsam.cli.main import main
from lfsam.result import SegmentationResult
from lfsam.video import read_video
from lfsam.video.io.result import video_result_writer
from lfsam.video.io.synth import generate_video, write_video_frames
from lfsam.viz import time_strip
from lfsam.viz.overlay import overlay_view


@pytest.fixture(scope="module")
def video_and_result(tmp_path_factory):
    folder = tmp_path_factory.mktemp("video")
    write_video_frames(generate_video(grid=(3, 3), size=(24, 32), frames=3, seed=0,
                                      num_objects=2), folder / "clip")
    video = read_video(folder / "clip")
    with video_result_writer(folder / "result", meta={"input": str(folder / "clip")}) as w:
        for lf in video:
            w.write(SegmentationResult(labels=lf.labels))
    return video, folder / "result"


def _frames(path):
    with Image.open(path) as gif:
        return [np.asarray(frame.convert("RGB")) for frame in ImageSequence.Iterator(gif)]


def test_one_view_over_time(video_and_result, tmp_path):
    video, result = video_and_result
    out = tmp_path / "view.gif"
    assert main(["show", str(result), "--view", "2,1", "--out", str(out), "--quiet"]) == 0
    frames = _frames(out)
    assert len(frames) == 3 and frames[0].shape == (24 + 6, 32, 3)
    lf = video.frame(1)
    expected = overlay_view(lf.views, lf.labels, None, 2, 1)
    # GIF colours are quantised: the overlay is close, the time bar exact (few colours)
    assert np.abs(frames[1][:24].astype(int) - expected).mean() < 4
    np.testing.assert_array_equal(frames[1][24:], time_strip(1, 3, 32))


def test_grid_over_time_and_errors(video_and_result, tmp_path, capsys):
    _, result = video_and_result
    out = tmp_path / "grid.gif"
    assert main(["show", str(result), "--out", str(out), "--quiet"]) == 0
    frames = _frames(out)
    assert len(frames) == 3 and frames[0].shape[0] > 3 * 24 and frames[0].shape[1] > 3 * 32
    assert main(["show", str(result), "--out", str(tmp_path / "x.png")]) != 0
    assert "animation over time" in capsys.readouterr().err
    assert main(["show", str(result), "--view", "3,0", "--out", str(tmp_path / "x.gif")]) != 0
    assert "outside the 3 x 3 grid" in capsys.readouterr().err
    assert not (tmp_path / "x.gif").exists()
