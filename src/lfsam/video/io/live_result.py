"""A video result written *in place* while a stream runs (issues 35 and 44; docs/design.md
section 10): :func:`live_video_result_writer` writes each frame's file behind the tracking
thread and keeps the manifest valid at every moment, so :func:`lfsam.load_result` reads the
frames done while the stream goes on; :func:`check_live_folder` checks ``--out`` before a
stream starts. The format is :mod:`lfsam.video.io.result`'s; this module adds the writer thread.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import json
import os
import queue
import shutil
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from lfsam.errors import LfsamError
from lfsam.fileutil import atomic_output
from lfsam.prompts import ObjectPrompts
from lfsam.result import SegmentationResult, label_storage_dtype
from lfsam.video.io.result import RESULT_MARKER, FrameWriter, check_result_folder

__all__ = ["check_live_folder", "live_video_result_writer"]


def check_live_folder(path: str | os.PathLike) -> Path:
    """Check that a live video result can be written to ``path``: a new name or an empty
    folder, in an existing parent folder (a live result is written in place, so an earlier
    result is never overwritten).

    Raises
    ------
    LfsamError
        One line naming the problem and the fix.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise LfsamError(f"{str(path)!r} is a file; a followed stream writes a folder (one "
                         "result per frame): give a new folder name")
    if not path.exists():
        check_result_folder(path)  # the suffix and the parent folder
    elif any(path.iterdir()):
        raise LfsamError(
            f"{str(path)!r} is not empty; a followed stream writes its frames into --out as "
            "they are done, so give a new folder name (or remove the old one)"
        )
    return path


#: Frames a live writer holds at most before :meth:`_LiveWriter.write` waits for the disk.
QUEUE_FRAMES = 4
#: Seconds the writer thread waits for a frame before it looks at its queue again.
WAKE = 0.2
#: The manifest is rewritten once the writer has caught up, or at the latest after this many
#: frames (rewriting it costs in the number of frames so far).
PUBLISH_EVERY = 8
_STOP = object()


class _LiveWriter(FrameWriter):
    """Writes each frame into the result folder itself, in a thread of its own (write-behind,
    issue 44), and updates the manifest after it (see :func:`live_video_result_writer`)."""

    def __init__(self, folder: Path, meta: dict[str, Any],
                 objects: Callable[[], Sequence[ObjectPrompts]] | None,
                 queue_frames: int = QUEUE_FRAMES) -> None:
        super().__init__(folder)
        self.meta = meta
        self.objects = objects
        #: Held while the manifest is built; whoever changes ``meta`` during the stream holds it.
        self.lock = threading.Lock()
        #: Frames handed to :meth:`write` (``frames`` counts those on disk).
        self.accepted = 0
        #: Seconds each frame's file took (the manifest's rewrites not counted), in order.
        self.write_seconds: list[float] = []
        #: Seconds from each frame's arrival (as given to :meth:`write`) to its file on disk.
        self.disk_latencies: list[float] = []
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=max(1, int(queue_frames)))
        self._error: BaseException | None = None
        self._abandon = threading.Event()
        self._unpublished = 0
        self._thread = threading.Thread(target=self._run, name="lfsam-result-writer",
                                        daemon=True)
        self._thread.start()

    def write(self, result: SegmentationResult, arrived: float | None = None) -> None:
        """Hand over the next frame: checked now, written by the writer thread (this waits only
        while :data:`QUEUE_FRAMES` frames are still to write; no frame is ever dropped).

        Parameters
        ----------
        result : SegmentationResult
        arrived : float, optional
            The frame's arrival (``time.time()``), for :attr:`disk_latencies`.

        Raises
        ------
        LfsamError
            Labels of another shape than the first frame's.
        Exception
            Whatever made the writer thread fail on an earlier frame (a full disk).
        """
        self._raise_error()
        self.check(result, self.accepted)
        self._queue.put((_owned(result), arrived))
        self.accepted += 1

    def flush(self) -> None:
        """Wait until every frame handed over is on disk and in the manifest. A Ctrl-C while
        waiting leaves the frames not yet started unwritten (as :meth:`close`) and is raised
        again.

        Raises
        ------
        Exception
            Whatever made the writer thread fail.
        """
        try:
            self._queue.join()
        except KeyboardInterrupt:
            self._abandon.set()
            raise
        self._raise_error()

    def close(self) -> None:
        """Write every frame still queued, then stop the thread (idempotent). A Ctrl-C while
        waiting leaves the frames not yet started unwritten (the one being written finishes:
        no partial file) and is raised again."""
        if not self._thread.is_alive():
            return
        self._queue.put(_STOP)
        try:
            self._thread.join()
        except KeyboardInterrupt:
            self._abandon.set()
            self._thread.join()
            raise

    def publish(self, complete: bool) -> None:
        """Write the manifest of the frames on disk so far, atomically."""
        with self.lock:
            objects = None if self.objects is None else self.objects()
            text = json.dumps(self.manifest(self.meta, objects, complete=complete), indent=1,
                              default=str)
        with atomic_output(self.folder / RESULT_MARKER) as tmp:
            Path(tmp).write_text(text, encoding="utf-8")
        self._unpublished = 0

    def _raise_error(self) -> None:
        if self._error is not None:
            raise self._error

    def _run(self) -> None:
        """The writer thread: each frame's file, then the manifest once caught up. It looks
        at the queue again every :data:`WAKE` seconds: a Ctrl-C that stops the tracking
        thread inside ``put``, after the frame is queued and before the wake-up call, must
        not leave it waiting for ever (and the tracking thread in ``flush`` or ``close``)."""
        while True:
            try:
                item = self._queue.get(timeout=WAKE)
            except queue.Empty:
                continue
            try:
                if item is _STOP:
                    return
                if self._error is None and not self._abandon.is_set():
                    self._store(*item)
            except BaseException as exc:  # handed to the tracking thread (write, flush)
                self._error = exc
            finally:
                self._queue.task_done()

    def _store(self, result: SegmentationResult, arrived: float | None) -> None:
        start = time.perf_counter()
        self.store(result)
        self.write_seconds.append(time.perf_counter() - start)
        if arrived is not None:
            self.disk_latencies.append(time.time() - arrived)
        self._unpublished += 1
        if self._queue.qsize() == 0 or self._unpublished >= PUBLISH_EVERY:
            self.publish(complete=False)


def _owned(result: SegmentationResult) -> SegmentationResult:
    """``result`` with its labels and meta copied for the writer thread (the caller, e.g. the
    viewer's labels layer, may change its own while the file is written): the labels in their
    storage dtype (:func:`lfsam.result.label_storage_dtype`: uint8 for a few objects, about 2 ms
    for a 5x5x480x640 frame), which is also what the file holds."""
    labels = np.asarray(result.labels)
    if labels.dtype.kind not in "iu":
        labels = labels.astype(np.int32)
    return dataclasses.replace(result, labels=labels.astype(label_storage_dtype(labels)),
                               meta=copy.deepcopy(result.meta))


@contextlib.contextmanager
def live_video_result_writer(
    path: str | os.PathLike, meta: dict[str, Any] | None = None,
    objects: Callable[[], Sequence[ObjectPrompts]] | None = None,
) -> Iterator[_LiveWriter]:
    """Write a video result frame by frame *in place*, readable while it grows (a followed
    stream, issue 35), the files written behind the tracking thread (issue 44).

    ``writer.write(result)`` checks the frame and hands it to a writer thread (a bounded queue
    of :data:`QUEUE_FRAMES` frames: it waits when the disk is that far behind, and never drops
    a frame), which writes each frame's file atomically (zlib level
    :data:`lfsam.result.FAST_LEVEL`) and then rewrites the manifest atomically with
    ``"complete": false`` once it has caught up (at the latest every :data:`PUBLISH_EVERY`
    frames), so :func:`load_video_result` sees a valid result of the frames on disk at any
    moment (also after a crash or a kill); ``writer.flush()`` waits for all of them. On leaving
    the block, whatever ended it (the stream's end, an error, Ctrl-C), every frame handed over
    is written, then the manifest once more with ``"complete": true``; a folder that received
    no frame is removed. A failed write (a full disk) stops the writing and is raised in the
    calling thread by the next ``write``, ``flush`` or the block's end. ``writer.lock`` guards
    ``meta`` while the manifest is built: change it only holding the lock during a stream.

    Parameters
    ----------
    path : path-like
        The result folder (:func:`check_live_folder`: new or empty).
    meta : dict, optional
        The manifest's ``meta``, read at every manifest (so it may be completed meanwhile,
        under ``writer.lock``).
    objects : callable, optional
        Returns the objects' prompts so far (they may grow during the stream), kept as
        ``meta["objects"]``.
    """
    path = check_live_folder(path)
    created = not path.exists()
    path.mkdir(exist_ok=True)
    writer = _LiveWriter(path, meta if meta is not None else {}, objects)
    try:
        yield writer
        writer.flush()
    finally:
        try:
            writer.close()  # a Ctrl-C here still leaves a complete manifest (below)
        finally:
            if writer.frames:
                writer.publish(complete=True)
            elif created:
                shutil.rmtree(path, ignore_errors=True)
