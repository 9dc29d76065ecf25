"""Following a frames folder that is still growing: a light-field camera's stream
(docs/design.md section 10, issue 35).

:class:`FrameFollower` watches a folder of frames (each any light field lfsam reads, the
entries :func:`lfsam.video.io.frames_folder.frame_entries` counts) and yields each new frame as it
lands, in arrival order (frames found together: in natural name order). A frame counts once its
entry is there, so writers put complete frames in by renaming (a file or a folder of views
written under a hidden or other name — ``.frame_7.npz``, ``frame_7.npz.part`` — and renamed to
``frame_7.npz``). The folder is polled (every :attr:`FrameFollower.poll` seconds; no
platform-specific file notification), which is what bounds the arrival time's precision.

The stream ends (:attr:`FrameFollower.ended_by`):

- ``"END"``: a file named ``END`` appears in the folder (the frames already there are yielded
  first);
- ``"timeout"``: ``timeout`` seconds pass without a new frame while the follower waits;
- ``"stopped"``: :meth:`FrameFollower.stop` is called (from another thread: the viewer's Stop).
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from lfsam.errors import LfsamError
from lfsam.video.io.frames_folder import frame_entries

__all__ = ["END_FILE", "ArrivedFrame", "FrameFollower", "check_follow_folder"]

#: The file whose appearance ends a followed stream.
END_FILE = "END"


@dataclass(frozen=True)
class ArrivedFrame:
    """A frame entry that has landed in the followed folder.

    Attributes
    ----------
    index : int
        Its place in arrival order (0 for the first).
    path : Path
        The entry (a light-field file or folder).
    arrived : float
        When it landed (``time.time()``), as closely as polling tells: its modification time,
        but not before the previous look at the folder that did not see it (nor after the look
        that did). Never later than the true arrival, so latencies are never understated.
    """

    index: int
    path: Path
    arrived: float


def check_follow_folder(folder: str | os.PathLike) -> Path:
    """The folder to follow, which must exist (frames may already be in it).

    Raises
    ------
    LfsamError
        One line naming the path and the fix.
    """
    folder = Path(folder)
    if not folder.is_dir():
        what = "is not a folder" if folder.exists() else "does not exist"
        raise LfsamError(
            f"--follow watches a frames folder, and {str(folder)!r} {what}; create the folder "
            "the camera writes its frames into (one light field per frame, renamed in when "
            "complete) and start lfsam on it"
        )
    return folder


class FrameFollower:
    """Yield the frames of a growing folder as they land (see the module docstring).

    Parameters
    ----------
    folder : path-like
        The frames folder (:func:`check_follow_folder`).
    timeout : float, optional
        End after this many seconds without a new frame (None: wait until ``END`` or
        :meth:`stop`).
    poll : float
        Seconds between looks at the folder.

    Examples
    --------
    >>> follower = FrameFollower("frames", timeout=30)  # doctest: +SKIP
    >>> for frame in follower:  # doctest: +SKIP
    ...     print(frame.index, frame.path.name)
    >>> follower.ended_by  # doctest: +SKIP
    'END'
    """

    def __init__(self, folder: str | os.PathLike, *, timeout: float | None = None,
                 poll: float = 0.05) -> None:
        if timeout is not None and not timeout > 0:
            raise LfsamError(f"--follow-timeout must be a positive number of seconds, "
                             f"not {timeout}")
        self.folder = check_follow_folder(folder)
        self.timeout = timeout
        self.poll = float(poll)
        #: ``"END"``, ``"timeout"`` or ``"stopped"`` once the iteration is over.
        self.ended_by: str | None = None
        self._seen: set[str] = set()
        self._stop = threading.Event()
        self._busy = False
        self._waiting_since = time.monotonic()

    def stop(self) -> None:
        """End the stream at the next look (thread-safe); the frame being yielded is kept."""
        self._stop.set()

    @property
    def stopping(self) -> bool:
        """Whether :meth:`stop` was called."""
        return self._stop.is_set()

    def set_busy(self, busy: bool) -> None:
        """Tell the follower, iterated in a thread of its own, that frames it yielded are still
        being read or segmented (:class:`lfsam.video.stream.feed.FrameFeed`): the timeout counts
        only the time without a new frame while nothing is being done, and restarts when the
        consumer becomes idle (thread-safe)."""
        if self._busy and not busy:
            self._waiting_since = time.monotonic()
        self._busy = bool(busy)

    def _new_entries(self) -> list[Path]:
        try:
            return frame_entries(self.folder, skip=self._seen)
        except OSError as exc:
            raise LfsamError(f"cannot list the followed folder {str(self.folder)!r}: "
                             f"{exc}") from None

    def __iter__(self) -> Iterator[ArrivedFrame]:
        index = 0
        self._waiting_since = time.monotonic()
        previous_look = time.time()
        while True:
            if self._stop.is_set():
                self.ended_by = "stopped"
                return
            ended = (self.folder / END_FILE).exists()  # looked at before the listing
            look = time.time()
            fresh = self._new_entries()
            if fresh:
                arrived = [min(max(_mtime(entry, look), previous_look), look) for entry in fresh]
                for entry in fresh:
                    self._seen.add(entry.name)
                previous_look = look
                for entry, when in zip(fresh, arrived, strict=True):
                    yield ArrivedFrame(index, entry, when)
                    index += 1
                    if self._stop.is_set():
                        break
                self._waiting_since = time.monotonic()
                continue
            previous_look = look
            if ended:
                self.ended_by = END_FILE
                return
            if (self.timeout is not None and not self._busy
                    and time.monotonic() - self._waiting_since >= self.timeout):
                self.ended_by = "timeout"
                return
            self._stop.wait(self.poll)


def _mtime(entry: Path, default: float) -> float:
    try:
        return entry.stat().st_mtime
    except OSError:
        return default
