"""What the objects of one light field share in the streaming engine (docs/design.md sections 3
and 8): each view's embedding (:class:`lfsam.embeddings.EmbeddingStore`, encoded at most once),
its disparity (:class:`lfsam.disparity.views.ViewDisparities`, resolved once, on the device),
the forward warps between views (:class:`lfsam.pipeline.warps.WarpCache`), the objects' clicks
carried into a view, the stage timer, which views are refined (docs/design.md section 3.7),
the run's metadata and the labels' fusion, timed.

:class:`SharedViews` is the base of :class:`lfsam.pipeline.engine.StreamingEngine`, which runs
the four steps over these views; it knows nothing of the steps.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
import torch

from lfsam.disparity.non_lambertian import surface_disparity_of_view
from lfsam.disparity.views import ViewDisparities
from lfsam.embeddings import EmbeddingStore
from lfsam.lightfield import LightField
from lfsam.pipeline.config import PipelineConfig
from lfsam.pipeline.fusion import fuse_packed
from lfsam.pipeline.objects import (
    Clicks,
    ObjectTable,
    TrackedObject,
    View,
    clicks_in_view,
)
from lfsam.pipeline.propagation import ForwardWarp
from lfsam.pipeline.sparse import nearest_sources, refined_views
from lfsam.pipeline.warps import WarpCache
from lfsam.segmenters.base import Segmenter, ViewEmbedding
from lfsam.timing import StageTimer

__all__ = ["SharedViews"]


class SharedViews:
    """A light field's views as the engine shares them between objects (module docstring).

    Parameters
    ----------
    segmenter : Segmenter
    config : PipelineConfig
    lightfield : LightField
    disparity : {"estimate", "gt"}, path to a .npy, or ndarray
        Resolved lazily, once per view asked (:class:`lfsam.disparity.views.ViewDisparities`).
    cache_dir : path, optional
        On-disk embedding cache.
    memory_budget_mb : float
        In-memory embedding budget.
    progress : bool
        A progress bar over views in :meth:`StreamingEngine.run`.
    """

    def __init__(
        self,
        segmenter: Segmenter,
        config: PipelineConfig,
        lightfield: LightField,
        disparity: Any = "estimate",
        *,
        cache_dir: Any = None,
        memory_budget_mb: float = 2048.0,
        progress: bool = False,
    ) -> None:
        self.segmenter = segmenter
        self.config = config
        self.lightfield = lightfield
        self.device = segmenter.device
        self.progress = progress
        self.timer = StageTimer(self.device)
        self.decode_counts: Counter[int] = Counter()
        """Prompts decoded per object id (each decoder row counts once)."""
        self.disparities = ViewDisparities(lightfield, disparity, device=str(self.device))
        self.store = EmbeddingStore(
            segmenter, lightfield.views, cache_dir=cache_dir, memory_budget_mb=memory_budget_mb
        )
        self._disp_tensors: dict[tuple[View, bool], torch.Tensor] = {}
        #: Silhouettes of the objects referenced in a view (the surface depth of glass and
        #: mirrors, :meth:`StreamingEngine._surface_masks`).
        self._surfaces: dict[View, np.ndarray] = {}
        #: Forward warps, cached and built ahead (:mod:`lfsam.pipeline.warps`).
        self.warps = WarpCache(lightfield.view_shape, self.device, self.timer)
        self._base: frozenset[View] | None = None
        self._base_key: tuple[bool, str | int] | None = None


    # --- shared per-view data ----------------------------------------------------------------
    def embedding(self, view: View) -> ViewEmbedding:
        """The embedding of ``view`` (encoded on first use, then cached)."""
        with self.timer("encode"):
            return self.store.get(view)

    def disparity(self, view: View, carried: bool = False) -> torch.Tensor:
        """Disparity of ``view`` on the segmenter's device (resolved once); with ``carried``,
        the one for carrying refined masks out of it
        (:meth:`lfsam.disparity.views.ViewDisparities.carried`)."""
        view = (int(view[0]), int(view[1]))
        carried = carried and self.disparities.warps_center(view)
        key = (view, carried)
        if key not in self._disp_tensors:
            with self.timer("disparity"):
                disp = self.disparities.carried(view) if carried else self.disparities.get(view)
                if view in self._surfaces and not carried:
                    disp, _ = surface_disparity_of_view(
                        self.lightfield.views, view, disp, self._surfaces[view],
                        self.lightfield.present, device=self.device,
                    )
            self._disp_tensors[key] = torch.tensor(disp, dtype=torch.float32, device=self.device)
        return self._disp_tensors[key]

    def _timed_disparity(self, view: View) -> np.ndarray:
        """The disparity of ``view`` as an array, its resolution (an estimate on first use)
        timed as the ``disparity`` stage, also inside another stage (issue 46)."""
        with self.timer("disparity"):
            return self.disparities.get(view)

    def warp(self, source: View, target: View, carried: bool = False) -> ForwardWarp:
        """The forward warp of ``source``'s disparity into ``target`` (cached, LRU); with
        ``carried``, of its disparity for carrying masks (:meth:`disparity`)."""
        carried = carried and self.disparities.warps_center(source)
        return self.warps.get(self.disparity, source, target, carried)

    def clicks_in_view(
        self, obj: TrackedObject, view: View, zbuffer_test: bool = True
    ) -> tuple[np.ndarray, np.ndarray]:
        """The object's clicks carried into ``view`` (:func:`lfsam.pipeline.objects.
        clicks_in_view`), with the z-buffer test of the cached warps."""
        if obj.clicks is None:
            obj.clicks = Clicks.of(obj.prompts, self._timed_disparity, self.lightfield.view_shape)
        zbuffer = (lambda source: self.warp(source, view).zbuffer) if zbuffer_test else None
        return clicks_in_view(
            obj.clicks, view, self.lightfield.view_shape, zbuffer, self.config.zbuffer_tolerance
        )

    def gray(self, view: View) -> torch.Tensor:
        """The view's gray image in [0, 1] on the device (the fill's guide)."""
        image = torch.as_tensor(np.asarray(self.lightfield.views[view]), device=self.device)
        return image.to(torch.float32).mean(dim=-1) / 255.0


    # --- which views are refined (docs/design.md section 3.7) -------------------------------
    @property
    def base_refined(self) -> frozenset[View] | None:
        """The views refined for every object, None for all of them (the paper):
        :func:`lfsam.pipeline.sparse.refined_views` of the configuration's ``refine_views``
        (None too without refinement)."""
        key = (self.config.refine, self.config.refine_views)
        if self._base_key != key:
            lf = self.lightfield
            self._base = (
                refined_views(self.config.refine_views, lf.present, lf.center)
                if self.config.refine
                else None
            )
            self._base_key = key
        return self._base

    def refines(self, view: View, reference: View) -> bool:
        """Whether steps 3-4 run in ``view`` for the objects whose reference view is
        ``reference``: every view with ``refine_views="all"``, else the base set
        (:attr:`base_refined`) and the reference view itself."""
        base = self.base_refined
        return base is None or view in base or view == reference

    def fill_sources(self, view: View, reference: View) -> list[View]:
        """The refined views a view not refined takes its masks from, nearest first
        (:func:`lfsam.pipeline.sparse.nearest_sources`)."""
        base = self.base_refined
        return nearest_sources(view, (base or frozenset()) | {reference})

    def refined_views(self, objects: ObjectTable) -> np.ndarray:
        """``(S, T)`` bool: the views refined for at least one of ``objects``
        (:meth:`refined_flags` of their reference views)."""
        center = self.lightfield.center
        return self.refined_flags([objects[i].reference_view(center) for i in objects.ids])

    def renumber_counts(self, mapping: Mapping[int, int]) -> None:
        """Move the decode counts of renumbered objects (``mapping``: old id -> new id)."""
        moved = {old: self.decode_counts.pop(old, 0) for old in mapping}
        for old, new in mapping.items():
            if moved[old]:
                self.decode_counts[new] = moved[old]

    def run_meta(self) -> dict[str, Any]:
        """The run's metadata that the engine knows: the segmenter, the configuration, the
        views encoded and present, and where each reference view's disparity came from
        (result ``meta``)."""
        lf = self.lightfield
        resolved = self.disparities.resolved
        return {
            "segmenter": self.segmenter.describe(),
            "config": self.config.to_dict(),
            "views_encoded": self.store.views_encoded,
            "views_present": int(lf.present.sum()),
            "disparity_source": self.disparities.source(
                lf.center if lf.center in resolved or not resolved else resolved[0]
            ),
            "disparity_sources": {
                f"{s},{t}": self.disparities.source((s, t)) for s, t in resolved
            },
        }

    def refined_flags(self, references: Iterable[View]) -> np.ndarray:
        """``(S, T)`` bool: the views refined for at least one object whose reference view is
        among ``references`` (result metadata ``refined_views``)."""
        lf = self.lightfield
        base = self.base_refined
        if base is None:
            return np.asarray(lf.present, dtype=bool).copy()
        flags = np.zeros(lf.grid_shape, dtype=bool)
        for view in (*base, *references):
            flags[view] = True
        return flags

    # --- labels ------------------------------------------------------------------------------
    def fuse(
        self, ids: list[int], bits: Mapping[int, np.ndarray], paint_order: list[int]
    ) -> np.ndarray:
        """:func:`lfsam.pipeline.fusion.fuse_packed` (docs/design.md section 3.6), timed."""
        with self.timer("fuse"):
            return fuse_packed(self.lightfield, ids, bits, paint_order)
