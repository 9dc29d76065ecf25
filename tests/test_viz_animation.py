"""Tests of snake-order animations (lfsam.viz.animation): frames, GIF and MP4 files."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image, ImageSequence

from lfsam.errors import LfsamError
from lfsam.lightfield import snake_order
from lfsam.viz import animation
from lfsam.viz.animation import animation_frames, indicator_strip, write_animation
from lfsam.viz.overlay import overlay_labels
from test_viz_scene import make_scene


def _expected_order(s_count: int, t_count: int) -> list[tuple[int, int]]:
    """Snake order written out independently: even rows left to right, odd rows back."""
    return [
        (s, t if s % 2 == 0 else t_count - 1 - t) for s in range(s_count) for t in range(t_count)
    ]


def _read_gif(path) -> list[np.ndarray]:
    with Image.open(path) as image:
        return [np.asarray(frame.convert("RGB")) for frame in ImageSequence.Iterator(image)]


def test_frames_are_the_overlays_in_snake_order():
    lf = make_scene(grid=(3, 4))
    frames = list(animation_frames(lf.views, lf.labels, alpha=0.4, indicator=False))
    assert len(frames) == 12
    assert snake_order((3, 4)) == _expected_order(3, 4)
    for frame, (s, t) in zip(frames, _expected_order(3, 4), strict=True):
        assert frame.shape == (48, 64, 3)
        np.testing.assert_array_equal(
            frame, overlay_labels(lf.views[s, t], lf.labels[s, t], alpha=0.4)
        )


def test_indicator_lights_the_current_view():
    grid, width = (3, 4), 64
    c = int(np.clip((width - 1) // 4 - 1, 1, 4))  # documented cell size
    for s, t in _expected_order(*grid):
        strip = indicator_strip(grid, (s, t), width)
        assert strip.shape == (3 * (c + 1) + 1, width, 3)
        lit = np.argwhere((strip == animation._INDICATOR_ON).all(axis=-1))
        assert lit.min(axis=0).tolist() == [1 + s * (c + 1), 1 + t * (c + 1)]
        assert lit.max(axis=0).tolist() == [s * (c + 1) + c, t * (c + 1) + c]
    # A grid too wide for the frame is cropped, never wider than the frame.
    assert indicator_strip((2, 40), (1, 39), 30).shape[1] == 30


def test_gif_has_one_frame_per_view_in_snake_order(tmp_path):
    lf = make_scene(grid=(3, 3))
    path = write_animation(tmp_path / "views.gif", animation_frames(lf.views, lf.labels), fps=5)
    assert path == tmp_path / "views.gif"
    frames = _read_gif(path)
    assert len(frames) == 9
    overlays = np.stack(
        [overlay_labels(lf.views[s, t], lf.labels[s, t]) for s, t in lf.view_indices()]
    )
    index = {view: i for i, view in enumerate(lf.view_indices())}
    for frame, view in zip(frames, _expected_order(3, 3), strict=True):
        assert frame.shape[1] == 64 and frame.shape[0] > 48
        # GIF quantises to 256 colours per frame: each frame must be nearest to its own view's
        # overlay, and close to it.
        error = np.abs(overlays.astype(float) - frame[:48].astype(float)).mean(axis=(1, 2, 3))
        assert int(np.argmin(error)) == index[view]
        assert error[index[view]] < 4.0


def test_gif_keeps_identical_views_as_separate_frames(tmp_path):
    views = np.full((2, 3, 16, 24, 3), 90, dtype=np.uint8)  # every view the same
    path = write_animation(tmp_path / "flat.gif", animation_frames(views))
    assert len(_read_gif(path)) == 6


def test_mp4_has_one_frame_per_view(tmp_path):
    imageio = pytest.importorskip("imageio.v2")
    pytest.importorskip(
        "imageio_ffmpeg", reason="MP4 needs the optional imageio-ffmpeg (dev extra)"
    )
    lf = make_scene(grid=(3, 3), size=(47, 63))  # odd sizes get padded to even
    path = write_animation(tmp_path / "views.mp4", animation_frames(lf.views, lf.labels), fps=4)
    reader = imageio.get_reader(path, format="FFMPEG")
    try:
        frames = [np.asarray(f) for f in reader]
    finally:
        reader.close()
    assert len(frames) == 9
    assert frames[0].shape[0] % 2 == 0 and frames[0].shape[1] == 64
    for frame, (s, t) in zip(frames, _expected_order(3, 3), strict=True):
        expected = overlay_labels(lf.views[s, t], lf.labels[s, t]).astype(float)
        assert np.abs(frame[:47, :63].astype(float) - expected).mean() < 12.0


def test_mp4_falls_back_to_gif_with_a_message(tmp_path, monkeypatch):
    monkeypatch.setattr(animation, "ffmpeg_available", lambda: False)
    views = np.random.default_rng(0).integers(0, 255, (2, 2, 8, 12, 3), dtype=np.uint8)
    with pytest.warns(UserWarning, match="pip install imageio-ffmpeg"):
        path = write_animation(tmp_path / "a.mp4", animation_frames(views))
    assert path == tmp_path / "a.gif"
    assert path.is_file() and not (tmp_path / "a.mp4").exists()
    assert len(_read_gif(path)) == 4


def test_bad_requests_and_failures_leave_no_file(tmp_path):
    views = np.zeros((2, 2, 8, 12, 3), dtype=np.uint8)
    with pytest.raises(LfsamError, match=r"\.gif or \.mp4"):
        write_animation(tmp_path / "a.png", animation_frames(views))
    with pytest.raises(LfsamError, match="no frames"):
        write_animation(tmp_path / "a.gif", iter([]))

    def broken():
        yield np.zeros((8, 12, 3), dtype=np.uint8)
        raise RuntimeError("renderer failed")

    for name in ("b.gif", "b.mp4"):
        with pytest.raises(RuntimeError):
            write_animation(tmp_path / name, broken())
    assert list(tmp_path.iterdir()) == []
