"""EdgeTAM's (and transformers SAM 2's) video memory over the reference views of a light-field
video (docs/design.md section 10).

The counterpart of :class:`lfsam.video.memory.ReferenceMemory` for the ``transformers`` backend
(:class:`~lfsam.segmenters.transformers.backend.TransformersSegmenter`): ``transformers``'
``EdgeTamVideoModel`` / ``Sam2VideoModel``
(:func:`lfsam.segmenters.transformers.video_build.video_model_for`,
sharing the segmenter's encoder and heads) streamed one center view per frame through its
inference session (``EdgeTamVideoInferenceSession``), with no frame count known up front:

- :meth:`TransformersReferenceMemory.next_frame` encodes frame f's center view once
  (``get_image_features`` on the segmenter's pixels), puts the features where the video model
  looks for them (``session.cache.cache_vision_features``) and returns the segmenter's
  :class:`~lfsam.segmenters.base.ViewEmbedding` of that same pass (``get_image_embeddings``' two
  steps: the no-memory embedding added, the levels reshaped), so the pipeline does not encode the
  view again;
- :meth:`~TransformersReferenceMemory.add_mask` conditions an object on a mask at this frame (as
  the processor's ``add_inputs_to_inference_session(input_masks=...)`` does: resized to the
  model's input, antialiased, thresholded at 0.5);
- :meth:`~TransformersReferenceMemory.track` runs the model on this frame for every object
  (``model(inference_session, frame_idx, frame)``: streaming, so object pointers reach
  ``max_object_pointers_in_encoder`` frames back whatever the frame count);
- :meth:`~TransformersReferenceMemory.correct` adds negative clicks on an object's tracked mask
  (point inputs at this frame, as the processor writes them);
- :meth:`~TransformersReferenceMemory.forget` keeps the session flat in F.

Masks are the model's low-resolution logits resized to the view (bilinear, as the processor's
``post_process_masks``) and thresholded at 0.

Memory stays flat: at frame f + 1 the model reads the non-conditioning outputs of frames
f + 2 - ``num_maskmem`` .. f (memories) and f + 2 - ``max_object_pointers_in_encoder`` .. f
(object pointers), so after frame f outputs older than f + 2 - n are dropped, n the larger of the
two (16 for EdgeTAM and SAM 2): the masks are those of an unbounded session. The frame's pixel
values, cached features of older frames, the inputs of earlier frames and the full-resolution
masks ``Sam2VideoModel`` keeps with each output (read only while that frame is encoded into
memory) are dropped too. Conditioning outputs (one per ``add_mask`` frame) are kept. The memory
runs in float32; with a bfloat16 segmenter :meth:`~TransformersReferenceMemory.next_frame` returns
None (its embeddings come from another arithmetic) and the pipeline encodes the view itself.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from lfsam.errors import LfsamError
from lfsam.segmenters.base import Segmenter, ViewEmbedding
from lfsam.segmenters.sam2.backend import Sam2Features
from lfsam.segmenters.sam2.build import inference_context
from lfsam.segmenters.transformers.backend import TransformersSegmenter, preprocess_views
from lfsam.segmenters.transformers.video_build import (
    session_class,
    video_memory_problem,
    video_model_for,
)

__all__ = ["TransformersReferenceMemory", "has_transformers_video_memory"]


def has_transformers_video_memory(segmenter: Segmenter) -> bool:
    """Whether ``segmenter`` is a transformers SAM 2 / EdgeTAM model whose video memory lfsam
    can build (a video checkpoint folder, or random weights); False for SAM v1, image-only
    folders and every other segmenter (docs/design.md section 10)."""
    if not isinstance(segmenter, TransformersSegmenter):
        return False
    return video_memory_problem(segmenter.model) is None


class TransformersReferenceMemory:
    """The video memory of a transformers SAM 2 / EdgeTAM segmenter over the center views of a
    light-field video, one frame at a time (docs/design.md section 10).

    Parameters
    ----------
    segmenter : TransformersSegmenter
        Of the ``sam2`` or ``edgetam`` family, from a video checkpoint or with random weights;
        the video model shares its encoder and heads.
    view_shape : (U, V)
        Size of the center views; masks are returned at this size.

    Raises
    ------
    LfsamError
        The segmenter has no video memory (SAM v1, an image-only folder: the line says what to
        do instead), or its memory weights cannot be read.

    Attributes
    ----------
    logits : (N, U, V) float32 ndarray
        The mask logits of the latest :meth:`track` or :meth:`correct`, in :attr:`object_ids`
        order.
    window : int
        Frames of non-conditioning outputs kept behind the current one (lossless: n - 2).
    """

    def __init__(self, segmenter: TransformersSegmenter, view_shape: tuple[int, int]) -> None:
        if not isinstance(segmenter, TransformersSegmenter):
            raise LfsamError(f"the {getattr(segmenter, 'name', segmenter)!r} segmenter is not a "
                             "transformers model; its video memory is lfsam.video.memory's")
        self.segmenter = segmenter
        self.model = video_model_for(segmenter.model)
        self.device = torch.device(segmenter.device)
        self.view_shape = (int(view_shape[0]), int(view_shape[1]))
        self.image_size = int(segmenter.model.image_size)
        self.session: Any = session_class(self.model)(
            video_height=self.view_shape[0], video_width=self.view_shape[1],
            inference_device=self.device, inference_state_device=self.device,
            video_storage_device=self.device, dtype=torch.float32,
            max_vision_features_cache_size=1,
        )
        config = self.model.config
        self.window = max(int(self.model.num_maskmem),
                          int(config.max_object_pointers_in_encoder)) - 2
        self.frame = -1
        self.logits = np.zeros((0, *self.view_shape), np.float32)
        self._pixels: torch.Tensor | None = None

    @property
    def object_ids(self) -> list[int]:
        """Objects the memory tracks, in the order they were added."""
        return [int(i) for i in self.session.obj_ids]

    # --- frames ---------------------------------------------------------------------------
    def next_frame(self, index: int, image: np.ndarray) -> ViewEmbedding | None:
        """Load frame ``index``'s center view and encode it once.

        Parameters
        ----------
        index : int
            The frame: the first one seen (any), then one more than the previous each time.
        image : (U, V, 3) uint8 ndarray
            The center view.

        Returns
        -------
        ViewEmbedding or None
            The segmenter's embedding of ``image`` from this encoder pass (equal to
            ``segmenter.encode(image[None])[0]``, counted in its ``encode_calls``); None with a
            bfloat16 segmenter, whose embeddings come from another arithmetic.

        Raises
        ------
        LfsamError
            A frame out of order, or an image of another size.
        """
        index = int(index)
        if index < 0 or (self.frame >= 0 and index != self.frame + 1):
            raise LfsamError(f"frames go forward one at a time: frame {index} after frame "
                             f"{self.frame}")
        image = np.asarray(image)
        if image.shape != (*self.view_shape, 3) or image.dtype != np.uint8:
            raise LfsamError(f"frame {index}'s center view is {image.shape} {image.dtype}; the "
                             f"memory takes {self.view_shape[0]} x {self.view_shape[1]} x 3 uint8")
        with inference_context(self.device, precision="float32"):
            views = torch.from_numpy(np.ascontiguousarray(image[None])).to(self.device)
            pixels = preprocess_views(views, self.image_size)
            out = self.model.get_image_features(pixels, return_dict=True)
            feats, pos = list(out.fpn_hidden_states), list(out.fpn_position_encoding)
            self.session.cache.cache_vision_features(
                index, {"vision_feats": feats, "vision_pos_embeds": pos})
            embedding = None if self.segmenter.autocast is not None else self._embedding(feats)
        self._pixels, self.frame = pixels[0], index
        return embedding

    def _embedding(self, feats: list[torch.Tensor]) -> ViewEmbedding:
        """``get_image_embeddings``' output from its ``get_image_features`` pass, as the
        segmenter keeps it (:class:`Sam2Features`)."""
        maps = list(feats)
        maps[-1] = maps[-1] + self.model.no_memory_embedding
        levels = [f.permute(1, 2, 0).view(1, -1, *size)
                  for f, size in zip(maps, self.model.backbone_feature_sizes, strict=True)]
        self.segmenter.encode_calls += 1
        return ViewEmbedding(image_size=self.view_shape, key=None,
                             data=Sam2Features(image_embed=levels[-1],
                                               high_res_feats=levels[:-1]))

    # --- prompts and tracking -------------------------------------------------------------
    def _check_frame(self) -> None:
        if self.frame < 0:
            raise LfsamError("the memory has no frame yet: call next_frame first")

    def _mark_new_inputs(self, obj_id: int) -> None:
        """The object's inputs at this frame are read by the next forward (the processor
        replaces this list; objects added one by one are appended)."""
        pending = self.session.obj_with_new_inputs
        if obj_id not in pending:
            pending.append(obj_id)

    def add_mask(self, obj_id: int, mask: np.ndarray) -> None:
        """Condition ``obj_id`` on ``mask`` (U, V) bool at the current frame (read by the next
        :meth:`track`)."""
        self._check_frame()
        mask = np.asarray(mask, bool)
        if mask.shape != self.view_shape:
            raise LfsamError(f"object {obj_id}'s mask is {mask.shape}; the center views are "
                             f"{self.view_shape}")
        side = self.image_size
        with inference_context(self.device, precision="float32"):
            inputs = torch.from_numpy(mask).to(self.device)[None, None].float()
            if inputs.shape[-2:] != (side, side):
                inputs = F.interpolate(inputs, size=(side, side), mode="bilinear",
                                       align_corners=False, antialias=True)
                inputs = (inputs >= 0.5).float()
        obj_idx = self.session.obj_id_to_idx(int(obj_id))
        self.session.add_mask_inputs(obj_idx, self.frame, inputs)
        self.session.remove_point_inputs(obj_idx, self.frame)
        self._mark_new_inputs(int(obj_id))

    def track(self) -> dict[int, np.ndarray]:
        """Every tracked object's mask (U, V) bool at the current frame ({} without objects;
        an empty mask: the object is not there)."""
        self._check_frame()
        if not self.session.obj_ids:
            self.logits = np.zeros((0, *self.view_shape), np.float32)
            return {}
        return self._run()

    def correct(self, obj_id: int, negatives: Sequence[tuple[float, float]]
                ) -> dict[int, np.ndarray]:
        """Negative clicks ``(x, y)`` (column, row in view pixels) on ``obj_id``'s tracked mask
        at the current frame (replacing earlier clicks there); every object's mask afterwards.

        The frame's output for ``obj_id`` becomes the model's answer to the clicks on its
        memory-conditioned features (as ``transformers`` treats clicks on a tracked frame) and
        is what later frames remember. Meant for tracked frames: on a frame where ``obj_id``
        was given a mask, the clicks would replace that mask.

        Raises
        ------
        LfsamError
            ``obj_id`` is not tracked.
        """
        self._check_frame()
        obj_id = int(obj_id)
        if obj_id not in self.object_ids:
            raise LfsamError(f"object {obj_id} is not tracked; tracked: {self.object_ids}")
        points = torch.tensor(np.asarray(negatives, np.float32).reshape(-1, 2))
        if not len(points):
            return self.track()
        height, width = self.view_shape
        points[..., 0] = points[..., 0] * (self.image_size / width)
        points[..., 1] = points[..., 1] * (self.image_size / height)
        inputs = {"point_coords": points[None, None],
                  "point_labels": torch.zeros(1, 1, len(points), dtype=torch.int32)}
        obj_idx = self.session.obj_id_to_idx(obj_id)
        self.session.add_point_inputs(obj_idx, self.frame, inputs)
        self.session.remove_mask_inputs(obj_idx, self.frame)
        self._mark_new_inputs(obj_id)
        return self._run()

    def _run(self) -> dict[int, np.ndarray]:
        """The model on the current frame (streaming: its features are in the cache)."""
        with inference_context(self.device, precision="float32"):
            out = self.model(inference_session=self.session, frame_idx=self.frame,
                             frame=self._pixels)
            low = out.pred_masks.float().reshape(-1, 1, *out.pred_masks.shape[-2:])
            logits = F.interpolate(low, size=self.view_shape, mode="bilinear",
                                   align_corners=False)[:, 0]
        self.logits = logits.cpu().numpy().astype(np.float32, copy=False)
        masks = self.logits > 0.0
        return {int(i): masks[n] for n, i in enumerate(out.object_ids)}

    # --- bounded memory -------------------------------------------------------------------
    def forget(self) -> None:
        """Drop what the model can no longer look at (call after each frame): non-conditioning
        outputs and tracked-frame marks older than :attr:`window` frames behind the current one,
        the inputs of earlier frames, cached features of earlier frames, the stored pixel
        values and the full-resolution masks of finished frames. Conditioning outputs are
        kept."""
        session, oldest = self.session, self.frame - self.window
        for obj_idx, outputs in session.output_dict_per_obj.items():
            for frame in [f for f in outputs["non_cond_frame_outputs"] if f < oldest]:
                del outputs["non_cond_frame_outputs"][frame]
            for kept in (outputs["cond_frame_outputs"], outputs["non_cond_frame_outputs"]):
                for out in kept.values():
                    out.pop("high_res_masks", None)  # Sam2VideoModel: read in its own frame only
            tracked = session.frames_tracked_per_obj[obj_idx]
            for frame in [f for f in tracked if f < oldest]:
                del tracked[frame]
            for inputs in (session.point_inputs_per_obj[obj_idx],
                           session.mask_inputs_per_obj[obj_idx]):
                for frame in [f for f in inputs if f < self.frame]:
                    del inputs[frame]
        cached = getattr(session.cache, "_vision_features", {})  # at most 1 (its size)
        for frame in [f for f in cached if f < self.frame]:
            del cached[frame]
        if session.processed_frames is not None:
            session.processed_frames.clear()
