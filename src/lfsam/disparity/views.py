"""The disparity of any view, resolved lazily and at most once per view (a cache).

Prompts may be given in any view (docs/design.md section 8), and an object prompted in view
``r = (s_r, t_r)`` is propagated with the disparity ``D_r`` of that view. :class:`ViewDisparities`
resolves the disparity of each view at most once, from any source
(:func:`lfsam.disparity.source.resolve_disparity`; a center-only map is forward-warped by
:func:`lfsam.disparity.center_warp.warp_center_disparity`), for the interactive predictor.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import Future

import numpy as np

from lfsam.disparity.center_warp import warp_center_disparity
from lfsam.disparity.epi import resolve_view
from lfsam.disparity.source import load_disparity_spec, resolve_view_disparity
from lfsam.lightfield import LightField

__all__ = ["ViewDisparities"]


class ViewDisparities:
    """The disparity of every view a caller asks for, resolved lazily and at most once per view.

    Parameters
    ----------
    lightfield : LightField
    spec : {"estimate", "gt"}, path to a .npy, or ndarray
        Any source :func:`lfsam.disparity.source.resolve_disparity` accepts. A file is read and
        checked once, here (so a bad file fails before any work).
    device : str, optional
        Where the estimator and the warps run.

    Examples
    --------
    >>> from lfsam.synth import generate_scene
    >>> lf = generate_scene(grid=(3, 3), size=(24, 32), num_objects=1)
    >>> views = ViewDisparities(lf, "gt")
    >>> views.get((0, 2)).shape, views.source((0, 2))
    ((24, 32), 'gt')
    """

    def __init__(
        self,
        lightfield: LightField,
        spec: str | os.PathLike | np.ndarray = "estimate",
        device: str | None = None,
    ) -> None:
        self.lightfield = lightfield
        self.device = device
        # a file becomes its (checked) array once; "estimate" and "gt" stay as they are
        self._spec, self._name = load_disparity_spec(spec, lightfield)
        self._cache: dict[tuple[int, int], tuple[np.ndarray, str, np.ndarray | None]] = {}
        self._carried: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}
        self._pending: dict[tuple[int, int], Future] = {}
        self._lock = threading.Lock()

    def prefetch(self, view: tuple[int, int] | None = None) -> None:
        """Start resolving ``view``'s disparity (default the center's) in a thread, for a
        caller that knows it will ask for it: an estimate then runs beside what the caller does
        first (encoding a view, a video model's memory), and :meth:`get` waits for it. The
        same array as without; an error is raised by the call that asks for it (docs/design.md
        section 8)."""
        key = resolve_view(self.lightfield.grid_shape, view)
        with self._lock:
            if key in self._cache or key in self._pending:
                return
            future: Future = Future()
            self._pending[key] = future

        def work() -> None:
            try:
                future.set_result(self._compute(key))
            except BaseException as exc:  # handed to the caller that asks for this view
                future.set_exception(exc)

        threading.Thread(target=work, name=f"lfsam-disparity-{key}", daemon=True).start()

    def _compute(self, key: tuple[int, int]) -> tuple[np.ndarray, str, np.ndarray | None]:
        disparity, source, holes = resolve_view_disparity(
            self._spec, self.lightfield, view=key, device=self.device, name=self._name
        )
        disparity = np.array(disparity, dtype=np.float32)
        disparity.flags.writeable = False
        return disparity, source, holes

    def _resolve(self, view: tuple[int, int] | None) -> tuple[np.ndarray, str, np.ndarray | None]:
        key = resolve_view(self.lightfield.grid_shape, view)
        with self._lock:
            found, pending = self._cache.get(key), self._pending.get(key)
        if found is not None:
            return found
        found = pending.result() if pending is not None else self._compute(key)
        with self._lock:
            self._pending.pop(key, None)
            return self._cache.setdefault(key, found)

    @property
    def estimated(self) -> bool:
        """Whether the disparity is the estimator's (``"estimate"``), not a given map."""
        return isinstance(self._spec, str) and self._spec == "estimate"

    def get(self, view: tuple[int, int] | None = None) -> np.ndarray:
        """Disparity of ``view`` (default the center), ``(U, V)`` float32, read-only."""
        return self._resolve(view)[0]

    def source(self, view: tuple[int, int] | None = None) -> str:
        """Where the disparity of ``view`` came from (for result metadata)."""
        return self._resolve(view)[1]

    def holes(self, view: tuple[int, int] | None = None) -> np.ndarray | None:
        """Pixels of ``view`` whose disparity was filled after a forward warp (None if none
        was warped)."""
        return self._resolve(view)[2]

    def warps_center(self, view: tuple[int, int]) -> bool:
        """Whether :meth:`carried` differs from :meth:`get` for ``view``: an estimate, in a view
        other than the center."""
        key = resolve_view(self.lightfield.grid_shape, view)
        return isinstance(self._spec, str) and self._spec == "estimate" and (
            key != self.lightfield.center
        )

    def carried(self, view: tuple[int, int]) -> np.ndarray:
        """Disparity of ``view`` for carrying its refined masks into other views (the sparse
        fill, docs/design.md section 3.7), ``(U, V)`` float32, read-only.

        A map of every view (ground truth, a file) or a center map forward-warped is what
        :meth:`get` gives. An *estimate* is not run again per view: the center view's estimate
        is forward-warped into ``view`` (:func:`lfsam.disparity.center_warp.
        warp_center_disparity`), one estimate per light field instead of one per refined view
        (about 1 s each for 9 x 9 views of 240 x 320 on a 2-core CPU), and the same whichever
        views were estimated before (results do not depend on the order of edits).
        """
        key = resolve_view(self.lightfield.grid_shape, view)
        if not self.warps_center(key):
            return self.get(key)
        return self._warped_center(key)[0]

    def carried_holes(self, view: tuple[int, int]) -> np.ndarray | None:
        """Pixels of :meth:`carried` that no center pixel landed on (filled from their
        neighbours, docs/design.md section 3.7), ``(U, V)`` bool, read-only; None where
        :meth:`carried` is :meth:`get` (every pixel known)."""
        key = resolve_view(self.lightfield.grid_shape, view)
        if not self.warps_center(key):
            return None
        return self._warped_center(key)[1]

    def _warped_center(self, key: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        if key not in self._carried:
            center = self.lightfield.center
            offset = (key[0] - center[0], key[1] - center[1])
            disparity, holes = warp_center_disparity(
                self.get(center).copy(), offset, device=self.device  # a writable copy for torch
            )
            disparity = np.array(disparity, dtype=np.float32)
            holes = np.array(holes, dtype=bool)
            disparity.flags.writeable = False
            holes.flags.writeable = False
            self._carried[key] = (disparity, holes)
        return self._carried[key]

    @property
    def resolved(self) -> list[tuple[int, int]]:
        """The views resolved so far."""
        return list(self._cache)
