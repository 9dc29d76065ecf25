"""Template matching for the search of carried objects (issue 47; docs/design.md section 10,
"Tracking"), vectorised: one batch of FFTs for the masked SSD of every shift, one gather for
the robust cost of many shifts.

A template (:class:`lfsam.video.tracking.carry.Template`) may carry more channels than RGB: the
search adds the disparity as a fourth (:func:`with_depth`), so that an object is told from a
background of the same colours by its depth, the light field's own cue.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import torch
from scipy import fft

from lfsam.video.tracking.carry import (
    MAX_PIXEL_DIFFERENCE,
    Template,
    masked_cost,
    window_within,
)

__all__ = [
    "ALMOST", "BINS", "MAX_GATHER", "cost_map", "cost_maps", "fft_threads", "likely_shifts",
    "likely_shifts_many", "pixel_costs", "placed_at", "robust_costs", "support_in_answer",
    "with_depth",
]

#: At most this many (shift, pixel) pairs are gathered by :func:`robust_costs`: beyond it,
#: every k-th template pixel is scored and the sums are scaled (many shifts of a large
#: template near a prediction).
MAX_GATHER = 60_000


def fft_threads() -> int:
    """Threads for the batched FFTs: PyTorch's CPU thread count (``OMP_NUM_THREADS``,
    :func:`torch.set_num_threads`). scipy splits a batch of transforms between them, each
    transform computed as on one thread: the same numbers on any count."""
    return max(1, torch.get_num_threads())


def margins_in(templates: Sequence[Template], images: Sequence[np.ndarray],
               radius: int | None) -> tuple[int, int, int, int]:
    """The reach ``(top, left, bottom, right)`` of the shifts within ``radius`` pixels of each
    template's place that can overlap its frame (a shift laying the template wholly outside
    is never a match: the window is cut there, the same shifts scored in a smaller FFT);
    the largest over the templates, so that their windows have one shape."""
    reach = np.zeros(4, np.int64)
    for template, image in zip(templates, images, strict=True):
        height, width = image.shape[:2]
        h, w = template.mask.shape
        r0, c0 = template.origin
        whole = np.array([r0 + h, c0 + w, height - r0, width - c0])
        cut = np.clip(whole, 0, None if radius is None else int(radius))
        reach = np.maximum(reach, cut)
    return tuple(int(x) for x in reach)


def with_depth(template: Template, image: np.ndarray, disparity: np.ndarray | None,
               expected: float, tolerance: float) -> tuple[Template, np.ndarray]:
    """The template and the view with the disparity as a fourth channel, scaled so that
    ``tolerance`` disparity pixels weigh :data:`lfsam.video.tracking.carry.MAX_PIXEL_DIFFERENCE` (in
    the masked SSD a weight; in the robust cost a gate, :func:`pixel_costs`): the
    template's pixels all at ``expected``, the view's at its disparity map (unknown pixels at
    ``expected``: no evidence either way). Without a disparity map both are returned as they
    are."""
    if disparity is None:
        return template, image
    scale = MAX_PIXEL_DIFFERENCE / tolerance
    depth = np.where(np.isfinite(disparity), disparity, expected).astype(np.float32) * scale
    h, w = template.mask.shape
    own = np.full((h, w, 1), expected * scale, np.float32)
    return (replace(template, image=np.concatenate([template.image, own], -1)),
            np.concatenate([image, depth[..., None]], -1))


def cost_map(template: Template, image: np.ndarray, radius: int | None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The masked mean squared difference of ``template`` at every integer shift within
    ``radius`` pixels of its place (None: every shift where it overlaps the frame); inf where
    it overlaps the frame by less than :data:`lfsam.video.tracking.carry.MIN_PIXELS` and a fifth of
    its mask. The same numbers as :func:`lfsam.video.tracking.carry.cost_map` (up to rounding), from
    one batch of real FFTs: the channels' cross terms are summed before the one inverse transform,
    and the overlap counts are constants where the searched region lies inside the frame.

    Returns
    -------
    cost : (H, W) float array
    du, dv : (H, W) int arrays
        The shift of each entry.
    """
    h, w = template.mask.shape
    window, valid, margins = window_within(template, image, margins_in([template], [image], radius))
    rh, rw, channels = window.shape
    region = np.ascontiguousarray(np.moveaxis(window, -1, 0))  # (C, rh, rw)
    inside = bool(valid.all())
    m = template.mask.astype(np.float32)
    a = np.moveaxis(template.image, -1, 0) * m  # (C, h, w)
    shape = (fft.next_fast_len(rh, True), fft.next_fast_len(rw, True))
    # correlation = convolution with the flipped kernel; the valid part is not wrapped
    kernels = np.concatenate([a, m[None], (a**2).sum(0)[None]])[:, ::-1, ::-1]
    workers = fft_threads()
    k_hat = fft.rfft2(kernels, s=shape, workers=workers)
    signals = [region, (region**2).sum(0)[None]]
    if not inside:
        signals.append(valid[None])
    x_hat = fft.rfft2(np.concatenate(signals), s=shape, workers=workers)
    products = [(x_hat[:channels] * k_hat[:channels]).sum(0),
                x_hat[channels] * k_hat[channels]]
    if not inside:
        products += [x_hat[channels + 1] * k_hat[channels], x_hat[channels + 1]
                     * k_hat[channels + 1]]
    out = fft.irfft2(np.stack(products), s=shape, workers=workers)[:, h - 1:rh, w - 1:rw]
    cross, energy = out[0], out[1]
    if inside:
        count = np.full(cross.shape, m.sum())
        own = np.full(cross.shape, (a**2).sum())
    else:
        count, own = out[2], out[3]
    return masked_cost(own, cross, energy, count, float(m.sum()), margins)


#: Colour bins per channel of :func:`likely_shifts`' look-up (as
#: :func:`lfsam.video.tracking.carry.looks_alike`'s histograms).
BINS = 6
#: :func:`likely_shifts` keeps the shifts this nearly as likely as the likeliest.
ALMOST = 0.9


def likely_shifts(template: Template, image: np.ndarray, radius: int, count: int,
                  taken: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The shifts within ``radius`` pixels of the template's place where most of its pixels
    land on pixels that *could* support it (at most ``count``, those within :data:`ALMOST`
    of the likeliest), all shifts at once (:func:`likely_shifts_many` of one view)."""
    du, dv, _ = likely_shifts_many([template], [image], radius, count, [taken])[0]
    return du, dv


def likely_shifts_many(templates: Sequence[Template], images: Sequence[np.ndarray],
                       radius: int, count: int, taken: Sequence[np.ndarray | None]
                       ) -> list[tuple[np.ndarray, np.ndarray, int]]:
    """For each template in its image (the templates alike but for their origin: one object
    predicted in several views), the shifts within ``radius`` pixels of its place where most
    of its pixels land on pixels that *could* support it (at most ``count``, those within
    :data:`ALMOST` of the likeliest), every shift of every view from one batch of real FFTs.
    A view pixel could support the template where its colour lies in a colour bin of the
    template's pixels (:data:`BINS` per channel), it is not ``taken`` (a ``(U, V)`` bool
    mask of pixels known to be other objects, or None) and, with a disparity channel
    (:func:`with_depth`), it lies within the depth gate. The count is an upper bound of
    :func:`robust_costs`' support that does not pair pixels, so it is not led astray by a
    cover over most of the template as the masked SSD is: the candidates for an object
    whose prediction missed it (the search's widening stage,
    :func:`lfsam.video.tracking.search.search_object`), scored exactly by :func:`robust_costs`
    after.

    Returns
    -------
    list of (du, dv, bound)
        Per view the shifts (int arrays), the likeliest first (ties: the nearer; empty where
        no pixel could support the template) and the largest count.
    """
    first = templates[0]
    look = first.image[first.mask]

    def bins(values: np.ndarray) -> np.ndarray:
        q = np.clip((values[..., :3] * BINS / 256.0).astype(np.int64), 0, BINS - 1)
        return (q[..., 0] * BINS + q[..., 1]) * BINS + q[..., 2]

    present = np.zeros(BINS**3, bool)
    present[bins(look)] = True
    coulds, margins = [], []
    reach = margins_in(templates, images, radius)
    for template, image, known in zip(templates, images, taken, strict=True):
        window, valid, _ = window_within(template, image, reach)
        could = present[bins(window)] & (valid > 0)
        if known is not None:
            could &= window_within(template, known[..., None].astype(np.float32),
                               reach)[0][..., 0] == 0
        if window.shape[-1] > 3:  # the depth gate: the template's pixels are at one depth
            could &= np.abs(window[..., 3] - look[0, 3]) <= MAX_PIXEL_DIFFERENCE
        coulds.append(could)
        margins.append(reach)
    h, w = first.mask.shape
    rh, rw = coulds[0].shape
    shape = (fft.next_fast_len(rh, True), fft.next_fast_len(rw, True))
    workers = fft_threads()
    x_hat = fft.rfft2(np.stack(coulds).astype(np.float32), s=shape, workers=workers)
    k_hat = fft.rfft2(first.mask[::-1, ::-1].astype(np.float32), s=shape, workers=workers)
    scores = np.rint(fft.irfft2(x_hat * k_hat, s=shape, workers=workers)[:, h - 1:rh, w - 1:rw])
    out = []
    for score, (top, left, bottom, right) in zip(scores, margins, strict=True):
        du, dv = np.mgrid[-top:bottom + 1, -left:right + 1]
        score = score.ravel()
        # only the shifts scoring at least the count-th best can be among the first count
        # (the same order: the sort is stable, the keys the same)
        order = np.arange(score.size)
        if score.size > count:
            order = np.flatnonzero(score >= np.partition(score, score.size - count)[
                score.size - count])
        order = order[np.lexsort(((du**2 + dv**2).ravel()[order], -score[order]))][:count]
        best = int(score[order[0]])
        # the bound is flat over a part of the object seen whole (every shift that lays the
        # template over it): all of that plateau, not only its nearest shifts
        order = order[score[order] >= max(ALMOST * best, 1.0)]
        out.append((du.ravel()[order], dv.ravel()[order], best))
    return out


def cost_maps(templates: Sequence[Template], images: Sequence[np.ndarray], radius: int
              ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """:func:`cost_map` of each template in its image, the templates alike but for their
    origin (one object predicted in several views), from one batch of real FFTs: the
    template's transform once, the views' windows together. The same numbers as
    :func:`cost_map` up to rounding."""
    first = templates[0]
    h, w = first.mask.shape
    margins = margins_in(templates, images, radius)
    windows = [window_within(t, im, margins) for t, im in zip(templates, images, strict=True)]
    rh, rw, channels = windows[0][0].shape
    m = first.mask.astype(np.float32)
    a = np.moveaxis(first.image, -1, 0) * m  # (C, h, w)
    shape = (fft.next_fast_len(rh, True), fft.next_fast_len(rw, True))
    kernels = np.concatenate([a, m[None], (a**2).sum(0)[None]])[:, ::-1, ::-1]
    workers = fft_threads()
    k_hat = fft.rfft2(kernels, s=shape, workers=workers)
    # the windows laid straight into the transform's zero-padded input (what s=shape pads)
    signals = np.zeros((len(windows), channels + 2, *shape), np.float32)
    for k, (win, valid, _) in enumerate(windows):
        planes = signals[k, :channels, :rh, :rw]
        planes[...] = np.moveaxis(win, -1, 0)
        # the energy channel by channel, in the order a sum over the last axis adds them
        # (the same float32 numbers; a strided reduction took ten times longer)
        energy = signals[k, channels, :rh, :rw]
        np.square(planes[0], out=energy)
        for plane in planes[1:]:
            energy += plane**2
        signals[k, channels + 1, :rh, :rw] = valid
    x_hat = fft.rfft2(signals, workers=workers)  # (V, C + 2, ...)
    products = np.stack([(x_hat[:, :channels] * k_hat[:channels]).sum(1),
                         x_hat[:, channels] * k_hat[channels],
                         x_hat[:, channels + 1] * k_hat[channels],
                         x_hat[:, channels + 1] * k_hat[channels + 1]], 1)
    out = fft.irfft2(products, s=shape, workers=workers)[..., h - 1:rh, w - 1:rw]
    pixels, own_sum = m.sum(), (a**2).sum()
    results = []
    for k, (_, valid, margins) in enumerate(windows):
        cross, energy = out[k, 0], out[k, 1]
        if valid.all():  # as cost_map: the overlap terms are constants inside the frame
            count, own = np.full(cross.shape, pixels), np.full(cross.shape, own_sum)
        else:
            count, own = out[k, 2], out[k, 3]
        results.append(masked_cost(own, cross, energy, count, float(pixels), margins))
    return results


#: A value no pixel is near: the sentinel :func:`robust_costs` reads outside the frame.
_FAR = np.float32(1e6)


def robust_costs(template: Template, image: np.ndarray, du: np.ndarray, dv: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The *robust* cost of the template at each shift ``(du[k], dv[k])``: the sum over its
    pixels of the distance (summed over channels) truncated at
    :data:`lfsam.video.tracking.carry.MAX_PIXEL_DIFFERENCE`, a pixel outside the frame costing the
    truncation, so that pixels covered by something in front cost the same everywhere; and
    the support count (pixels under the truncation). One gather for all shifts (of at most
    :data:`MAX_GATHER` shift-pixel pairs: beyond it, of every k-th template pixel, scaled).

    Returns
    -------
    cost : (K,) float array
    count : (K,) int array
    """
    height, width = image.shape[:2]
    rows, cols = np.nonzero(template.mask)
    total = rows.size
    step = max(1, -(-np.size(du) * total // MAX_GATHER))
    if step > 1:  # many shifts of a large template: every step-th pixel, the sums scaled
        rows, cols = rows[::step], cols[::step]
    look = template.image[rows, cols]  # (N, C)
    r = template.origin[0] + rows[None, :] + np.asarray(du).reshape(-1, 1)
    c = template.origin[1] + cols[None, :] + np.asarray(dv).reshape(-1, 1)
    inside = (r >= 0) & (r < height) & (c >= 0) & (c < width)
    # one flat index, gathered channel by channel (the channels summed in place: as
    # pixel_costs, without a (K, N, C) array); a pixel outside the frame reads a sentinel
    # that costs the truncation
    index = np.where(inside, r * width + c, height * width)
    planes = np.concatenate([image.reshape(height * width, -1),
                             np.full((1, image.shape[-1]), _FAR, np.float32)]).T
    diff = np.abs(planes[0][index] - look[:, 0])
    for channel in (1, 2):
        diff += np.abs(planes[channel][index] - look[:, channel])
    if image.shape[-1] > 3:  # the depth gate (pixel_costs)
        diff[np.abs(planes[3][index] - look[:, 3]) > MAX_PIXEL_DIFFERENCE] = (
            MAX_PIXEL_DIFFERENCE)
    np.minimum(diff, MAX_PIXEL_DIFFERENCE, out=diff)
    scale = total / max(rows.size, 1)
    if step == 1:
        return diff.sum(1), (diff < MAX_PIXEL_DIFFERENCE).sum(1)
    return diff.sum(1) * scale, np.rint((diff < MAX_PIXEL_DIFFERENCE).sum(1) * scale).astype(int)


def support_in_answer(template: Template, image: np.ndarray, mask: np.ndarray,
                      du: np.ndarray, dv: np.ndarray) -> np.ndarray:
    """:func:`robust_costs`' support count of the template's colours at each shift
    ``(du[k], dv[k])``, the view read only inside the answer ``mask`` (a pixel outside it
    never looks the same): how much of an answer the template explains there
    (:func:`lfsam.video.tracking.search.explaining_shift`,
    :mod:`lfsam.video.tracking.placement`)."""
    inside = np.where(mask[..., None], image[..., :3], np.float32(1e4)).astype(np.float32)
    return robust_costs(replace(template, image=template.image[..., :3]), inside, du, dv)[1]


def pixel_costs(values: np.ndarray, look: np.ndarray) -> np.ndarray:
    """Each pixel's truncated distance to the template's (``(..., C)`` arrays): the RGB
    distance summed over channels, at most :data:`lfsam.video.tracking.carry.MAX_PIXEL_DIFFERENCE`;
    with a disparity channel (:func:`with_depth`) a pixel farther in depth than the tolerance
    costs the truncation whatever its colour (a gate, not a sum: an object whose depth
    changed within the tolerance keeps its support)."""
    colour = np.abs(values[..., :3] - look[..., :3]).sum(-1)
    if values.shape[-1] > 3:
        far = np.abs(values[..., 3] - look[..., 3]) > MAX_PIXEL_DIFFERENCE
        colour = np.where(far, MAX_PIXEL_DIFFERENCE, colour)
    return np.minimum(colour, MAX_PIXEL_DIFFERENCE)


def placed_at(template: Template, image: np.ndarray, du: int, dv: int
              ) -> tuple[np.ndarray, np.ndarray] | None:
    """``template``'s mask shifted by ``(du, dv)`` into the frame (clipped) and its support:
    the pixels whose cost (:func:`pixel_costs`) is under the truncation, as
    :func:`lfsam.video.tracking.carry.shifted` with the disparity gate. None outside the frame."""
    height, width = image.shape[:2]
    h, w = template.mask.shape
    r0, c0 = template.origin[0] + du, template.origin[1] + dv
    tr0, tc0 = max(-r0, 0), max(-c0, 0)
    ir0, ic0, ir1, ic1 = max(r0, 0), max(c0, 0), min(r0 + h, height), min(c0 + w, width)
    if ir1 <= ir0 or ic1 <= ic0:
        return None
    mask = np.zeros((height, width), bool)
    support = np.zeros((height, width), bool)
    sub = template.mask[tr0:tr0 + ir1 - ir0, tc0:tc0 + ic1 - ic0]
    look = template.image[tr0:tr0 + ir1 - ir0, tc0:tc0 + ic1 - ic0]
    mask[ir0:ir1, ic0:ic1] = sub
    same = pixel_costs(image[ir0:ir1, ic0:ic1], look) < MAX_PIXEL_DIFFERENCE
    support[ir0:ir1, ic0:ic1] = sub & same
    return mask, support
