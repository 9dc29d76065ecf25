"""The disparity of each reference view, resolved once (docs/design.md section 8)."""

from __future__ import annotations

from typing import Any

import numpy as np

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField

__all__ = ["ViewDisparities"]

View = tuple[int, int]


class ViewDisparities:
    """Lazily resolved, cached disparity maps of the views of one light field.

    Parameters
    ----------
    lightfield : LightField
    spec : {"estimate", "gt"}, path to a .npy, or ndarray
        As :func:`lfsam.disparity.resolve_disparity`.
    device : str, optional
        Where the estimator runs.
    """

    def __init__(self, lightfield: LightField, spec: Any, device: str | None = None) -> None:
        self.lightfield = lightfield
        self.spec = spec
        self.device = device
        self._maps: dict[View, np.ndarray] = {}
        self._sources: dict[View, str] = {}

    def get(self, view: View) -> np.ndarray:
        """Disparity ``(U, V)`` float32 of ``view``."""
        view = (int(view[0]), int(view[1]))
        if view not in self._maps:
            self._maps[view], self._sources[view] = self._resolve(view)
        return self._maps[view]

    def sources(self) -> dict[View, str]:
        """Where each resolved view's disparity came from (for result metadata)."""
        return dict(self._sources)

    def _resolve(self, view: View) -> tuple[np.ndarray, str]:
        from lfsam.disparity import resolve_disparity

        lf = self.lightfield
        spec = self.spec
        if isinstance(spec, np.ndarray):
            array = np.asarray(spec, dtype=np.float32)
            if array.shape == (*lf.grid_shape, *lf.view_shape):
                return array[view], "array"
            if array.shape != lf.view_shape:
                raise LfsamError(
                    f"disparity has shape {array.shape}, expected {lf.view_shape} (center view) "
                    f"or {(*lf.grid_shape, *lf.view_shape)} (every view)"
                )
            if view != lf.center:
                raise LfsamError("a center-view disparity array cannot serve another view")
            return array, "array"
        if str(spec) == "gt" and lf.has_full_disparity:
            return np.asarray(lf.disparity[view], dtype=np.float32), "gt"
        if view == lf.center:
            return resolve_disparity(spec, lf, device=self.device)
        raise LfsamError(f"disparity {spec!r} of view {view} is not available")
