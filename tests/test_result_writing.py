"""Writing results fast enough for a live stream (issue 44; docs/design.md sections 1 and 10):
result format 2 (labels in the smallest dtype, zlib level per write) reads back the same int32
labels and still reads format 1; a live result's files are written behind the tracking thread,
never lose a frame, are flushed however the stream ends and are never partial."""

from __future__ import annotations

import threading
import time
import zipfile

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import lfsam
import lfsam.result
import lfsam.video.io.result as video_result
from lfsam.errors import LfsamError
from lfsam.result import (
    FAST_LEVEL,
    PackedMasks,
    SegmentationResult,
    label_ids,
    label_storage_dtype,
    load_result,
    save_result,
)
from lfsam.video.io.live_result import QUEUE_FRAMES, live_video_result_writer
from lfsam.video.io.result import RESULT_MARKER, frame_name


def _labels(top: int, seed: int = 0) -> np.ndarray:
    """(2, 3, 16, 20) labels: regions of ids 0 .. top, with ``top`` present."""
    rng = np.random.default_rng(seed)
    labels = np.zeros((2, 3, 16, 20), np.int32)
    ids = np.unique(np.r_[rng.integers(1, top + 1, size=5), top])
    for k, i in enumerate(ids):
        labels[:, :, 2 * k: 2 * k + 5, 3 * k: 3 * k + 7] = i
    return labels


@pytest.mark.parametrize("top, stored", [(0, "uint8"), (3, "uint8"), (255, "uint8"),
                                         (256, "uint16"), (65535, "uint16"),
                                         (65536, "int32"), (2**31 - 1, "int32")])
@pytest.mark.parametrize("level", [0, FAST_LEVEL, 6, 9])
def test_labels_round_trip_in_the_smallest_dtype(tmp_path, top, stored, level):
    labels = _labels(top) if top else np.zeros((2, 3, 16, 20), np.int32)
    masks = PackedMasks((2, 2, 3, 16, 20))
    masks.set_view(1, 2, np.stack([labels[1, 2] > 0, labels[1, 2] == top]))
    result = SegmentationResult(labels=labels, masks=masks, scores=np.array([0.5, 1.0]),
                                meta={"m": 1})
    path = save_result(result, tmp_path / "r.npz", level=level)
    with np.load(path) as npz:  # an ordinary .npz: NumPy reads it
        assert str(npz["labels"].dtype) == stored and int(npz["format_version"]) == 2
    with zipfile.ZipFile(path) as archive:
        kinds = {info.compress_type for info in archive.infolist()}
    assert kinds == {zipfile.ZIP_STORED if level == 0 else zipfile.ZIP_DEFLATED}
    loaded = load_result(path)
    assert loaded.labels.dtype == np.int32
    np.testing.assert_array_equal(loaded.labels, labels)
    np.testing.assert_array_equal(loaded.masks.view(1, 2), masks.view(1, 2))
    assert loaded.meta == {"m": 1}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.npz"]


def test_format_1_files_still_load(tmp_path):
    """A file as lfsam wrote it before format 2: int32 labels, numpy.savez_compressed."""
    labels = _labels(70000)
    with open(tmp_path / "old.npz", "wb") as handle:
        np.savez_compressed(handle, format_version=np.array(1), labels=labels,
                            timings=np.array('{"total": 1.0}'), meta=np.array('{"a": 2}'),
                            scores=np.ones(2, np.float32))
    loaded = load_result(tmp_path / "old.npz")
    assert loaded.labels.dtype == np.int32 and loaded.meta == {"a": 2}
    np.testing.assert_array_equal(loaded.labels, labels)
    # and a version-2 file of the same labels stays readable by a version-1 reader (int32 ids)
    save_result(SegmentationResult(labels=labels), tmp_path / "new.npz")
    with np.load(tmp_path / "new.npz") as npz:
        np.testing.assert_array_equal(npz["labels"].astype(np.int32), labels)


def test_negative_labels_are_kept_int32_and_refused_on_reading(tmp_path):
    labels = _labels(3)
    labels[0, 0, 0, 0] = -1  # not a label: ids are >= 0, 0 = unlabeled
    assert label_storage_dtype(labels) == np.int32
    save_result(SegmentationResult(labels=labels), tmp_path / "neg.npz")
    with pytest.raises(LfsamError, match=">= 0"):
        load_result(tmp_path / "neg.npz")


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(0, 2**31 - 1), min_size=1, max_size=40),
       st.lists(st.integers(1, 5), min_size=1, max_size=40))
def test_label_ids_are_numpy_unique(values, repeats):
    runs = np.repeat(np.array(values, np.int32), np.resize(repeats, len(values)))
    assert label_ids(runs.reshape(1, 1, 1, -1)).tolist() == np.unique(runs).tolist()


# --- a live result written behind the tracking thread ------------------------------------------
def _frame(f: int) -> SegmentationResult:
    labels = np.zeros((1, 2, 4, 5), np.int32)
    labels[:, :, f % 4, :] = 300 + f  # ids over 255: stored as uint16
    return SegmentationResult(labels=labels, meta={"frame": f})


def _gate(monkeypatch) -> tuple[threading.Event, list[int]]:
    """Make every frame's file wait for the returned event; count the files started."""
    gate, started = threading.Event(), []
    save = video_result.save_result

    def gated(result, path, **kwargs):
        started.append(result.meta["frame"])
        assert gate.wait(30)
        return save(result, path, **kwargs)

    monkeypatch.setattr(video_result, "save_result", gated)
    return gate, started


def _wait(condition, timeout=10.0):
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.01)


def _files(out):
    return sorted(p.name for p in out.iterdir())


def test_writes_are_behind_bounded_and_every_frame_lands(tmp_path, monkeypatch):
    gate, started = _gate(monkeypatch)
    out = tmp_path / "live"
    count = QUEUE_FRAMES + 4
    with live_video_result_writer(out, meta={"x": 1}) as writer:
        for f in range(3):
            writer.write(_frame(f), arrived=time.time())  # returns with the disk blocked
        assert writer.accepted == 3 and writer.frames == 0
        feeder = threading.Thread(target=lambda: [writer.write(_frame(f))
                                                  for f in range(3, count)])
        feeder.start()
        # one frame in the writer's hands, QUEUE_FRAMES waiting: then write() waits too
        _wait(lambda: writer.accepted == QUEUE_FRAMES + 1 and started == [0])
        time.sleep(0.2)
        assert writer.accepted == QUEUE_FRAMES + 1 and feeder.is_alive()
        gate.set()
        feeder.join(30)
        writer.flush()
        assert writer.frames == count and len(lfsam.load_result(out)) == count
    video = lfsam.load_result(out)
    assert video.complete and video.object_ids == [300 + f for f in range(count)]
    for f in range(count):
        np.testing.assert_array_equal(video.labels[f], _frame(f).labels)
    assert len(writer.write_seconds) == count and len(writer.disk_latencies) == 3
    assert _files(out) == sorted([RESULT_MARKER, *(frame_name(f) for f in range(count))])


@pytest.mark.parametrize("ending", [RuntimeError, KeyboardInterrupt])
def test_an_error_or_ctrl_c_mid_stream_still_writes_every_frame(tmp_path, monkeypatch, ending):
    gate, _ = _gate(monkeypatch)
    out = tmp_path / "live"
    with pytest.raises(ending):
        with live_video_result_writer(out) as writer:
            for f in range(4):
                writer.write(_frame(f))
            assert writer.frames == 0
            threading.Timer(0.2, gate.set).start()  # the disk catches up while the block ends
            raise ending
    video = lfsam.load_result(out)
    assert video.complete and len(video) == 4
    assert _files(out) == sorted([RESULT_MARKER, *(frame_name(f) for f in range(4))])


def test_a_failed_write_is_raised_in_the_tracking_thread_and_leaves_no_partial_file(
        tmp_path, monkeypatch):
    save = video_result.save_result

    def full_disk(result, path, **kwargs):
        if result.meta["frame"] == 2:
            raise OSError(28, "No space left on device")
        return save(result, path, **kwargs)

    monkeypatch.setattr(video_result, "save_result", full_disk)
    out = tmp_path / "live"
    with pytest.raises(OSError, match="No space"):
        with live_video_result_writer(out) as writer:
            for f in range(5):
                writer.write(_frame(f))
                time.sleep(0.05)
    video = lfsam.load_result(out)  # the frames before the failure, no gap, no partial file
    assert len(video) == 2 and video.complete
    assert _files(out) == sorted([RESULT_MARKER, frame_name(0), frame_name(1)])


def test_a_real_save_failure_leaves_no_partial_file(tmp_path, monkeypatch):
    """save_result's own atomic write: a failure inside the .npz writer leaves nothing."""
    def boom(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(lfsam.result, "write_npz", boom)
    out = tmp_path / "live"
    with pytest.raises(OSError):
        with live_video_result_writer(out) as writer:
            writer.write(_frame(0))
    assert not out.exists()  # no frame written: no folder, no temporary file
    assert list(tmp_path.iterdir()) == []


def test_the_file_holds_the_frame_as_handed_over_whatever_the_caller_changes(
        tmp_path, monkeypatch):
    gate, _ = _gate(monkeypatch)
    out = tmp_path / "live"
    frame = _frame(0)
    with live_video_result_writer(out) as writer:
        writer.write(frame)
        frame.labels[:] = 7  # e.g. a viewer painting its labels layer while the file waits
        frame.meta["frame"] = 99
        gate.set()
    written = lfsam.load_result(out).frame(0)
    np.testing.assert_array_equal(written.labels, _frame(0).labels)
    assert written.meta == {"frame": 0}


def test_a_ctrl_c_while_the_end_waits_for_the_disk_finishes_the_file_in_progress(
        tmp_path, monkeypatch):
    gate, started = _gate(monkeypatch)
    out = tmp_path / "live"
    with pytest.raises(KeyboardInterrupt):
        with live_video_result_writer(out) as writer:
            for f in range(4):
                writer.write(_frame(f))
            _wait(lambda: started == [0])  # frame 0's file under way, 3 queued
            join = writer._queue.join

            def interrupted_once():  # Ctrl-C while the block's end waits for the disk
                writer._queue.join = join
                threading.Timer(0.2, gate.set).start()
                raise KeyboardInterrupt

            writer._queue.join = interrupted_once
    video = lfsam.load_result(out)
    assert video.complete and len(video) == 1 and started == [0]  # the rest left unwritten
    assert _files(out) == [frame_name(0), RESULT_MARKER]
