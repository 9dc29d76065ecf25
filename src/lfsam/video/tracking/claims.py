"""Competing claims on an answer found again (issue 47, ninth pass; docs/design.md section 10,
"Tracking", step 7).

The frame's carried objects are searched one after the other (:func:`lfsam.video.
frame_search.search_frame`, the surest first) and each takes the answer its search accepts.
Two hidden objects of alike colours can then claim the same pixels: the first searched takes
them, and the other, searched later, finds them placed already. Fresh seed 1402: a small
disc (object 4) hidden for four frames was "found again" on a sliver of object 1, which
re-entered at the frame's border where it had left; the disc's template explained 40 % of
that sliver, 58 pixels from its prediction (its search radius 49), object 1's 85 %, 31 pixels
from its own, at the same depth; the disc held object 1 from then on (an identity swap
between two clicked objects, both returns never found).

So an answer that gives an id back is checked against the other hidden objects still to be
searched in the frame (:func:`rival`): where one of them, at its predicted place in that
view within its search radius and at the answer's depth, explains the answer clearly
better (:func:`explained`: the share of the answer's pixels its template covers with pixels
that look the same, each weighted by how alike), that object is searched first and the
first one again after it (:func:`lfsam.video.tracking.frame_search.search_frame`): the answer goes
to the better explanation, and the other object keeps looking elsewhere (the pixels taken read
as placed). Each rival is searched once, so the frame's work stays bounded.

An answer grown past :data:`GROWN` times the object's largest area is checked the same way
against every object still to be searched, tracked ones too (twelfth pass): on fresh seed
1801 under the oracle's jitter a small tracked object, searched first, got an answer covering
its neighbour too (2.5x its area), and the neighbour's own answers, lying on those pixels,
were refused for the nine frames left (240 lost triples; 11 with the check).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import numpy as np

from lfsam.video.tracking.carry import MAX_PIXEL_DIFFERENCE
from lfsam.video.tracking.motion import Track, predicted, predicted_disparity, search_radius

__all__ = ["CHECK", "GROWN", "MAX_PAIRS", "RIVAL_MARGIN", "explained", "rival"]

#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.claims_check`.
CHECK = True
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.rival_margin`.
RIVAL_MARGIN = 0.1
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.claims_grown`.
GROWN = 1.5
#: At most this many (answer pixel, template pixel) pairs are compared (:func:`explained`;
#: beyond it every k-th answer pixel, the share unchanged in expectation).
MAX_PAIRS = 2_000_000


def explained(track: Track, view: tuple[int, int], mask: np.ndarray, image: np.ndarray,
              center: tuple[int, int], radius: int | None) -> float:
    """How much of the answer ``mask`` (in ``view``, whose image is ``image``) the track's
    template explains: the largest, over the template's shifts within ``radius`` of its
    predicted place in that view (None: any shift), of the sum over the template's pixels
    landing on the answer of ``MAX_PIXEL_DIFFERENCE - distance`` (the robust cost's
    truncation, :func:`lfsam.video.tracking.match.robust_costs`), divided by
    ``MAX_PIXEL_DIFFERENCE`` times the answer's area: 1 where the template covers every answer pixel
    with the same colour, 0 where none looks alike.

    Every (answer pixel, template pixel) pair votes for the shift that puts one on the other,
    so only shifts overlapping the answer are counted (exact, cost in the two areas'
    product, at most :data:`MAX_PAIRS`)."""
    if track.template is None or not mask.any():
        return 0.0
    template = predicted(track, view, center)
    rows, cols = np.nonzero(mask)
    area = rows.size
    t_rows, t_cols = np.nonzero(template.mask)
    step = max(1, -(-area * t_rows.size // MAX_PAIRS))
    rows, cols = rows[::step], cols[::step]
    look = template.image[t_rows, t_cols, :3].astype(np.float32)  # (M, 3)
    seen = image[rows, cols, :3].astype(np.float32)  # (N, 3)
    # (N, M) pairs, one channel at a time (no (N, M, 3) temporary)
    distance = np.abs(seen[:, None, 0] - look[None, :, 0])
    for channel in range(1, look.shape[1]):
        distance += np.abs(seen[:, None, channel] - look[None, :, channel])
    gain = np.minimum(distance, MAX_PIXEL_DIFFERENCE, out=distance)
    np.subtract(MAX_PIXEL_DIFFERENCE, gain, out=gain)
    # each pair votes for its shift (answer pixel - template pixel), as one index: rows and
    # columns apart by more than either extent, so no two shifts share an index
    t_rows, t_cols = t_rows + template.origin[0], t_cols + template.origin[1]
    lo_u, lo_v = int(rows.min() - t_rows.max()), int(cols.min() - t_cols.max())
    width = int(cols.max() - t_cols.min()) - lo_v + 1
    shift = ((rows - lo_u) * width + cols - lo_v)[:, None] - (t_rows * width + t_cols)[None, :]
    votes = np.bincount(shift.ravel(), weights=gain.ravel())
    if radius is not None:
        du, dv = np.divmod(np.arange(votes.size), width)
        votes[(du + lo_u) ** 2 + (dv + lo_v) ** 2 > radius**2] = 0.0
    return float(votes.max()) * step / (MAX_PIXEL_DIFFERENCE * area)  # gains are >= 0


def rival(obj_id: int, view: tuple[int, int], mask: np.ndarray, image: np.ndarray,
          tracks: dict[int, Track], pending: Iterable[int], center: tuple[int, int],
          depth: Callable[[tuple[int, int], np.ndarray], float | None],
          hidden_only: bool = True) -> int | None:
    """The hidden object among ``pending`` (still to be searched in this frame) that explains
    the answer ``obj_id`` found again (``view``, ``mask``) clearly better (module docstring),
    or None. ``depth(view, mask)``: the answer's median disparity (None: unknown).
    ``hidden_only`` False: tracked objects among ``pending`` too (an answer grown past
    :data:`GROWN` times the object's largest area)."""
    hidden = [i for i in pending if i != obj_id and tracks[i].template is not None
              and (tracks[i].unseen > 0 or not hidden_only)]
    if not hidden:
        return None
    value = depth(view, mask)
    own = explained(tracks[obj_id], view, mask, image, center, None)
    best, best_id = own + RIVAL_MARGIN, None
    for other in hidden:
        track = tracks[other]
        expected, tolerance = predicted_disparity(track)
        if value is not None and abs(value - expected) > tolerance:
            continue  # not at its depth: not that object
        share = explained(track, view, mask, image, center, search_radius(track))
        if share >= best:
            best, best_id = share, other
    return best_id
