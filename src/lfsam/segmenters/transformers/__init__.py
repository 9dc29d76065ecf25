"""SAM-family models through Hugging Face ``transformers`` (docs/design.md section 3.8):
EdgeTAM, transformers-format SAM 2 and SAM v1 checkpoints (SlimSAM, MedSAM).

- :mod:`~lfsam.segmenters.transformers.build`: model folders and configs, weights, tiny tests;
- :mod:`~lfsam.segmenters.transformers.model`: transformers' image encoder with SAM 2's heads
  as Meta's modules (:mod:`~lfsam.segmenters.transformers.heads`, weights mapped by
  :mod:`~lfsam.segmenters.transformers.convert`, Meta's architecture read as a ``Sam2Config`` by
  :mod:`~lfsam.segmenters.transformers.sam2_config`);
- :mod:`~lfsam.segmenters.transformers.backend`: :class:`TransformersSegmenter`, decoded by
  lfsam's batched SAM 2 decoder; :mod:`~lfsam.segmenters.transformers.sam1` for SAM v1 inputs;
- :mod:`~lfsam.segmenters.transformers.video_build`: the video models for memory tracking.

The package's name is the library's: inside it, ``import transformers`` still means Hugging
Face's package (absolute imports).
"""
