"""What the viewer's "Render" dock runs in its own thread, without Qt (docs/design.md section 13).

:mod:`lfsam.viewer.render_dock` reads the light field, the masks and the disparity source in
the GUI thread and hands them to these jobs, which call :mod:`lfsam.render` (no rendering here),
and :func:`write_output`, which writes through :mod:`lfsam.render.output` (the writers of
``lfsam render``). Each job returns a :class:`Rendered`; :func:`summary` is its status line.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from lfsam.disparity import resolve_disparity
from lfsam.lightfield import LightField
from lfsam.render import (
    behind_focus,
    object_focus,
    objects_in_front,
    refocus,
    remove_objects,
    see_through,
)
from lfsam.render.output import FLAG_NAME, write_image, write_removed

__all__ = [
    "DisparityCache",
    "RenderOutput",
    "Rendered",
    "range_job",
    "refocus_job",
    "remove_job",
    "see_through_job",
    "summary",
    "write_output",
]

#: What the layer of a removed light field is called (the status names it).
REMOVED_LAYER = "lfsam removed"

Range = tuple[float, float]


@dataclass
class RenderOutput:
    """What the dock rendered last.

    Attributes
    ----------
    kind : {"refocus", "see-through", "remove"}
    focus : float or None
        The focus used, pixels per view step (None for "remove").
    object_id : int or None
        The object focused on, seen through or removed (None for a plain refocus).
    seconds : float
        The time the rendering took (not the disparity's resolution).
    image : (U, V, 3) float32 array in [0, 255], or None
        The refocused or seen-through image.
    coverage : (U, V) float32 array in [0, 1], or None
        See-through: the share of the views that saw each pixel.
    lightfield : LightField or None
        "remove": the light field without the object.
    unseen : (S, T, U, V) bool array or None
        "remove": the pixels no view saw (inpainted; flagged in ``inpainted.npy`` on Save).
    """

    kind: str
    focus: float | None
    object_id: int | None
    seconds: float
    image: np.ndarray | None = None
    coverage: np.ndarray | None = None
    lightfield: LightField | None = None
    unseen: np.ndarray | None = None


@dataclass
class Rendered:
    """A job's answer: the output (None: only the scene's range was sought) and what was
    learnt about the scene.

    Attributes
    ----------
    output : RenderOutput or None
    scene_range : (float, float) or None
        The center disparity's finite extent (the focus is clipped into it, as ``lfsam
        render`` does).
    source : str
        Where the disparity came from (:func:`lfsam.disparity.resolve_disparity`).
    disparity_seconds : float or None
        The time the disparity took, when this job resolved it (None: it was known).
    asked : float or None
        The focus asked for, when it lay outside the scene's range and was clipped.
    """

    output: RenderOutput | None
    scene_range: Range | None
    source: str
    disparity_seconds: float | None = None
    asked: float | None = None


class DisparityCache:
    """The center disparity of one light field, resolved once per light field and disparity
    source (one job runs at a time, so it needs no lock)."""

    def __init__(self) -> None:
        self._key: tuple | None = None
        self._kept: tuple = ()
        self._value: tuple[np.ndarray, str, Range | None] | None = None

    def get(self, lightfield: LightField, spec: Any) -> tuple[tuple, float | None]:
        """``(disparity, source, scene range)`` of ``lightfield`` from ``spec`` ("estimate",
        "gt", a ``.npy`` path or an array), and the seconds it took (None: it was known)."""
        named = isinstance(spec, str | os.PathLike)
        key = (id(lightfield), str(spec) if named else id(spec))
        if key == self._key and self._value is not None:
            return self._value, None
        start = time.monotonic()
        disparity, source = resolve_disparity(spec, lightfield)
        finite = disparity[np.isfinite(disparity)]
        scene = (float(finite.min()), float(finite.max())) if finite.size else None
        self._key, self._kept = key, (lightfield, spec)  # the ids stay theirs while kept
        self._value = (disparity, source, scene)
        return self._value, time.monotonic() - start


def _clip(focus: float, scene: Range | None) -> tuple[float, float | None]:
    """``focus`` within the scene's range, and the focus asked for when it was not."""
    if scene is None or scene[0] <= focus <= scene[1]:
        return float(focus), None
    return float(min(max(focus, scene[0]), scene[1])), float(focus)


def range_job(cache: DisparityCache, lightfield: LightField, spec: Any) -> Rendered:
    """Only the scene's disparity range (for the focus slider)."""
    (_, source, scene), fresh = cache.get(lightfield, spec)
    return Rendered(None, scene, source, fresh)


def refocus_job(cache: DisparityCache, lightfield: LightField, spec: Any,
                focus: float | None = None, obj_id: int | None = None,
                center_mask: np.ndarray | None = None) -> Rendered:
    """:func:`lfsam.render.refocus` at ``focus``, or at object ``obj_id``'s median disparity
    (:func:`lfsam.render.object_focus` of its ``center_mask``)."""
    (disparity, source, scene), fresh = cache.get(lightfield, spec)
    if center_mask is not None:
        focus = object_focus(center_mask, disparity)
    focus, asked = _clip(focus, scene)
    start = time.monotonic()
    image = refocus(lightfield.views, focus, present=lightfield.present, disparity_range=scene)
    output = RenderOutput("refocus", focus, obj_id, time.monotonic() - start, image=image)
    return Rendered(output, scene, source, fresh, asked)


def see_through_job(cache: DisparityCache, lightfield: LightField, spec: Any, obj_id: int,
                    labels: np.ndarray, focus: float | None = None) -> Rendered:
    """:func:`lfsam.render.see_through` object ``obj_id`` of ``labels`` (every view's label
    map), at ``focus`` or at what lies behind it (:func:`lfsam.render.behind_focus`); the other
    objects in front of the focal plane are left out too (:func:`lfsam.render.objects_in_front`,
    as ``lfsam render`` does)."""
    (disparity, source, scene), fresh = cache.get(lightfield, spec)
    masks = labels == obj_id
    if focus is None:
        focus = behind_focus(masks, disparity)
    focus, asked = _clip(focus, scene)
    start = time.monotonic()
    front = objects_in_front(labels, [obj_id], disparity, focus)
    image, coverage = see_through(lightfield.views, masks, focus=focus, occluders=front,
                                  present=lightfield.present, disparity_range=scene)
    output = RenderOutput("see-through", focus, obj_id, time.monotonic() - start, image=image,
                          coverage=coverage)
    return Rendered(output, scene, source, fresh, asked)


def remove_job(cache: DisparityCache, lightfield: LightField, spec: Any, obj_id: int,
               masks: np.ndarray) -> Rendered:
    """:func:`lfsam.render.remove_objects`: the light field without object ``obj_id``, its
    metadata naming the removed object as ``lfsam render --remove`` does."""
    (disparity, source, scene), fresh = cache.get(lightfield, spec)
    start = time.monotonic()
    views, unseen = remove_objects(lightfield.views, masks, disparity,
                                   present=lightfield.present)
    meta = {k: v for k, v in lightfield.meta.items() if k != "generator"}
    meta["render"] = {"removed": [obj_id], "result": "lfsam view", "inpainted": int(unseen.sum()),
                      "flags": FLAG_NAME}
    removed = LightField(views, present=lightfield.present, meta=meta)
    output = RenderOutput("remove", None, obj_id, time.monotonic() - start, lightfield=removed,
                          unseen=unseen)
    return Rendered(output, scene, source, fresh)


def write_output(output: RenderOutput, path: str | os.PathLike) -> str:
    """Write ``output`` to ``path`` atomically (:mod:`lfsam.render.output`): an image, or the
    removed light field as ``.npz`` or a scene folder with its flags; the status line."""
    if output.kind == "remove":
        written = write_removed(output.lightfield, output.unseen, path)
        return (f"wrote {written}: the light field without object {output.object_id} "
                f"({int(output.unseen.sum())} inpainted pixel(s) flagged in {FLAG_NAME})")
    written = write_image(path, output.image)
    what = ("seen through object" if output.kind == "see-through" else
            "focused on object" if output.object_id is not None else "refocused")
    whom = f" {output.object_id}" if output.object_id is not None else ""
    return f"wrote {written}: {what}{whom} at {output.focus:+.3f} px"


def summary(done: Rendered) -> str:
    """The status line of a job's answer: which object, what focus, how long it took."""
    scene = done.scene_range
    scene_text = f"scene {scene[0]:+.2f} to {scene[1]:+.2f} px" if scene else "scene range ?"
    out = done.output
    fresh = "" if done.disparity_seconds is None else (
        f" (disparity {done.source} resolved in {done.disparity_seconds:.2f} s, kept)")
    if out is None:
        slow = done.disparity_seconds is not None and done.disparity_seconds >= 0.05
        found = f", found in {done.disparity_seconds:.1f} s" if slow else ""
        return (f"focus slider over the {scene_text} (disparity {done.source}{found}); select an "
                "object in the lfsam dock's list to focus on it, see through it or remove it")
    took = f"{out.seconds:.2f} s{fresh}"
    clipped = (f"focus {done.asked:+.3f} px lies outside the scene's range: clipped. "
               if done.asked is not None else "")
    if out.kind == "refocus" and out.object_id is None:
        return (f"{clipped}refocused at {out.focus:+.3f} px per view step ({scene_text}, "
                f"disparity {done.source}) in {took}")
    if out.kind == "refocus":
        return (f"object {out.object_id}: in focus at its median disparity {out.focus:+.3f} px "
                f"({scene_text}) in {took}")
    if out.kind == "see-through":
        seen = float((out.coverage > 0).mean())
        return (f"{clipped}object {out.object_id}: seen through at {out.focus:+.3f} px "
                f"({scene_text}); {seen:.1%} of the pixels seen by some view; {took}. The slider "
                "now sees through it (uncheck 'slider sees through' to refocus)")
    grid = out.lightfield.grid_shape
    return (f"object {out.object_id} removed: {grid[0]}x{grid[1]} views in the layer "
            f"'{REMOVED_LAYER}', {int(out.unseen.sum())} pixel(s) seen by no view (inpainted, "
            f"flagged); {took}. Save… writes it (.npz or a folder)")
