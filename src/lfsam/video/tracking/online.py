"""Online tracking: a light-field video segmented one frame at a time, as frames come
(docs/design.md section 10, issue 35).

:class:`OnlineTracker` takes one light field per call (:meth:`~OnlineTracker.track`) with no
frame count up front, keeps the objects' ids, their prompts and the video memory between calls,
and returns that frame's :class:`~lfsam.result.SegmentationResult` at once. Prompts (clicks and
boxes, each tagged with the frame it belongs to) can be added before any frame
(:meth:`~OnlineTracker.add_prompts`). Memory and time per frame stay flat however long the
stream runs: SAM 2's memory keeps a bounded window (:mod:`lfsam.video.memory.sam2_memory`),
constrained prompts keep one template per object, and nothing else is kept per frame.
:func:`lfsam.video.tracking.track.track_video` is a loop over it.

Each frame is segmented across its views by the light-field pipeline
(:class:`lfsam.predictor.LightFieldPredictor`, with every option of
:class:`lfsam.api.SegmentOptions` passed through unchanged). Each object's reference-view mask
at frame f + 1 comes from frame f:

- with a segmenter that has a video memory (SAM 2), through that memory over the sequence of
  center views (:class:`lfsam.video.memory.ReferenceMemory`): an object is conditioned on its
  center-view mask where the user prompts it (the light-field pipeline segments that frame
  from the user's prompts, as a single light field), the memory tracks it in every later frame,
  negative clicks at a later frame are correction clicks there (center view), and each frame's
  light field is then segmented from the memory's masks given as masks
  (:meth:`LightFieldPredictor.add_mask`); an empty mask leaves the object out of that frame.
  The memory encodes each frame's center view once and hands the pipeline that embedding (one
  encoder pass per refined view per frame);
- with segmenters without memory (the oracle), through constrained prompts: each object is
  carried from the frame where it was last found and searched for in every frame
  (:mod:`lfsam.video.tracking.search`, issue 47: predicted place in its own view, the center view
  and the outer ring's views, ranked by how much of it they show, with a radius growing while it
  is unseen, then the whole view; several
  positive points, negative points on neighbours; the user's negative clicks of earlier frames
  stay unless they land on the carried mask, those given in the frame itself always stay). An
  object not found is *hidden* there (empty masks) and keeps its id, template and motion; it
  comes back under its id when found again. ``search=False`` keeps the carrying before issue 47
  (:mod:`lfsam.video.tracking.carry` alone: an answer is rejected when it holds less than half of
  the carried pixels, is more than :data:`MAX_GROWTH` times larger than the object was, or lies
  mostly on an object already placed in that frame; a lost object is matched over the whole
  view only).

Each frame result's ``meta["tracks"]`` gives every object's state there
(:data:`lfsam.video.tracking.search.STATES`: prompted, tracked, found, hidden, waiting), with the
video memory too (:func:`memory_states`: an object the memory scores absent is hidden, keeps its id,
and is found when the memory sees it again).

Objects start at the first frame of their prompts (absent before); prompts given at a later
frame replace the carried ones there. ``auto=True`` finds the objects of the first frame
(:class:`lfsam.generator.LightFieldMaskGenerator`); ``texts`` finds each phrase's instances in
the first frame (:func:`lfsam.text_search.find_text`, docs/design.md section 9), each then
tracked as an object found automatically (issue 46).
"""

from __future__ import annotations

import functools
import threading
import time
from collections.abc import Iterable
from dataclasses import replace
from typing import Any

import numpy as np

from lfsam.api import SegmentOptions
from lfsam.errors import LfsamError
from lfsam.generator import LightFieldMaskGenerator
from lfsam.lightfield import LightField
from lfsam.predictor import LightFieldPredictor
from lfsam.prompts import BoxPrompt, ObjectPrompts, PointPrompt, TextPrompt, validate_objects
from lfsam.result import SegmentationResult
from lfsam.segmenters.base import Segmenter
from lfsam.text_search import find_text
from lfsam.video.io.source import check_frame
from lfsam.video.memory.sam2_memory import reference_memory_for
from lfsam.video.tracking import rules
from lfsam.video.tracking.carry import Template, carry
from lfsam.video.tracking.frame_search import object_disparity, search_frame
from lfsam.video.tracking.prompts import frame_of, negatives_since, prompts_at, start_frame
from lfsam.video.tracking.rules import MAX_GROWTH
from lfsam.video.tracking.search import Track

__all__ = ["MAX_GROWTH", "OnlineTracker", "memory_states"]

#: Carried objects are searched within this fraction of the view's larger side.
SEARCH_FRACTION = 0.3
#: Frames a stream may reach (prompt frames are checked against it).
_MAX_FRAMES = 2**31


_Track = Track


class OnlineTracker:
    """Track objects through a light-field video given one frame at a time.

    Parameters
    ----------
    model : str or Segmenter, optional
        A model name (default ``options.model.name``; ``"oracle"`` is built per frame from
        that frame's labels) or a ready segmenter.
    disparity : {"estimate", "gt"}
        Where each frame's disparity comes from.
    options : SegmentOptions, optional
        Pipeline, model and run options, passed through to every frame.
    memory : bool, optional
        Track with the segmenter's video memory (True) or constrained prompts (False); default:
        the memory where the segmenter has one, prompts for the others.
    auto : bool
        Find the objects of the first frame automatically (prompts may be added besides, with
        other ids).
    texts : sequence of TextPrompt
        Phrases whose instances in the first frame become objects (found with
        ``options.model``'s text detector; the oracle answers from ground-truth categories),
        tracked from there; what each found is :attr:`text_finds`.
    search : bool
        Constrained prompts with the search of issue 47 (default;
        :mod:`lfsam.video.tracking.search`), or the carrying before it (False: the benchmark's
        baseline).

    Examples
    --------
    >>> from lfsam.synth import generate_scene
    >>> from lfsam.prompts import ObjectPrompts, PointPrompt
    >>> scene = generate_scene(grid=(3, 3), size=(48, 64), seed=0)
    >>> tracker = OnlineTracker("oracle", disparity="gt")
    >>> tracker.add_prompts([ObjectPrompts(1, (PointPrompt(20.0, 24.0),))])
    >>> result = tracker.track(scene)  # frame 0; call again with each new frame
    >>> result.labels.shape, tracker.frames_done
    ((3, 3, 48, 64), 1)
    """

    def __init__(self, model: str | Segmenter | None = None, *, disparity: str = "estimate",
                 options: SegmentOptions | None = None, memory: bool | None = None,
                 auto: bool = False, texts: Iterable[TextPrompt] = (),
                 search: bool = True) -> None:
        options = options or SegmentOptions()
        if not isinstance(disparity, str) or disparity not in ("estimate", "gt"):
            raise LfsamError("a light-field video takes --disparity estimate or gt (per frame)")
        if options.run.method != "lfsam":
            raise LfsamError("light-field videos are tracked with --method lfsam only")
        self.options = options
        self.disparity = disparity
        self.memory_option = memory
        self.auto = bool(auto)
        self.texts = tuple(texts)
        #: What each phrase of ``texts`` found in the first frame (``TextFind.to_dict``).
        self.text_finds: list[dict[str, Any]] = []
        self.search = bool(search)
        self.name = model.name if isinstance(model, Segmenter) else (model or options.model.name)
        self._per_frame = not isinstance(model, Segmenter) and self.name == "oracle"
        self.segmenter: Segmenter | None = model if isinstance(model, Segmenter) else None
        self._model_options = options.model if isinstance(model, Segmenter) or model is None \
            else replace(options.model, name=self.name)
        #: Frames tracked so far (the next frame's index).
        self.frames_done = 0
        #: ``"sam2-memory"``, ``"edgetam-memory"`` or ``"constrained-prompts"`` once the first
        #: frame is in.
        self.tracking: str | None = None
        self.grid_shape: tuple[int, int] | None = None
        self.view_shape: tuple[int, int] | None = None
        self._objects: dict[int, ObjectPrompts] = {}
        self._tracks: dict[int, _Track] = {}
        self._memory: Any = None
        self._radius = 0
        self._states: dict[int, str] = {}
        #: Seconds spent carrying and searching objects (constrained prompts), all frames.
        self.carry_seconds = 0.0
        self._posted: list[ObjectPrompts] = []
        self._posted_lock = threading.Lock()

    # --- prompts -----------------------------------------------------------------------------
    @property
    def prompts(self) -> list[ObjectPrompts]:
        """The prompted objects with every prompt given so far (frames kept), in the order
        they were first given."""
        return list(self._objects.values())

    @property
    def object_ids(self) -> list[int]:
        """Every object's id: the prompted ones and those found automatically."""
        return sorted({*self._objects, *self._tracks, *(
            self._memory.object_ids if self._memory is not None else ())})

    def add_prompts(self, objects: Iterable[ObjectPrompts], frame: int | None = None) -> None:
        """Add objects' prompts: clicks and boxes, each at its frame (``frame`` tags them all
        with one frame; default: as tagged, untagged = 0).

        Prompts of a known id join that object's (a box replaces its box); a frame already
        tracked cannot take prompts. Checked at once (against the video's grid and view size
        once the first frame is in).

        Raises
        ------
        LfsamError
            A prompt for a frame already tracked, an object with only negative clicks, or one
            outside the grid or view (one line).
        """
        merged = dict(self._objects)
        for obj in objects:
            if frame is not None:
                obj = ObjectPrompts(obj.obj_id, tuple(replace(p, frame=int(frame))
                                                      for p in obj.points),
                                    None if obj.box is None else replace(obj.box,
                                                                         frame=int(frame)))
            tagged = [*obj.points, *([obj.box] if obj.box is not None else [])]
            early = [frame_of(p) for p in tagged if frame_of(p) < self.frames_done]
            if early:
                raise LfsamError(
                    f"object {obj.obj_id}: frame {min(early)} is tracked already; prompts go on "
                    f"frame {self.frames_done} or later")
            if obj.obj_id in self._tracks and obj.obj_id not in self._objects:
                raise LfsamError(f"object {obj.obj_id} was found automatically; give the new "
                                 "object another id")
            old = merged.get(obj.obj_id)
            if old is not None:
                obj = ObjectPrompts(obj.obj_id, (*old.points, *obj.points),
                                    obj.box if obj.box is not None else old.box)
            merged[obj.obj_id] = obj
        if self.grid_shape is not None:
            validate_objects(list(merged.values()), self.grid_shape, self.view_shape,
                             _MAX_FRAMES)
            if self._memory is not None:
                _check_corrections(merged.values(), _center(self.grid_shape))
        self._objects = merged

    def post_prompts(self, objects: Iterable[ObjectPrompts]) -> None:
        """Hand over prompts for the next frame :meth:`track` starts, from any thread (the
        viewer's clicks while a stream runs in its worker): they are added then, tagged with
        that frame, as :meth:`add_prompts` adds them (posted prompts that do not fit are left
        out, with the reason in that frame's ``meta["refused_prompts"]``). Returns at once."""
        with self._posted_lock:
            self._posted.extend(objects)

    @property
    def waiting_prompts(self) -> list[ObjectPrompts]:
        """Prompts posted (:meth:`post_prompts`) that no frame has taken yet: once a stream
        has ended, those came after its last frame and were never used."""
        with self._posted_lock:
            return list(self._posted)

    # --- frames ------------------------------------------------------------------------------
    def track(self, lightfield: LightField) -> SegmentationResult:
        """Segment the next frame: every object's masks over all its views.

        Returns
        -------
        SegmentationResult
            The frame's result (``meta["frame"]`` is its index).

        Raises
        ------
        LfsamError
            A frame whose grid or view size differs from the first frame's (nothing changes:
            the stream may go on with the next frame), or prompts that do not fit the first
            frame.
        """
        lf = lightfield
        index = self.frames_done
        with self._posted_lock:
            posted, self._posted = self._posted, []
        refused = None
        if posted:
            try:
                self.add_prompts(posted, frame=index)
            except LfsamError as exc:  # the frame goes on without them
                refused = str(exc)
        if self.grid_shape is None:
            validate_objects(list(self._objects.values()), lf.grid_shape, lf.view_shape,
                             _MAX_FRAMES)
        else:
            check_frame(lf, index, self.grid_shape, self.view_shape, "the stream")
        segmenter = self._segmenter_for(lf)
        if self.grid_shape is None:
            self._memory = None if self.memory_option is False else reference_memory_for(
                segmenter, lf.view_shape, required=bool(self.memory_option))
            if self._memory is not None:
                _check_corrections(self._objects.values(), lf.center)
            self.tracking = _tracking_label(segmenter, self._memory)
            self.grid_shape, self.view_shape = lf.grid_shape, lf.view_shape
            self._radius = max(8, int(SEARCH_FRACTION * max(lf.view_shape)))
        options = self.options
        predictor = LightFieldPredictor(
            segmenter, options.pipeline, cache_dir=options.run.cache_dir,
            memory_budget_mb=options.run.memory_budget_mb, progress=False,
        )
        predictor.set_lightfield(lf, disparity=self.disparity)
        # the center's disparity estimated while the frame's center view is encoded
        predictor.engine.disparities.prefetch()
        first_auto = index == 0 and (self.auto or bool(self.texts))
        find = functools.partial(self._find_first, lf=lf)
        if self._memory is not None:
            prompted, masks = _memory_frame(self._memory, predictor, lf, index, self._objects,
                                            find if first_auto else None)
            self._states = memory_states(self._states, prompted, masks, self._objects)
        else:
            states: dict[int, str] = {}
            if first_auto:
                find(predictor)
                for obj_id in predictor.object_ids:
                    view, mask, _ = predictor.predict_reference(obj_id)
                    self._tracks[obj_id] = _Track(
                        view, Template.from_mask(lf.views[view], mask), area=int(mask.sum()),
                        disparity=object_disparity(predictor.disparity(view), mask),
                        sightings=1, state="prompted")
                    states[obj_id] = "prompted"
            found = [] if first_auto else [i for i in sorted(self._tracks)
                                           if i not in self._objects]
            use_box = segmenter.name != "oracle"
            start = time.perf_counter()
            if self.search:
                states.update(search_frame(predictor, lf, index, [*found, *self._objects],
                                           {i: self._objects.get(i) for i in
                                            [*found, *self._objects]}, self._tracks, use_box))
            else:
                placed = np.zeros(lf.view_shape, bool)
                for obj_id in [*found, *self._objects]:
                    placed |= _segment_object(predictor, lf, index, obj_id,
                                              self._objects.get(obj_id), self._tracks,
                                              self._radius, placed, use_box)
                    states.setdefault(obj_id, "tracked" if obj_id in predictor.object_ids
                                      else "hidden" if obj_id in self._tracks else "waiting")
            self._states = states
            self.carry_seconds += time.perf_counter() - start
        result = predictor.to_result()
        result.meta["frame"] = index
        if first_auto and self.texts:
            result.meta["text"] = self.text_finds
        result.meta["tracks"] = {str(i): s for i, s in sorted(self._states.items())}
        if refused is not None:
            result.meta["refused_prompts"] = refused
        self.frames_done += 1
        return result

    def _find_first(self, predictor: LightFieldPredictor, lf: LightField) -> None:
        """The first frame's objects found automatically and / or from :attr:`texts`."""
        references = self.options.run.references
        if self.auto:
            LightFieldMaskGenerator(predictor, references).generate()
        if self.texts:
            model = self._model_options
            finds = find_text(predictor, model.build_text_detector(lf), self.texts,
                              references, model.text_threshold)
            self.text_finds = [f.to_dict() for f in finds]

    def _segmenter_for(self, lf: LightField) -> Segmenter:
        if self._per_frame or self.segmenter is None:
            segmenter = self._model_options.build(lf, keep_decoder_state=False)
            if not self._per_frame:
                self.segmenter = segmenter
            return segmenter
        return self.segmenter


def _tracking_label(segmenter: Segmenter, memory: Any) -> str:
    """``meta["tracking"]``: ``sam2-memory`` (Meta's SAM 2, or a transformers SAM 2),
    ``edgetam-memory``, or ``constrained-prompts``."""
    if memory is None:
        return "constrained-prompts"
    info = getattr(getattr(segmenter, "model", None), "lfsam_info", None) or {}
    return "edgetam-memory" if info.get("model_type") == "edgetam" else "sam2-memory"


def _center(grid: tuple[int, int]) -> tuple[int, int]:
    return (grid[0] // 2, grid[1] // 2)


def _check_corrections(objects: Iterable[ObjectPrompts], center: tuple[int, int]) -> None:
    """With a video memory, a negative click at a frame where its object has no positive
    prompt is a correction click in the center view (checked before any work)."""
    for obj in objects:
        starts = {frame_of(p) for p in obj.points if p.positive}
        if obj.box is not None:
            starts.add(frame_of(obj.box))
        for p in obj.points:
            if (not p.positive and frame_of(p) not in starts and p.view is not None
                    and tuple(p.view) != center):
                raise LfsamError(
                    f"object {obj.obj_id}: with SAM 2's video memory a correction click at a "
                    f"later frame goes in the center view {center}, not {tuple(p.view)}")


def _center_mask(predictor: LightFieldPredictor, lf: LightField, obj_id: int) -> np.ndarray:
    """An object's step-1 mask in the center view (its final mask there when it was prompted
    in another view)."""
    view, mask, _ = predictor.predict_reference(obj_id)
    return mask if view == lf.center else predictor.masks_in_view([obj_id], lf.center)[0]


def memory_states(before: dict[int, str], prompted: set[int], masks: dict[int, np.ndarray],
                  objects: dict[int, ObjectPrompts]) -> dict[int, str]:
    """Each object's state (:data:`lfsam.video.tracking.search.STATES`) in a frame tracked with the
    video memory: prompted there, tracked (a mask), hidden (the memory's occlusion score says
    absent: an empty mask; the object stays in the memory under its id) or found again (a mask
    after hidden frames), waiting before its start."""
    states = {}
    for obj_id in sorted({*objects, *masks, *prompted}):
        if obj_id in prompted:
            states[obj_id] = "prompted"
        elif obj_id in masks and masks[obj_id].any():
            states[obj_id] = "found" if before.get(obj_id) == "hidden" else "tracked"
        elif obj_id in masks:
            states[obj_id] = "hidden"
        else:
            states[obj_id] = "waiting"
    return states


def _memory_frame(memory: Any, predictor: LightFieldPredictor, lf: LightField, index: int,
                  objects: dict[int, ObjectPrompts], find: Any
                  ) -> tuple[set[int], dict[int, np.ndarray]]:
    """One frame tracked with the video memory (see the module docstring): prompted objects
    from their prompts, the others from the memory's masks. Returns the prompted ids and the
    memory's masks."""
    embedding = memory.next_frame(index, lf.views[lf.center])
    if embedding is not None:
        predictor.engine.store.put(lf.center, embedding)
    prompted: set[int] = set()
    if find is not None:  # the first frame's objects found automatically or from text
        find(predictor)
        prompted = set(predictor.object_ids)
    for obj in objects.values():
        own = prompts_at(obj, index)
        if own is not None and own.has_positive:
            earlier = [p for p in negatives_since(obj, index) if p not in own.points]
            predictor.set_object(own.with_points(earlier))
            prompted.add(obj.obj_id)
    for obj_id in sorted(prompted):
        memory.add_mask(obj_id, _center_mask(predictor, lf, obj_id))
    masks = memory.track()
    for obj in objects.values():
        own = prompts_at(obj, index)
        if own is None or obj.obj_id in prompted or obj.obj_id not in masks:
            continue
        fresh = [p for p in own.points if not p.positive]
        if fresh:
            masks = memory.correct(obj.obj_id, [(p.x, p.y) for p in fresh])
    for obj_id, mask in masks.items():
        if obj_id not in prompted and mask.any():
            predictor.add_mask(obj_id, mask, lf.center)
    memory.forget()
    return prompted, masks


def _carried_prompts(obj_id: int, track: _Track, image: np.ndarray, negatives, fresh,
                     radius: int, use_box: bool) -> tuple[ObjectPrompts, np.ndarray, int] | None:
    """The constrained prompts of a carried object: ``negatives`` of earlier frames are
    dropped where they land on the carried mask, ``fresh`` ones (given in this frame) never."""
    avoid = tuple((p.x, p.y) for p in fresh)
    found = carry(track.template, image, None if track.lost else radius, avoid=avoid)
    if found is None:
        return None
    view = track.view
    kept = [p for p in negatives
            if p in fresh or not found.mask[round(p.y), round(p.x)]]
    points = (PointPrompt(*found.point, True, view), *(PointPrompt(p.x, p.y, False, view)
                                                       for p in kept))
    box = BoxPrompt(*found.box, view=view) if use_box else None
    return ObjectPrompts(obj_id, points, box), found.mask, int(found.mask.sum())


def _accept(mask: np.ndarray, carried: np.ndarray | None, expected: int,
            placed: np.ndarray) -> bool:
    """Whether a reference-view answer is the carried object (see the module docstring)."""
    area = int(mask.sum())
    if area == 0:
        return False
    if carried is not None:
        if (mask & carried).sum() < 0.5 * min(carried.sum(), area):
            return False
        if area > rules.MAX_GROWTH * max(expected, 1) + 50:
            return False
    return (mask & placed).sum() <= 0.5 * area


def _segment_object(predictor: LightFieldPredictor, lf: LightField, index: int, obj_id: int,
                    obj: ObjectPrompts | None, tracks: dict[int, _Track], radius: int,
                    placed: np.ndarray, use_box: bool) -> np.ndarray:
    """Add one object to this frame's predictor (or leave it out); its reference mask."""
    empty = np.zeros(lf.view_shape, bool)
    if obj is not None and (start_frame(obj) is None or index < start_frame(obj)):
        return empty
    own = None if obj is None else prompts_at(obj, index)
    negatives = () if obj is None else negatives_since(obj, index)
    track = tracks.get(obj_id)
    carried_mask, expected = None, 0
    if own is not None and own.has_positive:
        earlier = [p for p in negatives if p not in own.points]
        prompt = own.with_points(earlier)
    elif track is not None and track.template is not None:
        fresh = () if own is None else tuple(p for p in own.points if not p.positive)
        carried = _carried_prompts(obj_id, track, lf.views[track.view], negatives, fresh,
                                   radius, use_box)
        if carried is None:
            track.lost = True
            return empty
        prompt, carried_mask, expected = carried
        expected = max(expected, int(track.template.mask.sum()))
    else:
        return empty
    predictor.set_object(prompt)
    view, mask, _ = predictor.predict_reference(obj_id)
    if view != lf.center and carried_mask is None:
        placed_here = np.zeros_like(placed)
    else:
        placed_here = placed
    if not _accept(mask, carried_mask, expected, placed_here):
        predictor.remove_object(obj_id)
        if track is not None:
            track.lost = True
        return empty
    tracks[obj_id] = _Track(view, Template.from_mask(lf.views[view], mask))
    return mask if view == lf.center else empty
