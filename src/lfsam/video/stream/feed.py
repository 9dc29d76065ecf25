"""Frames of a followed stream read ahead, and (``latest``) only the newest
(docs/design.md section 10, issue 44; used by :func:`lfsam.video.stream.live.segment_stream`).

:class:`FrameFeed` stands between a :class:`lfsam.video.stream.follow.FrameFollower` and the
tracker. Two threads of its own keep the camera's side moving while a frame is segmented:

- the *follow* thread iterates the follower and queues each arrived entry (a path: cheap);
- the *prefetch* thread takes the next queued entry and reads (decodes) its light field, so
  that the frame after the current one is ready when the tracker asks for it. At most one
  decoded frame waits (memory stays flat however far the camera runs ahead).

With ``latest=True`` the tracker never works through a backlog: the prefetch thread always
takes the newest entry that has arrived, and a read-ahead frame that a newer arrival makes
stale before the tracker takes it is replaced by the newer one, read just in time for the
tracker's next request (from the last quarter of its average period between requests: reading
every arrival at once would take CPU time from the tracker for frames superseded again before
it asks; until the tracker has finished a frame, every arrival is read); and if a newer frame
has still come by the tracker's request and a read is cheap next to its period, it waits for
that read instead of taking an older frame. Every frame left
out that way is reported through ``on_superseded`` (in the consumer's thread, before the
frame that replaced it is yielded), so the result lists each one by name with the reason
``"newer frame available"``. Without ``latest`` every frame is yielded in arrival order.

A frame that cannot be read is yielded with its error (:meth:`ReadFrame.lightfield` raises
it), so the consumer skips it as before. While frames are queued, being read or being
segmented the follower's ``--follow-timeout`` does not run (:meth:`FrameFollower.set_busy`):
the timeout counts only the time the whole stream waits for the camera.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from lfsam.lightfield import LightField
from lfsam.video.stream.follow import ArrivedFrame, FrameFollower

__all__ = ["NEWER_FRAME", "FrameFeed", "ReadFrame"]

#: The reason recorded for a frame left out because a newer one had arrived.
NEWER_FRAME = "newer frame available"
#: With ``latest``, a newer arrival replaces the frame read ahead from this fraction of the
#: consumer's average period on (:meth:`FrameFeed._replace_at`).
JUST_IN_TIME = 0.75
#: With ``latest``, the consumer waits for a newer frame's read at its request when a read
#: takes under this fraction of its period (:meth:`FrameFeed._fresher_is_cheap`).
FRESH_READ = 0.2


@dataclass
class ReadFrame:
    """An arrived frame and its light field as read ahead (or the error reading it raised)."""

    arrived: ArrivedFrame
    _lightfield: LightField | None = None
    _error: BaseException | None = None

    def lightfield(self) -> LightField:
        """The frame's light field; raises what reading it raised."""
        if self._error is not None:
            raise self._error
        assert self._lightfield is not None
        return self._lightfield


class FrameFeed:
    """Yield :class:`ReadFrame` items from ``follower``, read ahead (see the module docstring).

    Parameters
    ----------
    follower : FrameFollower
        The followed folder; it decides when the stream ends.
    read : callable
        ``read(arrived) -> LightField``, called in the prefetch thread; an exception it
        raises is handed to the consumer with the frame (:meth:`ReadFrame.lightfield` raises
        it in the consumer's thread, which decides whether the frame is skipped).
    latest : bool
        Always take the newest arrived frame; older waiting frames are superseded.
    on_superseded : callable, optional
        ``on_superseded(arrived)`` for each frame left out for a newer one (consumer's thread).

    Examples
    --------
    >>> feed = FrameFeed(FrameFollower("frames"), read, latest=True)  # doctest: +SKIP
    >>> for item in feed:  # doctest: +SKIP
    ...     lf = item.lightfield()
    """

    def __init__(self, follower: FrameFollower, read: Callable[[ArrivedFrame], LightField], *,
                 latest: bool = False,
                 on_superseded: Callable[[ArrivedFrame], None] | None = None) -> None:
        self.follower = follower
        self.read = read
        self.latest = bool(latest)
        self.on_superseded = on_superseded
        self._cond = threading.Condition()
        self._queued: list[ArrivedFrame] = []  # arrived, not yet taken for reading
        self._ready: ReadFrame | None = None  # read ahead, not yet yielded
        self._superseded: list[ArrivedFrame] = []  # left out, not yet reported
        self._unreadable: list[ReadFrame] = []  # set aside by a newer frame, still yielded
        self._reading = False
        self._consuming = False
        self._followed = False  # the follower's iteration is over
        self._closed = False
        self._failure: BaseException | None = None
        #: The most decoded frames held at once by the feed (ready plus being read): at most 2.
        self.peak_held = 0
        self._period: float | None = None  # the consumer's time between requests (average)
        self._last_request = time.monotonic()
        self._read_time = 0.0  # the time one read takes (average)
        self._ready_started = 0.0  # when the read of the frame read ahead began
        self._waiting = False  # the consumer waits for a frame

    # --- the threads -------------------------------------------------------------------------
    def _follow(self) -> None:
        try:
            for arrived in self.follower:
                with self._cond:
                    if self._closed:
                        return
                    self._queued.append(arrived)
                    self._update_busy()
                    self._cond.notify_all()
        except BaseException as exc:  # handed to the consumer
            with self._cond:
                self._failure = exc
        finally:
            with self._cond:
                self._followed = True
                self._cond.notify_all()

    def _read_newest_in(self) -> float:
        """With ``latest`` and a newer frame queued: seconds until it should be read (<= 0:
        now). At once while the consumer waits or its pace is not known yet; otherwise just
        in time for its next request (from :data:`JUST_IN_TIME` of its average period between
        requests on, less the time a read takes), once, and again only if the frame read
        then has aged a quarter period (the consumer is late). Reading every arrival at once
        would take CPU time from the tracker for frames superseded again before it asks;
        reading none would hand it a frame up to a whole period old."""
        if self._waiting or self._period is None or (
                self._ready is None and not self._consuming):
            return 0.0
        now = time.monotonic()
        due = self._last_request + JUST_IN_TIME * self._period - 1.5 * self._read_time
        if self._ready is not None:
            due = max(due, self._ready_started + 0.25 * self._period) if (
                self._ready_started >= due) else due
        return due - now

    def _take(self) -> ArrivedFrame | None:
        """The next entry to read (under the lock), None when nothing more will come."""
        while True:
            if self._closed or self._failure is not None:
                return None
            if self._queued and not self.latest and self._ready is None:
                break
            if self._queued and self.latest:
                wait = self._read_newest_in()
                if wait <= 0:
                    break
                self._cond.wait(wait)
                continue
            if self._followed and not self._queued:
                return None
            self._cond.wait()
        if self.latest:
            self._superseded.extend(self._queued[:-1])
            self._queued = self._queued[-1:]
        self._reading = True
        return self._queued.pop(0)

    def _prefetch(self) -> None:
        try:
            while True:
                with self._cond:
                    arrived = self._take()
                    if arrived is None:
                        return
                    self.peak_held = max(self.peak_held, 1 + (self._ready is not None))
                began = time.monotonic()
                try:
                    item = ReadFrame(arrived, self.read(arrived))
                except Exception as exc:  # the consumer decides
                    item = ReadFrame(arrived, None, exc)
                with self._cond:
                    self._read_time = 0.7 * self._read_time + 0.3 * (time.monotonic() - began)
                    self._reading = False
                    if self._ready is not None:  # latest: the frame read before is older
                        self._set_aside(self._ready)
                    self._ready, self._ready_started = item, began
                    self._cond.notify_all()
        except BaseException as exc:  # handed to the consumer
            with self._cond:
                self._failure = exc
                self._cond.notify_all()
        finally:
            with self._cond:
                self._reading = False
                self._cond.notify_all()

    def _fresher_is_cheap(self) -> bool:
        """With ``latest``, at the consumer's request: a frame newer than the one read ahead
        has arrived and a read takes under :data:`FRESH_READ` of the consumer's period, so the
        consumer waits for the newer frame's read rather than take one that aged (once per
        request: frames arriving during that read do not make it wait again)."""
        return (self.latest and self._ready is not None and bool(self._queued)
                and self._period is not None and self._read_time < FRESH_READ * self._period)

    def _set_aside(self, item: ReadFrame) -> None:
        """A read frame that a newer one replaces: superseded, or (unreadable) still yielded
        so that the consumer skips it for what it is."""
        if item._error is not None:
            self._unreadable.append(item)
        else:
            self._superseded.append(item.arrived)

    def _update_busy(self) -> None:
        self.follower.set_busy(bool(self._queued or self._reading or self._ready is not None
                                    or self._unreadable or self._consuming))

    # --- the consumer ------------------------------------------------------------------------
    def __iter__(self) -> Iterator[ReadFrame]:
        follow = threading.Thread(target=self._follow, name="lfsam-feed-follow", daemon=True)
        prefetch = threading.Thread(target=self._prefetch, name="lfsam-feed-prefetch", daemon=True)
        follow.start()
        prefetch.start()
        try:
            while True:
                with self._cond:
                    now = time.monotonic()
                    if self._consuming:  # the consumer's period between requests
                        took = now - self._last_request
                        self._period = took if self._period is None else \
                            0.7 * self._period + 0.3 * took
                    self._last_request = now
                    self._consuming = False
                    self._update_busy()
                    self._waiting = True
                    self._cond.notify_all()
                    stale = self._ready if self._fresher_is_cheap() else None
                    while ((self._ready is None or self._ready is stale) and not self._unreadable
                           and self._failure is None
                           and not (self._followed and not self._queued and not self._reading)):
                        self._cond.wait(0.1)  # a timeout keeps Ctrl-C responsive
                    self._waiting = False
                    superseded, self._superseded = self._superseded, []
                    if self._unreadable:
                        item = self._unreadable.pop(0)
                    else:
                        item, self._ready = self._ready, None
                    failure = self._failure
                    self._consuming = item is not None
                    self._update_busy()
                    self._cond.notify_all()
                if self.on_superseded is not None:
                    for arrived in superseded:
                        self.on_superseded(arrived)
                if failure is not None:
                    raise failure
                if item is None:
                    return
                if self.follower.stopping:
                    return  # stopped: frames not yet started are dropped
                yield item
        finally:
            self.close()
            follow.join(timeout=5)
            prefetch.join(timeout=5)

    def close(self) -> None:
        """Stop both threads (frames not yet yielded are dropped)."""
        self.follower.stop()
        with self._cond:
            self._closed = True
            self._cond.notify_all()
