"""Meta's SAM 2 behind lfsam's segmenter interface (docs/design.md sections 3 and 6).

- :mod:`~lfsam.segmenters.sam2.build`: models from names, checkpoints or random weights, device
  and precision;
- :mod:`~lfsam.segmenters.sam2.backend`: :class:`Sam2Segmenter` (``encode`` once per view, then
  ``predict``, ``generate``, ``sample_features``), with its automatic mask generation in
  :mod:`~lfsam.segmenters.sam2.automatic` and its features for semantic occluding in
  :mod:`~lfsam.segmenters.sam2.features` (bases of the segmenter);
- :mod:`~lfsam.segmenters.sam2.decoder`: the batched mask decoder (many prompts share a view's
  image side);
- :mod:`~lfsam.segmenters.sam2.two_way`: its two-way transformer (absent points masked out);
- :mod:`~lfsam.segmenters.sam2.multiview`: prompts of several views in one decoder call;
- :mod:`~lfsam.segmenters.sam2.adapter`: the one place that touches sam2's private names.

Modules load on demand (``from lfsam.segmenters.sam2.backend import Sam2Segmenter``), so
importing the package does not import torch's model code.
"""
