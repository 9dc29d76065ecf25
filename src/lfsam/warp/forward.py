"""The forward warp (:mod:`lfsam.warp`): every source pixel moved to its landing pixel in a
target view, and the z-buffer there (the largest disparity landing on each target pixel).

* :func:`forward_warp` — one (source, target) pair, in a :class:`ForwardWarp`, which answers
  visibility (:meth:`ForwardWarp.visible`, :meth:`ForwardWarp.hides`), hole filling
  (:meth:`ForwardWarp.fill_holes`) and which target pixels the source sees at all
  (:meth:`ForwardWarp.seen`, :meth:`ForwardWarp.frame_runs`, :class:`FrameRuns`);
* :func:`forward_warps` — several pairs in one batched pass, hole indices included
  (docs/design.md section 3.5, "batched warps");
* :func:`splat_masks`, :func:`fill_warp_holes` — masks carried through a warp, and the gaps the
  forward warp leaves filled from the source pixels behind them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import torch
import torch.nn.functional as F

from lfsam.warp.landing import landing_pixels

__all__ = ["ForwardWarp", "FrameRuns", "fill_warp_holes", "forward_warp", "forward_warps",
           "splat_masks"]


@dataclass
class FrameRuns:
    """Widths of the strips at a target view's frame border that the source view does not see.

    Attributes
    ----------
    top, bottom : (V,) int tensor
        Unseen pixels from the top / bottom edge, per column.
    left, right : (U,) int tensor
        Unseen pixels from the left / right edge, per row.

    Masks propagated from several source views into one target view each have their own
    runs: then every field has one row per mask, ``(N, V)`` or ``(N, U)`` (:meth:`stack`).
    """

    top: torch.Tensor
    bottom: torch.Tensor
    left: torch.Tensor
    right: torch.Tensor

    @property
    def per_mask(self) -> bool:
        """Whether each field holds one row per mask (:meth:`stack`), ``(N, V)`` / ``(N, U)``."""
        return self.top.dim() == 2

    def rows(self, index: torch.Tensor) -> FrameRuns:
        """The rows ``index`` of per-mask runs (:meth:`stack`)."""
        return FrameRuns(self.top[index], self.bottom[index], self.left[index],
                         self.right[index])

    @staticmethod
    def stack(runs: list[FrameRuns], counts: list[int]) -> FrameRuns:
        """Per-mask runs of masks from several source views: ``runs[k]`` repeated for the
        ``counts[k]`` masks of source view ``k``, in order (one row per mask).

        Examples
        --------
        >>> import torch
        >>> a = FrameRuns(*(torch.zeros(2, dtype=torch.int64) for _ in range(4)))
        >>> b = FrameRuns(*(torch.ones(2, dtype=torch.int64) for _ in range(4)))
        >>> FrameRuns.stack([a, b], [1, 2]).top.tolist()
        [[0, 0], [1, 1], [1, 1]]
        """

        def rows(name: str) -> torch.Tensor:
            return torch.cat([getattr(r, name)[None].expand(c, -1)
                              for r, c in zip(runs, counts, strict=True)])

        return FrameRuns(rows("top"), rows("bottom"), rows("left"), rows("right"))


@dataclass
class ForwardWarp:
    """Where every source pixel lands in one target view, and the z-buffer there.

    Built by :func:`forward_warp`. Source and target views have the same size ``(U, V)``.

    Attributes
    ----------
    target : (U * V,) int64 tensor
        Flat index of the nearest target pixel of each source pixel (``-1`` where not valid).
    valid : (U * V,) bool tensor
        The source pixel lands inside the target view.
    zbuffer : (U * V,) float tensor
        Largest (closest) source disparity landing on each target pixel; ``-inf`` where none.
    ds, dt : float
        Offset of the target view from the source view.
    """

    target: torch.Tensor
    valid: torch.Tensor
    zbuffer: torch.Tensor
    ds: float = 0.0
    dt: float = 0.0
    # Mask-independent answers, computed once per warp (a cached warp serves every object and
    # every edit of the interactive predictor): view size -> holes, seen pixels.
    _holes: dict = field(default_factory=dict, init=False, repr=False, compare=False)
    _seen: dict = field(default_factory=dict, init=False, repr=False, compare=False)
    _index: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def hole_disparity(self, view_size: tuple[int, int]) -> torch.Tensor:
        """Disparity at each target pixel: the z-buffer, with holes filled from neighbours.

        Forward-warping holes (pixels no source pixel lands on) next to landed pixels take the
        smallest (farthest) disparity of their landed 3 x 3 neighbours: a hole opened by a
        stretched surface has that surface around it, and one opened by a disocclusion shows
        what lies behind, i.e. the farther side. Pixels with no landed neighbour stay ``-inf``.

        Returns
        -------
        (U, V) float tensor
        """
        return _hole_disparity(self.zbuffer.reshape(1, *view_size))[0]

    def hole_sources(
        self, view_size: tuple[int, int]
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """Fillable holes and the source pixel each one shows (backward lookup).

        A hole ``q`` with disparity ``d`` (:meth:`hole_disparity`) shows source pixel
        ``q + d (ds, dt)`` under the convention of :mod:`lfsam.geometry`, rounded to even like
        :func:`forward_warp`'s default; holes whose source lies outside the source view are not
        fillable.

        Returns
        -------
        hole_u, hole_v, source_u, source_v : (K,) int64 tensors
            Computed once per view size and kept with the warp (treat them as read-only).
        """
        key = (int(view_size[0]), int(view_size[1]))
        if key not in self._holes:
            self._holes[key] = self._hole_sources(key)
        return self._holes[key]

    def _hole_sources(
        self, view_size: tuple[int, int]
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        width = view_size[1]
        index = self.hole_index(view_size)
        holes = torch.nonzero(index >= 0, as_tuple=True)[0]
        sources = index[holes]
        return holes // width, holes % width, sources // width, sources % width

    def hole_index(self, view_size: tuple[int, int]) -> torch.Tensor:
        """The dense form of :meth:`hole_sources`: per target pixel, the flat index of the
        source pixel a fillable hole shows, ``-1`` elsewhere (landed pixels, holes without a
        landed neighbour, holes whose source lies outside the source view).

        Computed without reading anything back to the host (no ``nonzero``), so a GPU never
        waits on it (docs/design.md section 3.5); computed once per view size and kept with
        the warp (treat it as read-only).

        Returns
        -------
        (U * V,) int64 tensor
        """
        key = (int(view_size[0]), int(view_size[1]))
        if key not in self._index:
            self._index[key] = _hole_index(self.zbuffer.reshape(1, *key), self.ds, self.dt)[0]
        return self._index[key]

    def seen(self, view_size: tuple[int, int]) -> torch.Tensor:
        """Target pixels the warp reaches: landed on or fillable holes, ``(U, V)`` bool.

        The rest of the target view shows content the source view does not see (mostly a strip
        entering at the frame border), about which a propagated mask knows nothing. Computed
        once per view size and kept with the warp (a copy is returned).
        """
        key = (int(view_size[0]), int(view_size[1]))
        if key not in self._seen:
            landed = torch.isfinite(self.zbuffer)
            self._seen[key] = (landed | (self.hole_index(key) >= 0)).reshape(key)
        return self._seen[key].clone()

    def frame_runs(
        self, view_size: tuple[int, int], seen: torch.Tensor | None = None
    ) -> FrameRuns:
        """Unseen runs from each frame edge (see :meth:`seen`), per row or column.

        ``seen`` may be passed when already computed.

        Returns
        -------
        FrameRuns
            ``top`` and ``bottom`` per column ``(V,)``, ``left`` and ``right`` per row ``(U,)``:
            the number of unseen pixels from that edge inwards.
        """
        if seen is None:
            seen = self.seen(view_size)
        unseen = (~seen).to(torch.int32)

        def run(edge_first: torch.Tensor) -> torch.Tensor:
            return torch.cumprod(edge_first, dim=1).sum(dim=1)

        return FrameRuns(
            top=run(unseen.T),
            bottom=run(unseen.flip(0).T),
            left=run(unseen),
            right=run(unseen.flip(1)),
        )

    def visible(self, disparity: torch.Tensor, tolerance: float) -> torch.Tensor:
        """Source pixels not hidden in the target view by a closer source pixel (z-buffer test).

        A pixel is occluded when a source pixel with a disparity larger by more than
        ``tolerance`` lands on the same target pixel (docs/design.md section 3, beyond the
        paper). Each pixel is compared with its own disparity.

        Parameters
        ----------
        disparity : (U, V) float tensor
            The source disparity the warp was built from.
        tolerance : float
            Pixels per view step.

        Returns
        -------
        (U * V,) bool tensor
        """
        flat = disparity.reshape(-1)
        landed = self.zbuffer[self.target.clamp(min=0)]
        return self.valid & (flat >= landed - tolerance)

    def hides(self, disparity: torch.Tensor, tolerance: float) -> torch.Tensor:
        """Target pixels where a source pixel closer than ``disparity`` lands (z-buffer test).

        The target-side form of :meth:`visible`, for masks already placed in the target view
        (whole-mask propagation): ``disparity`` is, at each target pixel, the disparity of the
        surface the mask puts there (:func:`shift_masks_with_disparity`), so a slanted surface
        is compared with its own disparity pixel by pixel and never hides itself.

        Parameters
        ----------
        disparity : (..., U, V) float tensor
            Disparity of what a mask shows at each target pixel.
        tolerance : float
            Pixels per view step.

        Returns
        -------
        (..., U, V) bool tensor
        """
        return self.zbuffer.reshape(disparity.shape[-2:]) > disparity + tolerance

    def splat(self, masks: torch.Tensor, keep: torch.Tensor | None = None) -> torch.Tensor:
        """:func:`splat_masks` with this warp."""
        return splat_masks(masks, self, keep)

    def fill_holes(
        self, coarse: torch.Tensor, masks: torch.Tensor, keep: torch.Tensor | None = None
    ) -> torch.Tensor:
        """:func:`fill_warp_holes` with this warp."""
        return fill_warp_holes(coarse, masks, self, keep)


def _max3x3(planes: torch.Tensor) -> torch.Tensor:
    """Maximum over each pixel's 3 x 3 neighbourhood of ``(B, U, V)`` planes, ``-inf`` beyond
    the border: ``max_pool2d(planes, 3, stride=1, padding=1)``, as a maximum over rows then
    over columns (four elementwise maxima; a tenth of the pooling's time on a CPU)."""
    padded = F.pad(planes, (1, 1, 1, 1), value=float("-inf"))
    rows = torch.maximum(torch.maximum(padded[:, :-2], padded[:, 1:-1]), padded[:, 2:])
    return torch.maximum(torch.maximum(rows[..., :-2], rows[..., 1:-1]), rows[..., 2:])


def _hole_disparity(zbuffer: torch.Tensor) -> torch.Tensor:
    """:meth:`ForwardWarp.hole_disparity` of ``(B, U, V)`` z-buffers at once."""
    landed = torch.isfinite(zbuffer)
    # Min over landed neighbours = -max over -z, with unlanded pixels at -inf (ignored).
    negated = torch.where(landed, -zbuffer, torch.full_like(zbuffer, float("-inf")))
    neighbour_min = -_max3x3(negated)
    return torch.where(landed, zbuffer, neighbour_min.nan_to_num(neginf=float("-inf")))


def _hole_index(
    zbuffer: torch.Tensor, ds: float | torch.Tensor, dt: float | torch.Tensor
) -> torch.Tensor:
    """:meth:`ForwardWarp.hole_index` of ``(B, U, V)`` z-buffers at once, ``(B, U * V)``;
    tensor offsets are ``(B, 1, 1)``, on the z-buffers' device and of their dtype."""
    batch, height, width = zbuffer.shape
    filled = _hole_disparity(zbuffer)
    hole = ~torch.isfinite(zbuffer) & torch.isfinite(filled)
    d = torch.where(hole, filled, torch.zeros_like(filled))
    rows = torch.arange(height, device=d.device)[:, None]
    cols = torch.arange(width, device=d.device)[None, :]
    src_u = torch.round(rows + d * ds).long()
    src_v = torch.round(cols + d * dt).long()
    hole &= (src_u >= 0) & (src_u < height) & (src_v >= 0) & (src_v < width)
    return torch.where(hole, src_u * width + src_v, -1).reshape(batch, -1)


def _zbuffers(disparity: torch.Tensor, target: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    """The z-buffer of ``(..., U, V)`` source disparities landing at ``target`` (``valid``;
    :func:`landing_pixels`): the largest disparity on each target pixel, ``-inf`` where none,
    ``(..., U * V)``."""
    lead, size = disparity.shape[:-2], disparity.shape[-2] * disparity.shape[-1]
    rows = lead.numel()  # 1 for a single view
    zbuffer = torch.full((rows, size + 1), float("-inf"), device=disparity.device,
                         dtype=disparity.dtype)
    # every pixel is scattered (no boolean selection, which would make a GPU wait for the
    # host): those that land nowhere go to a spare last slot, dropped after
    zbuffer.scatter_reduce_(
        1, torch.where(valid, target, size).reshape(rows, size), disparity.reshape(rows, size),
        reduce="amax", include_self=True,
    )
    return zbuffer[:, :size].reshape(*lead, size)


def forward_warp(
    disparity: torch.Tensor, ds: float, dt: float, *, halves: str = "even"
) -> ForwardWarp:
    """Forward-warp a source view's pixel grid into the target view at offset ``(ds, dt)``.

    Parameters
    ----------
    disparity : (U, V) float tensor
        Disparity of the source view (package convention), any reference view.
    ds, dt : float
        View-row and view-column offsets of the target view from the source view.
    halves : {"even", "up"}
        Rounding of exact halves (:func:`landing_pixels`).

    Returns
    -------
    ForwardWarp

    Examples
    --------
    A closer pixel (disparity 2) lands on the same target pixel as a background pixel:

    >>> import torch
    >>> disparity = torch.tensor([[0.0, 0.0, 2.0]])
    >>> warp = forward_warp(disparity, 0, 1)
    >>> warp.target.tolist(), warp.zbuffer.tolist()
    ([0, 1, 0], [2.0, 0.0, -inf])
    >>> warp.visible(disparity, tolerance=0.2).tolist()
    [False, True, True]
    """
    target, valid = landing_pixels(disparity, ds, dt, halves=halves)
    return ForwardWarp(target=target, valid=valid, zbuffer=_zbuffers(disparity, target, valid),
                       ds=float(ds), dt=float(dt))


def forward_warps(
    disparity: torch.Tensor,
    ds: Sequence[float],
    dt: Sequence[float],
    *,
    halves: str = "even",
    holes: bool = True,
) -> list[ForwardWarp]:
    """:func:`forward_warp` of several (source, target) pairs in one batched pass.

    The same warps as one :func:`forward_warp` per pair, element for element, with each
    warp's :meth:`ForwardWarp.hole_index` computed in the same pass: a streamed light field
    warps every reference view into every view, and on a GPU the pairs' kernel launches, not
    their arithmetic, are the cost (docs/design.md section 3.5, "batched warps").

    Parameters
    ----------
    disparity : (B, U, V) float tensor
        The source disparity of each pair (the same source may appear several times).
    ds, dt : sequences of B floats
        Offset of each pair's target view from its source view.
    halves : {"even", "up"}
        Rounding of exact halves (:func:`landing_pixels`).
    holes : bool
        Also compute each warp's hole index (kept with the warp).

    Returns
    -------
    list of B ForwardWarp
        Their tensors are views into batched ones (treat them as read-only).

    Examples
    --------
    >>> import torch
    >>> disparity = torch.tensor([[[0.0, 0.0, 2.0]]]).expand(2, -1, -1)
    >>> one, two = forward_warps(disparity, [0, 0], [1, -1])
    >>> one.target.tolist() == forward_warp(disparity[0], 0, 1).target.tolist()
    True
    >>> two.zbuffer.tolist()  # the close pixel lands outside the view
    [0.0, 0.0, -inf]
    """
    batch, height, width = disparity.shape
    device = disparity.device
    dtype = disparity.dtype if disparity.is_floating_point() else torch.float32
    offsets = torch.tensor([list(ds), list(dt)], dtype=dtype).to(device)[:, :, None, None]
    target, valid = landing_pixels(disparity, offsets[0], offsets[1], halves=halves)
    zbuffer = _zbuffers(disparity, target, valid)
    index = _hole_index(zbuffer.reshape(batch, height, width), offsets[0], offsets[1]) \
        if holes else None
    warps = []
    for k in range(batch):
        warp = ForwardWarp(target=target[k], valid=valid[k], zbuffer=zbuffer[k],
                           ds=float(ds[k]), dt=float(dt[k]))
        if index is not None:
            warp._index[(height, width)] = index[k]
        warps.append(warp)
    return warps


def splat_masks(
    masks: torch.Tensor, warp: ForwardWarp, keep: torch.Tensor | None = None
) -> torch.Tensor:
    """Move every pixel of each mask to its target pixel (nearest-pixel forward warping).

    Parameters
    ----------
    masks : (N, U, V) bool tensor
        Source-view masks.
    warp : ForwardWarp
    keep : (U * V,) bool tensor, optional
        Only these source pixels are moved (e.g. the pixels visible in the target view).

    Returns
    -------
    (N, U, V) bool tensor
    """
    n, height, width = masks.shape
    size = height * width
    source = warp.valid if keep is None else (warp.valid & keep)
    # every source pixel is scattered (no gather): those not moved go to a spare last column
    target = torch.where(source, warp.target, size).expand(n, -1)
    out = torch.zeros((n, size + 1), dtype=torch.uint8, device=masks.device)
    # a target pixel is in a mask if any source pixel landing on it is (max of 0/1; the bool
    # masks scattered as their bytes, no copy)
    out.scatter_reduce_(1, target, masks.reshape(n, size).view(torch.uint8), reduce="amax")
    return out[:, :size].view(torch.bool).reshape(n, height, width)


def fill_warp_holes(
    coarse: torch.Tensor,
    masks: torch.Tensor,
    warp: ForwardWarp,
    keep: torch.Tensor | None = None,
    *,
    dense: bool | None = None,
) -> torch.Tensor:
    """Fill forward-warping holes by looking their source up in the source masks.

    A hole pixel ``q`` gets the disparity ``d`` of :meth:`ForwardWarp.hole_disparity`; under the
    convention of :mod:`lfsam.geometry` it shows source pixel ``q + d (ds, dt)``
    (:meth:`ForwardWarp.hole_sources`), and takes that pixel's mask memberships (forward-warp
    the depth, backward-warp the masks).

    Parameters
    ----------
    coarse : (N, U, V) bool tensor
        Splatted masks of the target view (a modified copy is returned).
    masks : (N, U, V) bool tensor
        Source-view masks.
    warp : ForwardWarp
    keep : (U * V,) bool tensor, optional
        Source pixels allowed to contribute (e.g. visible ones).
    dense : bool, optional
        Look every pixel up through :meth:`ForwardWarp.hole_index` (O(N x U x V), nothing read
        back to the host) instead of the hole list (O(N x holes), one ``nonzero``); both give
        the same masks. Default: dense on CUDA, where a host round trip costs more than the
        work (docs/design.md section 3.5).

    Returns
    -------
    (N, U, V) bool tensor
    """
    n, height, width = coarse.shape
    if dense is None:
        dense = coarse.device.type == "cuda"
    if dense:
        index = warp.hole_index((height, width))
        hole = index >= 0
        sources = index.clamp(min=0)
        size = height * width
        values = torch.index_select(masks.reshape(n, size), 1, sources)
        if keep is not None:
            values = values & keep[sources][None]
        return torch.where(hole, values, coarse.reshape(n, size)).reshape(n, height, width)
    hole_u, hole_v, src_u, src_v = warp.hole_sources((height, width))
    if hole_u.numel() == 0 or n == 0:
        return coarse
    sources = src_u * width + src_v
    values = torch.index_select(masks.reshape(n, -1), 1, sources)
    if keep is not None:
        values = values & keep[sources][None]
    out = coarse.clone()
    out.reshape(n, -1)[:, hole_u * width + hole_v] = values
    return out
