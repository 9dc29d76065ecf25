"""Tracking objects through a light-field video (docs/design.md section 10).

Each frame is segmented across its views by the light-field pipeline
(:class:`lfsam.predictor.LightFieldPredictor`, with every option of
:class:`lfsam.api.SegmentOptions` passed through unchanged). Each object's reference-view mask
at frame f + 1 comes from frame f:

- with a SAM 2 segmenter, through SAM 2's video memory over the sequence of center views
  (:class:`lfsam.video.memory.ReferenceMemory`): an object is conditioned on its center-view
  mask where the user prompts it (the light-field pipeline segments that frame from the user's
  prompts, as a single light field), SAM 2 tracks it in every later frame, negative clicks at a
  later frame are SAM 2 correction clicks there (center view), and each frame's light field is
  then segmented from SAM 2's masks given as masks (:meth:`LightFieldPredictor.add_mask`); an
  empty mask leaves the object out of that frame;
- with segmenters without memory (the oracle), through constrained prompts
  (:mod:`lfsam.video.carry`): its
frame-f mask and pixels are matched into frame f + 1, and the segmenter is prompted there with a
point at the deepest matching pixel (and, for SAM 2, a box around the carried mask); the user's
negative clicks of earlier frames stay (those landing on the carried mask are dropped; those
given in the frame itself always stay, and the carried point keeps away from them). An
answer is rejected (the object is *lost* in that frame: empty masks) when it holds less than
half of the carried pixels, is more than :data:`MAX_GROWTH` times larger than the object was,
or lies mostly on an object already placed in that frame. A lost object is searched for over the
whole view in every later frame with its last template, and keeps its id when it comes back.
Objects start at the first frame of their prompts (absent before); prompts given at a later
frame replace the carried ones there. ``auto`` finds the objects of frame 0
(:class:`lfsam.generator.LightFieldMaskGenerator`).

The result is written frame by frame (:mod:`lfsam.video.result`): memory stays flat in F. Its
manifest keeps each object's frame-tagged prompts as given (``meta["objects"]``), so that the
viewer reopens the folder editable (:meth:`lfsam.video.result.VideoResult.stored_prompts`).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from lfsam.api import SegmentOptions
from lfsam.errors import LfsamError
from lfsam.generator import LightFieldMaskGenerator
from lfsam.predictor import LightFieldPredictor
from lfsam.prompts import BoxPrompt, ObjectPrompts, PointPrompt, validate_objects
from lfsam.result import SegmentationResult
from lfsam.segmenters.base import Segmenter
from lfsam.version import __version__
from lfsam.video.carry import Template, carry
from lfsam.video.memory import ReferenceMemory, has_video_memory
from lfsam.video.prompts import frame_of, negatives_since, prompts_at, start_frame
from lfsam.video.result import VideoResult, load_video_result, video_result_writer
from lfsam.video.source import LightFieldVideo

__all__ = ["MAX_GROWTH", "track_video"]

#: An answer more than this many times larger than the object's carried mask is rejected.
MAX_GROWTH = 4.0
#: Carried objects are searched within this fraction of the view's larger side.
SEARCH_FRACTION = 0.3


@dataclass
class _Track:
    """What is known of one object after the latest frame."""

    view: tuple[int, int]
    template: Template | None = None
    lost: bool = False


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
        if area > MAX_GROWTH * max(expected, 1) + 50:
            return False
    return (mask & placed).sum() <= 0.5 * area


def track_video(
    video: LightFieldVideo,
    prompts: Sequence[ObjectPrompts] | None,
    out: str | os.PathLike,
    *,
    model: str | Segmenter | None = None,
    disparity: str = "estimate",
    options: SegmentOptions | None = None,
    memory: bool | None = None,
    on_frame: Callable[[int, SegmentationResult], None] | None = None,
) -> VideoResult:
    """Track objects through a light-field video and write the chunked result.

    Parameters
    ----------
    video : LightFieldVideo
    prompts : sequence of ObjectPrompts, or None
        Objects with frame-tagged prompts (:mod:`lfsam.video.prompts`); None: automatic mask
        generation on frame 0.
    out : path-like
        The result folder (:func:`lfsam.video.result.video_result_writer`).
    model : str or Segmenter, optional
        A model name (default ``options.model.name``; ``"oracle"`` is built per frame from
        that frame's labels) or a ready SAM 2 segmenter.
    disparity : {"estimate", "gt"}
        Where each frame's disparity comes from.
    options : SegmentOptions, optional
        Pipeline, model and run options, passed through to every frame.
    memory : bool, optional
        Track with SAM 2's video memory (True) or constrained prompts (False); default: the
        memory for SAM 2 segmenters, prompts for the others.
    on_frame : callable, optional
        Called as ``on_frame(index, result)`` with each frame's
        :class:`~lfsam.result.SegmentationResult` once it is written, in frame order and in the
        calling thread (the viewer shows frames as they finish, docs/design.md section 8). An
        exception it raises stops the run; nothing is left at ``out`` then.

    Returns
    -------
    VideoResult
        The written result, opened lazily; its :meth:`~VideoResult.stored_prompts` gives
        ``prompts`` back in id order, frames kept ([] in the automatic mode).

    Raises
    ------
    LfsamError
        Prompts that do not fit the video, a disparity other than a name, the video
        baseline method (single light fields only), ``memory=True`` without SAM 2, or a
        correction click outside the center view with SAM 2's memory.
    """
    options = options or SegmentOptions()
    if not isinstance(disparity, str) or disparity not in ("estimate", "gt"):
        raise LfsamError("a light-field video takes --disparity estimate or gt (per frame)")
    if options.run.method != "lfsam":
        raise LfsamError("light-field videos are tracked with --method lfsam only")
    objects = list(prompts) if prompts is not None else None
    if objects is not None:
        validate_objects(objects, video.grid_shape, video.view_shape, video.num_frames)
    name = model.name if isinstance(model, Segmenter) else (model or options.model.name)
    per_frame = not isinstance(model, Segmenter) and name == "oracle"
    segmenter = model if isinstance(model, Segmenter) else None
    model_options = options.model if isinstance(model, Segmenter) or model is None else (
        type(options.model)(**{**options.model.__dict__, "name": name}))
    size = max(video.view_shape)
    radius = max(8, int(SEARCH_FRACTION * size))
    tracks: dict[int, _Track] = {}
    start = time.perf_counter()
    meta: dict[str, Any] = {
        "method": "lfsam-video", "input": video.meta.get("source"), "model": name,
        "frames": video.num_frames, "prompt_mode": "auto" if objects is None else "prompts",
        "package_version": __version__, "disparity": disparity,
    }
    bar = tqdm(total=video.num_frames, desc="tracking", unit="frame",
               disable=not options.run.progress)
    reference: ReferenceMemory | None = None
    with video_result_writer(out, meta=meta, objects=objects or []) as writer:
        for index in range(video.num_frames):
            lf = video.frame(index)
            if per_frame or segmenter is None:
                segmenter = model_options.build(lf, keep_decoder_state=False)
            if index == 0:
                reference = _memory_for(segmenter, memory, video)
                if reference is not None:
                    _check_corrections(objects or (), lf.center)
                meta["tracking"] = "sam2-memory" if reference else "constrained-prompts"
            predictor = LightFieldPredictor(
                segmenter, options.pipeline, cache_dir=options.run.cache_dir,
                memory_budget_mb=options.run.memory_budget_mb, progress=False,
            )
            predictor.set_lightfield(lf, disparity=disparity)
            placed = np.zeros(lf.view_shape, bool)
            if reference is not None:
                _memory_frame(reference, predictor, lf, index, objects, options.run.references)
            elif objects is None and index == 0:
                LightFieldMaskGenerator(predictor, options.run.references).generate()
                for obj_id in predictor.object_ids:
                    view, mask, _ = predictor.predict_reference(obj_id)
                    tracks[obj_id] = _Track(view, Template.from_mask(lf.views[view], mask))
            else:
                ids = sorted(tracks) if objects is None else [o.obj_id for o in objects]
                for obj_id in ids:
                    obj = None if objects is None else next(o for o in objects
                                                            if o.obj_id == obj_id)
                    placed |= _segment_object(predictor, lf, index, obj_id, obj, tracks,
                                              radius, placed, segmenter.name != "oracle")
            frame_result = predictor.to_result()
            writer.write(frame_result)
            if on_frame is not None:
                on_frame(index, frame_result)
            bar.update(1)
    bar.close()
    result = load_video_result(out)
    result.meta["seconds"] = time.perf_counter() - start
    return result


def _memory_for(segmenter: Segmenter, memory: bool | None,
                video: LightFieldVideo) -> ReferenceMemory | None:
    """SAM 2's video memory for this run, or None (constrained prompts)."""
    if memory is False:
        return None
    if not has_video_memory(segmenter):
        if memory:
            raise LfsamError(f"the {segmenter.name!r} segmenter has no video memory; track with "
                             "a SAM 2 --model or with constrained prompts")
        return None
    return ReferenceMemory(segmenter, video.num_frames, video.view_shape)


def _check_corrections(objects: Sequence[ObjectPrompts], center: tuple[int, int]) -> None:
    """With SAM 2's memory, a negative click at a frame where its object has no positive
    prompt is a SAM 2 correction click in the center view (checked before any work)."""
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


def _center_mask(predictor: LightFieldPredictor, lf, obj_id: int) -> np.ndarray:
    """An object's step-1 mask in the center view (its final mask there when it was prompted
    in another view)."""
    view, mask, _ = predictor.predict_reference(obj_id)
    return mask if view == lf.center else predictor.masks_in_view([obj_id], lf.center)[0]


def _memory_frame(memory: ReferenceMemory, predictor: LightFieldPredictor, lf, index: int,
                  objects: Sequence[ObjectPrompts] | None, references: Any) -> None:
    """One frame tracked with SAM 2's memory (see the module docstring): prompted objects
    from their prompts, the others from the memory's masks."""
    memory.next_frame(index, lf.views[lf.center])
    prompted: set[int] = set()
    if objects is None and index == 0:
        LightFieldMaskGenerator(predictor, references).generate()
        prompted = set(predictor.object_ids)
    for obj in objects or ():
        own = prompts_at(obj, index)
        if own is not None and own.has_positive:
            earlier = [p for p in negatives_since(obj, index) if p not in own.points]
            predictor.set_object(own.with_points(earlier))
            prompted.add(obj.obj_id)
    for obj_id in sorted(prompted):
        memory.add_mask(obj_id, _center_mask(predictor, lf, obj_id))
    masks = memory.track()
    for obj in objects or ():
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


def _segment_object(predictor: LightFieldPredictor, lf, index: int, obj_id: int,
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
