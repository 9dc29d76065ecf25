"""Prompts of a light-field video: which prompts belong to which frame (docs/design.md
section 10).

An object's prompts carry frames (:attr:`lfsam.prompts.PointPrompt.frame`, None = 0). The
object starts at the first frame that holds one of its positive points or its box (it is
absent before); a frame with prompts of its own re-prompts the object there (positive prompts
replace the carried ones); a negative click at frame F corrects frame F and, carried along with
the mask, the frames after it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

from lfsam.prompts import ObjectPrompts, PointPrompt

__all__ = ["frame_of", "latest_prompts", "negatives_since", "prompts_at", "start_frame"]


def frame_of(prompt) -> int:
    """A point's or box's frame (None reads as 0)."""
    return 0 if prompt.frame is None else int(prompt.frame)


def start_frame(obj: ObjectPrompts) -> int | None:
    """The first frame with a positive point or the box of ``obj`` (None: never started).

    Examples
    --------
    >>> from lfsam.prompts import PointPrompt
    >>> start_frame(ObjectPrompts(1, (PointPrompt(3, 4, True, None, 2),)))
    2
    """
    frames = [frame_of(p) for p in obj.points if p.positive]
    if obj.box is not None:
        frames.append(frame_of(obj.box))
    return min(frames) if frames else None


def prompts_at(obj: ObjectPrompts, frame: int) -> ObjectPrompts | None:
    """The prompts ``obj`` was given at ``frame``, frame tags removed (None: none there)."""
    points = tuple(replace(p, frame=None) for p in obj.points if frame_of(p) == frame)
    box = obj.box if obj.box is not None and frame_of(obj.box) == frame else None
    if not points and box is None:
        return None
    return ObjectPrompts(obj.obj_id, points, None if box is None else replace(box, frame=None))


def latest_prompts(obj: ObjectPrompts, frame: int) -> ObjectPrompts | None:
    """The prompts of the latest frame up to ``frame`` that gives ``obj`` a positive point or
    its box, frame tags removed (None: none so far): what an object whose prompts were never
    answered is asked again (issue 47, :func:`lfsam.video.tracking.frame_search.search_frame`).

    Examples
    --------
    >>> from lfsam.prompts import PointPrompt
    >>> obj = ObjectPrompts(1, (PointPrompt(3, 4), PointPrompt(5, 6, True, None, 2)))
    >>> latest_prompts(obj, 1).points[0].x, latest_prompts(obj, 5).points[0].x
    (3, 5)
    """
    frames = [frame_of(p) for p in obj.points if p.positive and frame_of(p) <= frame]
    if obj.box is not None and frame_of(obj.box) <= frame:
        frames.append(frame_of(obj.box))
    return prompts_at(obj, max(frames)) if frames else None


def negatives_since(obj: ObjectPrompts, frame: int) -> Sequence[PointPrompt]:
    """The negative clicks of ``obj`` given at frames up to ``frame`` (frame tags removed):
    a correction holds from its frame onwards."""
    return tuple(replace(p, frame=None) for p in obj.points
                 if not p.positive and frame_of(p) <= frame)
