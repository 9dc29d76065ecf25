"""What a live run says about objects not found (issue 47; docs/design.md section 10): the
objects searched for in each frame, since when, and at the end each object's hidden frames.
Used by ``lfsam segment --follow``'s per-frame lines and the viewer's Follow status, so both
say it the same way."""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

__all__ = ["HiddenSince", "hidden_frames_text", "hidden_now"]


class HiddenSince:
    """Each hidden object's first frame of its current run of hidden frames, frame by frame.

    Examples
    --------
    >>> runs = HiddenSince()
    >>> runs.update(3, [5])
    '; searching for 5 (hidden since frame 3)'
    >>> runs.update(4, [2, 5])
    '; searching for 2 (hidden since frame 4), 5 (hidden since frame 3)'
    >>> runs.update(5, [])
    ''
    """

    def __init__(self) -> None:
        self.since: dict[int, int] = {}

    def update(self, index: int, hidden: Iterable[int]) -> str:
        """Frame ``index``'s hidden object ids (``meta["tracks"]`` states ``"hidden"``): the
        note for that frame's line (empty where none is hidden)."""
        ids = sorted(int(i) for i in hidden)
        self.since = {i: self.since.get(i, index) for i in ids}
        if not ids:
            return ""
        return "; searching for " + ", ".join(
            f"{i} (hidden since frame {self.since[i]})" for i in ids)


def hidden_now(states: Mapping[str, str]) -> list[int]:
    """The ids a frame's ``meta["tracks"]`` gives as hidden."""
    return sorted(int(i) for i, state in states.items() if state == "hidden")


def hidden_frames_text(spans: Mapping[str, Sequence[Sequence[int]]]) -> str:
    """The end of a stream's line: each object's runs of hidden frames
    (:func:`lfsam.video.io.result.hidden_spans`), empty where none was hidden.

    Examples
    --------
    >>> hidden_frames_text({"2": [[4, 6]], "5": [[3, 3], [7, 8]]})
    '; hidden: object 2 in frame(s) 4-6; object 5 in frame(s) 3, 7-8'
    """
    if not spans:
        return ""
    return "; hidden: " + "; ".join(
        f"object {i} in frame(s) " + ", ".join(f"{a}-{b}" if b > a else f"{a}" for a, b in runs)
        for i, runs in spans.items())
