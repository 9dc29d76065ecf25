"""The forward warps of a light field's run: cached, and built ahead in batched passes.

Step 2 of the pipeline (paper section 3.2) warps each reference view's disparity into every view
(:func:`lfsam.warp.forward_warp`); the warps are shared by the propagation, the refinement's
unseen strips and the fill, and kept for reuse across the interactive predictor's edits (an LRU
within :data:`WARP_CACHE_BYTES`). A streamed run knows every (reference view, view) pair it will
warp, in order (:meth:`WarpCache.plan`), and builds them ahead several at a time
(:func:`lfsam.warp.forward_warps`) within :data:`WARP_BATCH_BYTES` of working memory
(docs/design.md section 3.5, "batched warps").
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Iterable
from itertools import islice

import torch

from lfsam.timing import StageTimer
from lfsam.warp import ForwardWarp, forward_warp, forward_warps

__all__ = ["WARP_BATCH_BYTES", "WARP_CACHE_BYTES", "WarpCache"]

View = tuple[int, int]

#: Forward warps (reference view, target view) kept for reuse across edits, in bytes.
WARP_CACHE_BYTES = 512 * 2**20

#: Working memory of one batched warp pass (:func:`lfsam.warp.forward_warps`) over the pairs a
#: streamed run asks next, in bytes (about 64 bytes a pixel a pair), per device type: on a GPU
#: the passes' kernel launches are the cost, so many pairs go together; on a CPU the
#: arithmetic is, and a pass stays within the caches (a few pairs of small views, one of large).
WARP_BATCH_BYTES = {"cuda": 256 * 2**20, "cpu": 4 * 2**20}


def _footprint(warp: ForwardWarp) -> tuple[list[tuple[int, int]], int]:
    """What a cached warp holds: ``(address, bytes)`` of the memory blocks its arrays live
    in, and the bytes of what it makes later, a byte a pixel for the seen map and 8 for the
    hole index unless it has it already. The warps of one batched pass
    (:func:`lfsam.warp.forward_warps`, their hole indices too) are slices of shared blocks,
    freed only when the last of them is."""
    arrays = [warp.target, warp.valid, warp.zbuffer, *warp._index.values()]
    blocks = [(x.untyped_storage().data_ptr(), x.untyped_storage().nbytes()) for x in arrays]
    return blocks, (1 if warp._index else 9) * warp.valid.numel()


class WarpCache:
    """Forward warps of one light field, keyed by (source view, target view, carried).

    Parameters
    ----------
    view_shape : (U, V)
    device : torch.device
        Where the warps are built (picks the batch budget of :data:`WARP_BATCH_BYTES`).
    timer : StageTimer
        Building a warp counts as the ``propagate`` stage.
    """

    def __init__(
        self, view_shape: tuple[int, int], device: torch.device, timer: StageTimer
    ) -> None:
        self._view_shape = view_shape
        self._device = torch.device(device)
        self._timer = timer
        self._warps: OrderedDict[tuple[View, View, bool], ForwardWarp] = OrderedDict()
        self._bytes = 0
        #: Memory block address -> [bytes, cached warps in it] (:func:`_footprint`).
        self._blocks: dict[int, list[int]] = {}
        #: What each cached warp was counted with (:func:`_footprint` when it was kept).
        self._counted: dict[tuple[View, View, bool], tuple[list[tuple[int, int]], int]] = {}
        #: The (source, target) pairs planned, in order -> position.
        self._ahead: dict[tuple[View, View], int] = {}

    def get(
        self,
        disparity: Callable[[View, bool], torch.Tensor],
        source: View,
        target: View,
        carried: bool = False,
    ) -> ForwardWarp:
        """The warp of ``source``'s disparity (the carried one with ``carried``) into
        ``target``: cached, else built (with the planned pairs that follow it) from
        ``disparity(view, carried)``, the source disparity on the device
        (:meth:`lfsam.pipeline.engine.StreamingEngine.disparity`; asked, not kept, so the
        cache holds no reference to its engine)."""
        key = (source, target, carried)
        if key in self._warps:
            self._warps.move_to_end(key)
            return self._warps[key]
        if not carried and (source, target) in self._ahead:
            return self._build_ahead(disparity, source, target)
        with self._timer("propagate"):
            warp = forward_warp(
                disparity(source, carried), target[0] - source[0], target[1] - source[1]
            )
        self._keep(key, warp)
        return warp

    def plan(self, pairs: Iterable[tuple[View, View]]) -> None:
        """The (source, target) pairs the next steps ask, in order (each once; no pairs ends
        the plan): a miss builds the following ones with it."""
        self._ahead = {}
        for pair in pairs:
            self._ahead.setdefault(pair, len(self._ahead))

    @property
    def nbytes(self) -> int:
        """Memory the cached warps hold: every memory block their arrays live in, counted
        once however many warps share it (a batched pass's block until its last warp is
        dropped), plus the seen maps and hole indices the warps make later (:func:`_footprint`)."""
        return self._bytes

    def forget_source(self, view: View) -> None:
        """Drop the (not carried) warps out of ``view`` (its disparity changed)."""
        for key in [key for key in self._warps if key[0] == view and not key[2]]:
            self._drop(key)

    def _count(self, blocks: list[tuple[int, int]], extra: int, step: int) -> None:
        """Count a warp's footprint in (``step`` 1) or out (-1) of :attr:`nbytes`."""
        self._bytes += step * extra
        for address, size in blocks:
            block = self._blocks.setdefault(address, [size, 0])
            if block[1] == 0:
                self._bytes += size
            block[1] += step
            if block[1] == 0:
                self._bytes -= size
                del self._blocks[address]

    def _drop(self, key: tuple[View, View, bool]) -> None:
        del self._warps[key]
        self._count(*self._counted.pop(key), -1)

    def _keep(self, key: tuple[View, View, bool], warp: ForwardWarp) -> None:
        """Cache a warp (LRU within :data:`WARP_CACHE_BYTES` of :attr:`nbytes`)."""
        self._warps[key] = warp
        self._counted[key] = _footprint(warp)
        self._count(*self._counted[key], 1)
        while self._bytes > WARP_CACHE_BYTES and len(self._warps) > 1:
            self._drop(next(iter(self._warps)))

    def _build_ahead(
        self, disparity: Callable[[View, bool], torch.Tensor], source: View, target: View
    ) -> ForwardWarp:
        """The warp of ``(source, target)``, built in one batched pass with the planned pairs
        after it that are not cached (within :data:`WARP_BATCH_BYTES`): the same warps, a few
        passes a frame instead of one per (reference view, view) pair."""
        height, width = self._view_shape
        budget = WARP_BATCH_BYTES.get(self._device.type, WARP_BATCH_BYTES["cpu"])
        most = max(1, budget // (64 * height * width))
        start = self._ahead[(source, target)]
        chunk = list(islice((pair for pair in islice(self._ahead, start, None)
                             if (*pair, False) not in self._warps), most))
        with self._timer("propagate"):
            sources = torch.stack([disparity(s, False) for s, _ in chunk])
            warps = forward_warps(
                sources, [t[0] - s[0] for s, t in chunk], [t[1] - s[1] for s, t in chunk]
            )
        for (s, t), warp in zip(chunk, warps, strict=True):
            self._keep((s, t, False), warp)
        return warps[0]
