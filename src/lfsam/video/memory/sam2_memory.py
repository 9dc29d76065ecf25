"""SAM 2's video memory over the sequence of reference views (docs/design.md section 10).

With a SAM 2 segmenter, each object's center-view mask at frame f + 1 comes from Meta's video
predictor (``SAM2VideoPredictor``, the per-object memory bank) run over one image per frame:
the center view of every light field. :class:`ReferenceMemory` drives it one frame at a time
(the light-field pipeline segments each frame from those masks before the next frame is read):

- :meth:`ReferenceMemory.next_frame` hands it frame f's center view (the only frame image it
  holds: the state's ``images`` is a one-frame window, :class:`_CurrentFrame`; no frame count
  is needed up front, so a live stream works: the state's ``num_frames`` grows with each
  frame). It runs the image encoder on it once, keeps the output where SAM 2 looks for it
  (``cached_features``) and returns the light-field segmenter's embedding of the same pass
  (:meth:`~lfsam.segmenters.sam2.backend.Sam2Segmenter.embedding_from_backbone`), so the
  frame's center view is encoded once for both (issue 35);
- :meth:`ReferenceMemory.add_mask` conditions an object on a mask at this frame
  (``add_new_mask``: an object's start or a re-prompt);
- :meth:`ReferenceMemory.track` runs the memory on this frame for every object
  (``propagate_in_video`` over this one frame);
- :meth:`ReferenceMemory.correct` adds negative clicks to an object's tracked mask at this frame
  (``add_new_points_or_box`` on a tracked frame: SAM 2's correction clicks).

Memory stays flat in F: after each frame the per-object outputs of frames the model can no
longer look at are dropped (:meth:`ReferenceMemory.forget`). At frame f + 1 SAM 2 reads the
non-conditioning outputs of at most ``n - 1`` earlier frames, f + 2 - n .. f, with
``n = max(num_maskmem, max_obj_ptrs_in_encoder)`` (its memory and its object pointers; 16 for
the published models), so after frame f everything older than f + 2 - n is dropped: exactly the
masks of an unbounded state (tested against Meta's full-video run), with n - 1 frames of
outputs held (besides each object's conditioning frames, one per prompted frame). The
weights, frame transform and state are the video baseline's
(:mod:`lfsam.baseline`): :func:`~lfsam.baseline.predictor.video_predictor_for`,
:func:`~lfsam.baseline.frames.video_frames` with the image predictor's transform (the encoder
sees the tensors the light-field segmenter encodes) and
:func:`~lfsam.baseline.frames.init_video_state`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from lfsam.baseline.predictor import MASK_THRESHOLD, quiet_sam2_video, video_predictor_for
from lfsam.errors import LfsamError
from lfsam.segmenters.base import Segmenter, ViewEmbedding
from lfsam.segmenters.sam2.build import inference_context

__all__ = ["ReferenceMemory", "has_video_memory", "reference_memory_for"]


def has_video_memory(segmenter: Segmenter) -> bool:
    """Whether ``segmenter`` is a SAM 2 image model whose video predictor lfsam can build."""
    if getattr(segmenter, "name", None) == "oracle" or getattr(segmenter, "model", None) is None:
        return False
    try:
        video_predictor_for(segmenter)
    except LfsamError:
        return False
    return True


def reference_memory_for(segmenter: Segmenter, view_shape: tuple[int, int],
                         required: bool = False) -> Any:
    """The video memory of ``segmenter`` over center views of ``view_shape``: Meta's SAM 2
    (:class:`ReferenceMemory`) or a transformers SAM 2 / EdgeTAM video checkpoint
    (:class:`lfsam.video.memory.hf_memory.TransformersReferenceMemory`); None for a segmenter
    without one (the oracle, SAM v1), or an :class:`LfsamError` naming the fix when ``required``."""
    if has_video_memory(segmenter):
        return ReferenceMemory(segmenter, view_shape)
    from lfsam.segmenters.transformers.backend import TransformersSegmenter

    if isinstance(segmenter, TransformersSegmenter):
        from lfsam.segmenters.transformers.video_build import video_memory_problem
        from lfsam.video.memory.hf_memory import TransformersReferenceMemory

        problem = video_memory_problem(segmenter.model)
        if problem is None:
            return TransformersReferenceMemory(segmenter, view_shape)
        if required:
            raise LfsamError(problem)
        return None
    if required:
        raise LfsamError(f"the {segmenter.name!r} segmenter has no video memory; track with "
                         "a SAM 2 or EdgeTAM --model, or with --tracking prompts")
    return None


class _CurrentFrame:
    """The state's ``images``: as long as the frames seen so far, holding only the current
    frame's tensor."""

    def __init__(self, device: torch.device) -> None:
        self.device = device
        self.index = -1
        self.tensor: torch.Tensor | None = None

    def __len__(self) -> int:
        return self.index + 1

    def __getitem__(self, index: int) -> torch.Tensor:
        if index != self.index or self.tensor is None:
            raise LfsamError(f"SAM 2 asked for frame {index}; only frame {self.index} is loaded")
        return self.tensor


class ReferenceMemory:
    """SAM 2's video predictor over the center views of a light-field video, one frame at a time.

    Parameters
    ----------
    segmenter : Segmenter
        A SAM 2 image segmenter; the video predictor shares its weights.
    view_shape : (U, V)
        Masks are returned at this size.
    """

    def __init__(self, segmenter: Segmenter, view_shape: tuple[int, int]) -> None:
        self.segmenter = segmenter
        self.predictor = video_predictor_for(segmenter)
        self.device = torch.device(self.predictor.device)
        self.view_shape = (int(view_shape[0]), int(view_shape[1]))
        self.frames = _CurrentFrame(self.device)
        # Meta's frame transform imports its image predictor (and torchvision): only for SAM 2
        from lfsam.baseline.frames import init_video_state

        self.state: dict[str, Any] = init_video_state(self.predictor, self.frames, view_shape)
        model = self.predictor
        #: Frames of per-object outputs kept behind the current one (lossless, see module doc).
        self.window = max(int(model.num_maskmem), int(model.max_obj_ptrs_in_encoder)) - 2
        self.frame = -1
        #: The mask logits ``(N, U, V)`` of the latest :meth:`track` or :meth:`correct`.
        self.logits = np.zeros((0, *view_shape), np.float32)

    @property
    def object_ids(self) -> list[int]:
        """Objects the memory tracks (in the order they were added)."""
        return list(self.state["obj_ids"])

    def next_frame(self, index: int, image: np.ndarray) -> ViewEmbedding | None:
        """Load frame ``index``'s center view ``(U, V, 3)`` uint8 (frames come in order) and
        encode it once.

        Returns
        -------
        ViewEmbedding or None
            The light-field segmenter's embedding of ``image`` from this encoder pass (give it
            to the pipeline: :meth:`lfsam.embeddings.EmbeddingStore.put`); None when the
            segmenter computes in another precision than the memory (bfloat16), which then
            encodes the view on its own.
        """
        if index <= self.frame:
            raise LfsamError(f"frames go forward: frame {index} after frame {self.frame}")
        image = np.asarray(image)
        from lfsam.baseline.frames import video_frames

        tensor = video_frames(image[None], int(self.predictor.image_size), self.device,
                              "image")[0]
        self.frames.index, self.frames.tensor, self.frame = index, tensor, index
        self.state["num_frames"] = index + 1
        self.state["cached_features"] = {}
        if getattr(self.segmenter, "autocast", None) is not None:
            return None
        batch = tensor[None]
        with inference_context(self.device):
            backbone_out = self.predictor.forward_image(batch)
        self.state["cached_features"] = {index: (batch, backbone_out)}
        return self.segmenter.embedding_from_backbone(backbone_out, image.shape[:2],
                                                      key=None)

    def add_mask(self, obj_id: int, mask: np.ndarray) -> None:
        """Condition ``obj_id`` on ``mask`` (U, V) at the current frame."""
        with inference_context(self.device), quiet_sam2_video():
            self.predictor.add_new_mask(self.state, self.frame, int(obj_id),
                                        torch.as_tensor(np.asarray(mask, bool)))

    def track(self) -> dict[int, np.ndarray]:
        """Every tracked object's mask (U, V) bool at the current frame (empty: not there)."""
        if not self.state["obj_ids"]:
            return {}
        with inference_context(self.device), quiet_sam2_video():
            for _, ids, logits in self.predictor.propagate_in_video(
                    self.state, start_frame_idx=self.frame, max_frame_num_to_track=0):
                return self._masks(ids, logits)
        return {}  # pragma: no cover - propagate_in_video always yields the start frame

    def correct(self, obj_id: int, negatives: Sequence[tuple[float, float]]
                ) -> dict[int, np.ndarray]:
        """Add negative clicks ``(x, y)`` to ``obj_id``'s tracked mask at the current frame;
        every object's mask there afterwards."""
        points = torch.tensor(np.asarray(negatives, np.float32).reshape(-1, 2))
        labels = torch.zeros(len(points), dtype=torch.int32)
        with inference_context(self.device), quiet_sam2_video():
            _, ids, logits = self.predictor.add_new_points_or_box(
                self.state, self.frame, int(obj_id), points=points, labels=labels,
                clear_old_points=True)
        return self._masks(ids, logits)

    def forget(self) -> None:
        """Drop per-object outputs the model can no longer look at (memory flat in F)."""
        oldest = self.frame - self.window
        for obj_idx, outputs in self.state["output_dict_per_obj"].items():
            stale = [f for f in outputs["non_cond_frame_outputs"] if f < oldest]
            for f in stale:
                del outputs["non_cond_frame_outputs"][f]
            tracked = self.state["frames_tracked_per_obj"][obj_idx]
            for f in [f for f in tracked if f < oldest]:
                del tracked[f]

    def _masks(self, ids: Sequence[int], logits: torch.Tensor) -> dict[int, np.ndarray]:
        self.logits = logits[:, 0].float().cpu().numpy()
        masks = self.logits > MASK_THRESHOLD
        return {int(i): masks[n] for n, i in enumerate(ids)}
