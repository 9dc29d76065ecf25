"""Light-field video input (issue 25): every form read lazily, and one-line errors."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from lfsam.cli.main import main
from lfsam.errors import LfsamError
from lfsam.io import write_lightfield
from lfsam.lightfield import LightField
from lfsam.video import is_video, read_video
from lfsam.video.io.view_files import write_view_videos

SHAPE = (4, 3, 3, 8, 10)


@pytest.fixture(scope="module")
def video_arrays():
    rng = np.random.default_rng(0)
    views = rng.integers(0, 256, (*SHAPE, 3), dtype=np.uint8)
    disparity = rng.normal(size=SHAPE).astype(np.float32)
    labels = rng.integers(0, 5, SHAPE).astype(np.int32)
    return views, disparity, labels


def _check(video, views, disparity=None, labels=None):
    assert video.shape == SHAPE and len(video) == SHAPE[0]
    for index in (2, 0, 3, 1):  # out of order: seeks back and forth
        lf = video.frame(index)
        assert lf.meta["frame"] == index
        np.testing.assert_array_equal(lf.views, views[index])
        if disparity is not None:
            np.testing.assert_array_equal(lf.disparity, disparity[index])
        if labels is not None:
            np.testing.assert_array_equal(lf.labels, labels[index])


@pytest.mark.parametrize("compressed", [False, True])
def test_npz_video_is_read_frame_by_frame(tmp_path, video_arrays, compressed):
    views, disparity, labels = video_arrays
    save = np.savez_compressed if compressed else np.savez
    save(tmp_path / "v.npz", views=views, disparity=disparity, labels=labels)
    with read_video(tmp_path / "v.npz") as video:
        assert video.has_disparity and video.has_labels
        _check(video, views, disparity, labels)
        if not compressed:  # stored members are memory-mapped, not loaded
            assert isinstance(video._source.views._mmap, np.memmap)


def test_npy_and_h5_videos(tmp_path, video_arrays):
    views, disparity, labels = video_arrays
    np.save(tmp_path / "v.npy", views)
    with read_video(tmp_path / "v.npy") as video:
        assert isinstance(video._source.views, np.memmap)
        _check(video, views)
    with h5py.File(tmp_path / "v.h5", "w") as handle:
        handle["views"], handle["disparity"], handle["labels"] = views, disparity, labels
    with read_video(tmp_path / "v.h5") as video:
        _check(video, views, disparity, labels)


def test_folder_of_frames_in_natural_order(tmp_path, video_arrays):
    views, _, labels = video_arrays
    folder = tmp_path / "frames"
    folder.mkdir()
    for index in range(SHAPE[0]):  # frame_2 sorts before frame_10 by number
        name = f"frame_{index * 4}"
        lf = LightField(views[index], labels=labels[index])
        write_lightfield(lf, folder / (name if index % 2 else f"{name}.npz"))
    assert is_video(folder)
    video = read_video(folder)
    assert video.meta["format"] == "frames-folder" and video.has_labels
    _check(video, views, labels=labels)


def test_view_videos(tmp_path, video_arrays):
    views = video_arrays[0]
    big = np.repeat(np.repeat(views, 2, axis=3), 2, axis=4)  # 16 x 20: even sizes for H.264
    folder = tmp_path / "videos"
    folder.mkdir()
    write_view_videos(iter(big), folder, SHAPE[1:3])
    assert sorted(p.name for p in folder.iterdir())[0] == "view_00_00.mp4"
    with read_video(folder) as video:
        assert video.shape == (4, 3, 3, 16, 20)
        for index in (3, 0, 2):
            np.testing.assert_array_equal(video.frame(index).views, big[index])


def test_info_reports_a_video(tmp_path, video_arrays, capsys):
    np.savez(tmp_path / "v.npz", views=video_arrays[0])
    assert main(["info", str(tmp_path / "v.npz")]) == 0
    assert "4 frames of 3 x 3 views of 8 x 10" in capsys.readouterr().out


def test_errors_are_one_line(tmp_path, video_arrays):
    views = video_arrays[0]
    (tmp_path / "empty").mkdir()
    with pytest.raises(LfsamError, match="is empty"):
        read_video(tmp_path / "empty")
    folder = tmp_path / "mixed"
    folder.mkdir()
    write_lightfield(LightField(views[0]), folder / "a.npz")
    write_lightfield(LightField(views[1, :2]), folder / "b.npz")
    video = read_video(folder)
    with pytest.raises(LfsamError, match=r"frame 1 .* 2 x 3 views .* frame 0 has 3 x 3"):
        video.frame(1)
    with pytest.raises(LfsamError, match="outside the video"):
        video.frame(5)
    np.savez(tmp_path / "bad.npz", views=views, labels=np.zeros((3, 3, 3, 8, 10), np.int32))
    with pytest.raises(LfsamError, match=r"labels .* expected \(4, 3, 3, 8, 10\)"):
        read_video(tmp_path / "bad.npz")
    videos = tmp_path / "uneven"
    videos.mkdir()
    big = np.repeat(np.repeat(views, 2, axis=3), 2, axis=4)
    write_view_videos(iter(big[:, :1, :2]), videos, (1, 2))
    short = tmp_path / "short"
    short.mkdir()
    write_view_videos(iter(big[:3, :1, :1]), short, (1, 1))
    (short / "view_00_00.mp4").replace(videos / "view_00_01.mp4")
    with pytest.raises(LfsamError, match=r"has 3 frames but view_00_00\.mp4 has 4"):
        read_video(videos)
    write_lightfield(LightField(views[0]), tmp_path / "single.npz")
    assert not is_video(tmp_path / "single.npz")
    with pytest.raises(LfsamError, match="not a light-field video"):
        read_video(tmp_path / "single.npz")
