"""The prompt model of interactive light-field segmentation (docs/design.md section 8).

An object is a stable integer id (>= 1) with any number of positive and negative points and at
most one box, each tagged with the view ``(s, t)`` it was given in (0-based view row, view
column; ``None`` = the center view). Points and boxes are in the view's own pixels, ``x`` = pixel
column and ``y`` = pixel row, as in Meta's ``sam2``.

The object is segmented in its *reference view* (:meth:`ObjectPrompts.reference_view`: the view
of its box, else of its first positive point) and propagated from there to every other view
(paper section 3.2, from any view instead of the center).

A prompt file is JSON: a list of objects (or ``{"objects": [...]}``), for example::

    [
      {"id": 1, "points": [[160, 120], [150, 90]], "labels": [1, 0]},
      {"id": 2, "points": [[40, 60]], "view": [0, 8]},
      {"id": 3, "box": [20, 30, 120, 140], "points": [{"xy": [70, 80], "label": 1,
                                                       "view": [4, 4]}]}
    ]

``points`` are ``[x, y]`` pairs with a parallel ``labels`` list (1 = positive, 0 = negative;
default all positive) or objects ``{"xy": [x, y], "label": 1, "view": [s, t]}``; ``view`` on
the object is the default view of its points and box; ``box`` is ``[x0, y0, x1, y1]`` or
``{"xyxy": [...], "view": [s, t]}``. ``id`` is optional (default: position + 1).

A *text prompt* (docs/design.md section 9) is an entry ``{"text": "red cup"}``, optionally with
``"view": [s, t]`` (default: the reference view): a concept, not an object. The text detector
finds every instance of it in that view, and each instance becomes an object with the phrase as
its category (ids after every prompted object's). ``[{"text": "disc"}, {"id": 1, "points":
[[40, 60]]}]`` mixes both.

For a light-field video (docs/design.md section 10) every point and box may also carry a
``frame`` (0-based; on the object it is the default of its points and box; absent = frame 0),
e.g. ``{"id": 4, "points": [[30, 40]], "frame": 3}`` starts object 4 at frame 3, and
``{"xy": [12, 20], "label": 0, "frame": 5}`` is a negative click at frame 5. A single light
field takes frame 0 only.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from lfsam.errors import LfsamError
from lfsam.fileutil import atomic_output

__all__ = [
    "BoxPrompt",
    "ObjectPrompts",
    "PointPrompt",
    "Prompt",
    "TextPrompt",
    "check_phrase",
    "load_prompts",
    "prompts_from_json",
    "prompts_to_json",
    "save_prompts",
    "split_prompts",
    "validate_objects",
]

View = tuple[int, int]


@dataclass(frozen=True)
class PointPrompt:
    """One click: ``(x, y)`` = (pixel column, pixel row) in view ``view`` (None = center), in
    frame ``frame`` of a video (None = frame 0; docs/design.md section 10)."""

    x: float
    y: float
    positive: bool = True
    view: View | None = None
    frame: int | None = None


@dataclass(frozen=True)
class BoxPrompt:
    """A box ``(x0, y0, x1, y1)`` in view ``view`` (None = center), in frame ``frame`` of a
    video (None = frame 0)."""

    x0: float
    y0: float
    x1: float
    y1: float
    view: View | None = None
    frame: int | None = None

    @property
    def xyxy(self) -> tuple[float, float, float, float]:
        """``(x0, y0, x1, y1)``."""
        return self.x0, self.y0, self.x1, self.y1


@dataclass(frozen=True)
class ObjectPrompts:
    """The prompts of one object: points (positive and negative) and at most one box.

    Parameters
    ----------
    obj_id : int
        Stable id >= 1; it becomes the object's label value.
    points : tuple of PointPrompt
    box : BoxPrompt, optional
    """

    obj_id: int
    points: tuple[PointPrompt, ...] = field(default_factory=tuple)
    box: BoxPrompt | None = None

    def reference_view(self, center: View) -> View:
        """The view the object is segmented in: its box's view, else its first positive
        point's view (``center`` for untagged prompts)."""
        if self.box is not None:
            return _view_or(self.box.view, center)
        for point in self.points:
            if point.positive:
                return _view_or(point.view, center)
        return center

    @property
    def has_positive(self) -> bool:
        """Whether the object has a positive point or a box (negatives alone select nothing)."""
        return self.box is not None or any(p.positive for p in self.points)

    def with_points(self, points: Iterable[PointPrompt]) -> ObjectPrompts:
        """A copy with ``points`` appended."""
        return ObjectPrompts(self.obj_id, (*self.points, *points), self.box)

    def with_box(self, box: BoxPrompt | None) -> ObjectPrompts:
        """A copy with its box replaced."""
        return ObjectPrompts(self.obj_id, self.points, box)

    def views(self, center: View) -> set[View]:
        """Every view in which this object has a prompt."""
        out = {_view_or(p.view, center) for p in self.points}
        if self.box is not None:
            out.add(_view_or(self.box.view, center))
        return out

    def resolved(self, center: View) -> ObjectPrompts:
        """A copy with every untagged prompt tagged with ``center``."""
        box = self.box
        if box is not None and box.view is None:
            box = replace(box, view=center)
        points = tuple(p if p.view is not None else replace(p, view=center) for p in self.points)
        return ObjectPrompts(self.obj_id, points, box)


@dataclass(frozen=True)
class TextPrompt:
    """A concept to find: every instance of ``phrase`` in view ``view`` (None = the reference
    view) becomes an object whose category is the phrase (docs/design.md section 9)."""

    phrase: str
    view: View | None = None

    def resolved_view(self, center: View) -> View:
        """The view the detector runs in (``center`` when untagged)."""
        return _view_or(self.view, center)


Prompt = ObjectPrompts | TextPrompt
"""Anything a prompt file or :func:`lfsam.segment` takes: an object or a concept."""


def check_phrase(phrase: object) -> str:
    """A text prompt's phrase with runs of white space made single spaces.

    Raises
    ------
    LfsamError
        If it is not a string or holds no word.
    """
    if not isinstance(phrase, str) or not phrase.split():
        raise LfsamError(
            f"a text prompt needs a phrase with at least one word (e.g. \"red cup\"), "
            f"got {phrase!r}"
        )
    return " ".join(phrase.split())


def split_prompts(prompts: Iterable[Prompt]) -> tuple[list[ObjectPrompts], list[TextPrompt]]:
    """The objects and the text prompts of a mixed list, each in its order."""
    objects: list[ObjectPrompts] = []
    texts: list[TextPrompt] = []
    for item in prompts:
        (texts if isinstance(item, TextPrompt) else objects).append(item)
    return objects, texts


def _view_or(view: View | None, default: View) -> View:
    return default if view is None else (int(view[0]), int(view[1]))


# --- validation ----------------------------------------------------------------------------------
def validate_objects(
    objects: Sequence[Prompt], grid_shape: View, view_shape: View, num_frames: int = 1,
) -> None:
    """Check prompts against a light field: ids, views inside the grid, points inside the view,
    boxes non-empty, and at least one positive point or a box per object; text prompts: a
    phrase and a view inside the grid; frames (of a video of ``num_frames``; 1 = a single light
    field) from 0 to ``num_frames - 1``.

    Raises
    ------
    LfsamError
        One line naming the object and the field at fault.
    """
    s_count, t_count = grid_shape
    height, width = view_shape
    seen: set[int] = set()
    for obj in objects:
        if isinstance(obj, TextPrompt):
            check_phrase(obj.phrase)
            view = obj.view
            if view is not None and not (0 <= view[0] < s_count and 0 <= view[1] < t_count):
                raise LfsamError(
                    f"text {obj.phrase!r} is tagged with view {view[0]},{view[1]} outside the "
                    f"{s_count}x{t_count} grid (views are S,T = 0..{s_count - 1},"
                    f"0..{t_count - 1})"
                )
            continue
        name = f"object {obj.obj_id}"
        if not isinstance(obj.obj_id, (int, np.integer)) or obj.obj_id < 1:
            raise LfsamError(f"{name}: id must be an integer >= 1")
        if obj.obj_id in seen:
            raise LfsamError(f"{name}: id used twice; give every object its own id")
        seen.add(obj.obj_id)
        if not obj.has_positive:
            raise LfsamError(
                f"{name}: only negative points; add a positive point or a box (a negative "
                "point only removes what a positive prompt selects)"
            )
        _check_frames(obj, name, num_frames)
        tagged = [(f"point {i + 1}", p.view) for i, p in enumerate(obj.points)]
        if obj.box is not None:
            tagged.append(("box", obj.box.view))
        for what, view in tagged:
            if view is not None and not (0 <= view[0] < s_count and 0 <= view[1] < t_count):
                raise LfsamError(
                    f"{name}: {what} is tagged with view {view[0]},{view[1]} outside the "
                    f"{s_count}x{t_count} grid (views are S,T = 0..{s_count - 1},0..{t_count - 1})"
                )
        for i, p in enumerate(obj.points):
            if not (np.isfinite(p.x) and np.isfinite(p.y)):
                raise LfsamError(f"{name}: point {i + 1} has a non-finite coordinate")
            if not (0 <= p.x <= width - 1 and 0 <= p.y <= height - 1):
                raise LfsamError(
                    f"{name}: point {i + 1} X,Y = {p.x:g},{p.y:g} lies outside the view "
                    f"(columns 0..{width - 1}, rows 0..{height - 1}); points are X,Y = column,row"
                )
        if obj.box is not None:
            x0, y0, x1, y1 = obj.box.xyxy
            if not all(np.isfinite(obj.box.xyxy)):
                raise LfsamError(f"{name}: box has a non-finite coordinate")
            if not (x1 > x0 and y1 > y0):
                raise LfsamError(
                    f"{name}: box {x0:g},{y0:g},{x1:g},{y1:g} is empty; give X0,Y0,X1,Y1 with "
                    "X1 > X0 and Y1 > Y0"
                )
            if x1 < 0 or y1 < 0 or x0 > width - 1 or y0 > height - 1:
                raise LfsamError(
                    f"{name}: box {x0:g},{y0:g},{x1:g},{y1:g} lies outside the view "
                    f"(columns 0..{width - 1}, rows 0..{height - 1})"
                )


def _check_frames(obj: ObjectPrompts, name: str, num_frames: int) -> None:
    """Frame tags of one object: whole numbers in range (one line naming the prompt)."""
    tagged = [(f"point {i + 1}", p.frame) for i, p in enumerate(obj.points)]
    if obj.box is not None:
        tagged.append(("box", obj.box.frame))
    for what, frame in tagged:
        if frame is None:
            continue
        if isinstance(frame, bool) or not isinstance(frame, (int, np.integer)) or frame < 0:
            raise LfsamError(f"{name}: {what} has frame {frame!r}; frames are whole numbers >= 0")
        if frame >= num_frames:
            where = ("a single light field has frame 0 only" if num_frames == 1
                     else f"the video has frames 0..{num_frames - 1}")
            raise LfsamError(f"{name}: {what} is tagged with frame {frame}, but {where}")


# --- JSON ----------------------------------------------------------------------------------------
_OBJECT_KEYS = {"id", "points", "labels", "box", "view", "frame"}


def prompts_to_json(objects: Sequence[Prompt]) -> list[dict[str, Any]]:
    """JSON-ready list of objects (every point and box with its view) and text prompts, the
    prompt-file format."""
    out: list[dict[str, Any]] = []
    for obj in objects:
        if isinstance(obj, TextPrompt):
            out.append(
                {"text": obj.phrase, **({"view": list(obj.view)} if obj.view is not None else {})}
            )
            continue
        entry: dict[str, Any] = {
            "id": int(obj.obj_id),
            "points": [
                {
                    "xy": [float(p.x), float(p.y)],
                    "label": int(p.positive),
                    **({"view": list(p.view)} if p.view is not None else {}),
                    **({"frame": int(p.frame)} if p.frame is not None else {}),
                }
                for p in obj.points
            ],
        }
        if obj.box is not None:
            entry["box"] = {
                "xyxy": [float(v) for v in obj.box.xyxy],
                **({"view": list(obj.box.view)} if obj.box.view is not None else {}),
                **({"frame": int(obj.box.frame)} if obj.box.frame is not None else {}),
            }
        out.append(entry)
    return out


def prompts_from_json(data: Any) -> list[Prompt]:
    """Parse the prompt-file format (see the module docstring): objects and text prompts.

    Raises
    ------
    LfsamError
        One line naming the object and the field at fault (unknown keys, wrong types).
    """
    if isinstance(data, dict) and set(data) == {"objects"}:
        data = data["objects"]
    if not isinstance(data, list):
        raise LfsamError(
            "a prompt file holds a JSON list of objects (or {\"objects\": [...]}), got "
            f"{type(data).__name__}"
        )
    objects = []
    for index, entry in enumerate(data):
        name = f"object {index + 1}"
        if not isinstance(entry, dict):
            raise LfsamError(f"{name}: must be a JSON object, got {type(entry).__name__}")
        if isinstance(entry.get("id"), int) and not isinstance(entry.get("id"), bool):
            name = f"object {entry['id']}"
        if "text" in entry:
            objects.append(_parse_text(entry, index))
            continue
        unknown = sorted(set(entry) - _OBJECT_KEYS)
        if unknown:
            raise LfsamError(
                f"{name}: unknown key(s) {', '.join(unknown)}; allowed: "
                f"{', '.join(sorted(_OBJECT_KEYS))}"
            )
        obj_id = entry.get("id", index + 1)
        if isinstance(obj_id, bool) or not isinstance(obj_id, int):
            raise LfsamError(f"{name}: id must be an integer >= 1, got {obj_id!r}")
        name = f"object {obj_id}"
        default_view = _parse_view(entry.get("view"), f"{name}: view")
        frame = _parse_frame(entry.get("frame"), f"{name}: frame")
        points = _parse_points(entry.get("points", []), entry.get("labels"), default_view, name)
        box = _parse_box(entry.get("box"), default_view, name)
        points = [p if p.frame is not None else replace(p, frame=frame) for p in points]
        if box is not None and box.frame is None:
            box = replace(box, frame=frame)
        objects.append(ObjectPrompts(obj_id, tuple(points), box))
    return objects


def _parse_text(entry: dict[str, Any], index: int) -> TextPrompt:
    unknown = sorted(set(entry) - {"text", "view"})
    if unknown:
        raise LfsamError(
            f"entry {index + 1}: a text prompt takes the keys text and view only, got "
            f"{', '.join(unknown)} (its instances get ids after the prompted objects')"
        )
    phrase = check_phrase(entry["text"])
    return TextPrompt(phrase, _parse_view(entry.get("view"), f"text {phrase!r}: view"))


def _parse_view(value: Any, what: str) -> View | None:
    if value is None:
        return None
    if (
        not isinstance(value, (list, tuple))
        or len(value) != 2
        or not all(isinstance(v, int) and not isinstance(v, bool) for v in value)
    ):
        raise LfsamError(f"{what} must be [S, T] (two integers), got {value!r}")
    return int(value[0]), int(value[1])


def _parse_frame(value: Any, what: str) -> int | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise LfsamError(f"{what} must be a whole number >= 0 (0-based frame), got {value!r}")
    return int(value)


def _number_list(value: Any, count: int, what: str) -> list[float]:
    if (
        not isinstance(value, (list, tuple))
        or len(value) != count
        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
    ):
        raise LfsamError(f"{what} must be {count} numbers, got {value!r}")
    return [float(v) for v in value]


def _parse_points(
    value: Any, labels: Any, default_view: View | None, name: str
) -> list[PointPrompt]:
    if not isinstance(value, list):
        raise LfsamError(f"{name}: points must be a list, got {type(value).__name__}")
    if labels is not None and (not isinstance(labels, list) or len(labels) != len(value)):
        raise LfsamError(f"{name}: labels must be a list as long as points ({len(value)})")
    points = []
    for i, item in enumerate(value):
        what = f"{name}: point {i + 1}"
        view = default_view
        label = 1 if labels is None else labels[i]
        if isinstance(item, dict):
            unknown = sorted(set(item) - {"xy", "label", "view", "frame"})
            if unknown:
                raise LfsamError(f"{what}: unknown key(s) {', '.join(unknown)}; allowed: "
                                 "frame, label, view, xy")
            xy = _number_list(item.get("xy"), 2, f"{what}: xy")
            label = item.get("label", label)
            if "view" in item:
                view = _parse_view(item["view"], f"{what}: view")
            frame = _parse_frame(item.get("frame"), f"{what}: frame")
        else:
            xy = _number_list(item, 2, what)
            frame = None
        if label not in (0, 1) or isinstance(label, bool):
            raise LfsamError(f"{what}: label must be 1 (positive) or 0 (negative), got {label!r}")
        points.append(PointPrompt(xy[0], xy[1], bool(label), view, frame))
    return points


def _parse_box(value: Any, default_view: View | None, name: str) -> BoxPrompt | None:
    if value is None:
        return None
    view = default_view
    if isinstance(value, dict):
        unknown = sorted(set(value) - {"xyxy", "view", "frame"})
        if unknown:
            raise LfsamError(f"{name}: box: unknown key(s) {', '.join(unknown)}; allowed: "
                             "frame, view, xyxy")
        if "view" in value:
            view = _parse_view(value["view"], f"{name}: box view")
        frame = _parse_frame(value.get("frame"), f"{name}: box frame")
        value = value.get("xyxy")
    else:
        frame = None
    xyxy = _number_list(value, 4, f"{name}: box")
    return BoxPrompt(*xyxy, view=view, frame=frame)


def load_prompts(
    path: str | os.PathLike,
    grid_shape: View | None = None,
    view_shape: View | None = None,
    num_frames: int = 1,
) -> list[Prompt]:
    """Read a prompt file (JSON, format in the module docstring): objects and text prompts,
    validated against a light field's (or a video's, with ``num_frames``) grid and view size
    when given.

    Raises
    ------
    LfsamError
        Missing file, invalid JSON (with line and column), or a malformed object.
    """
    path = Path(path)
    if not path.is_file():
        raise LfsamError(f"prompt file {str(path)!r} not found")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise LfsamError(
            f"prompt file {str(path)!r} is not valid JSON: {exc.msg} at line {exc.lineno} "
            f"column {exc.colno}"
        ) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise LfsamError(f"cannot read prompt file {str(path)!r}: {exc}") from None
    objects = prompts_from_json(data)
    if grid_shape is not None and view_shape is not None:
        validate_objects(objects, grid_shape, view_shape, num_frames)
    return objects


def save_prompts(objects: Sequence[Prompt], path: str | os.PathLike) -> Path:
    """Write a prompt file atomically (temp file + rename)."""
    with atomic_output(path) as tmp:
        tmp.write_text(json.dumps(prompts_to_json(objects), indent=1), encoding="utf-8")
    return Path(path)
