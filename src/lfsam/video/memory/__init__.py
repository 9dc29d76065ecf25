"""The models' video memory over the sequence of center views (docs/design.md section 10).

- :mod:`~lfsam.video.memory.sam2_memory` — SAM 2's memory bank (Meta's video predictor) driven
  one frame at a time: :class:`ReferenceMemory`, and :func:`reference_memory_for`, which picks
  the memory of a segmenter;
- :mod:`~lfsam.video.memory.hf_memory` — the same for the ``transformers`` backend (EdgeTAM).

May import: :mod:`lfsam.video.io`, the segmenters and the SAM 2 video baseline
(:mod:`lfsam.baseline`). Never :mod:`lfsam.video.tracking` or :mod:`lfsam.video.stream`: the
tracker asks the memory for masks, the memory knows nothing of the tracker.
"""

from lfsam.video.memory.sam2_memory import ReferenceMemory, has_video_memory, reference_memory_for

__all__ = ["ReferenceMemory", "has_video_memory", "reference_memory_for"]
