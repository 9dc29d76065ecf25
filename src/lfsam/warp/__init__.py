"""Moving pixels and masks from one view into another: the package's only warp.

Everything that carries pixels between views by disparity goes through this package: disparity
propagation (:mod:`lfsam.pipeline.propagation`), geometric occluding
(:mod:`lfsam.pipeline.propagation`) and the metrics' projection into the center view
(:mod:`lfsam.metrics.projection`). It is reference-agnostic: a *source* view (any view whose
disparity is known, not only the center) is warped into a *target* view at offset
``(ds, dt) = (s_target - s_source, t_target - t_source)`` by the convention of
:func:`lfsam.geometry.project_pixels` (docs/design.md sections 1 and 8).

* :func:`landing_pixels` — the nearest target pixel of each source pixel (batched;
  :mod:`lfsam.warp.landing`);
* :func:`forward_warp` — that, plus the z-buffer (largest disparity landing on each target pixel),
  in a :class:`ForwardWarp`, which answers visibility (:meth:`ForwardWarp.visible`,
  :meth:`ForwardWarp.hides`), hole filling (:meth:`ForwardWarp.fill_holes`) and which target
  pixels the source sees at all (:meth:`ForwardWarp.seen`, :meth:`ForwardWarp.frame_runs`);
* :func:`forward_warps` — several (source, target) pairs in one batched pass, hole indices
  included (docs/design.md section 3.5, "batched warps"; both in :mod:`lfsam.warp.forward`);
* :func:`shift_masks` — the whole-mask alternative: each mask translated by one sub-pixel shift,
  optionally carrying its own disparity along (:func:`shift_masks_with_disparity`);
* :func:`shift_whole_pixels` — one plane translated by whole pixels (exact, by slicing; both in
  :mod:`lfsam.warp.shift`).

Rounding to the nearest pixel is explicit (``halves``): the pipeline rounds exact halves to even
(``torch.round``), the metrics round them up (``floor(x + 0.5)``, which keeps a constant
half-pixel shift a translation); both are kept so that results are unchanged
(docs/design.md section 5).
"""

from lfsam.warp.forward import (
    ForwardWarp,
    FrameRuns,
    fill_warp_holes,
    forward_warp,
    forward_warps,
    splat_masks,
)
from lfsam.warp.landing import HALVES, landing_pixels
from lfsam.warp.shift import shift_masks, shift_masks_with_disparity, shift_whole_pixels

__all__ = [
    "HALVES",
    "ForwardWarp",
    "FrameRuns",
    "fill_warp_holes",
    "forward_warp",
    "forward_warps",
    "landing_pixels",
    "shift_masks",
    "shift_masks_with_disparity",
    "shift_whole_pixels",
    "splat_masks",
]
