"""Where a partly seen object's template lies, from the answer that found it (issue 47;
docs/design.md section 10, "Tracking", step 8: an answer's place).

A mostly hidden object is found by the part of its template that still shows, and that part
often fits the template's texture at several shifts: the shift the match chose is then no
measure of where the object is, and the velocity measured from it sends the next prediction
astray (seed 403: an ellipse behind the near occluder carried 14 pixels away from where it
was within three frames, then lost). Once the answer is accepted, SAM's mask says which pixels
are the object; :func:`answer_place` places the template where it explains them best:

* the template's pixels that look the same there (:func:`lfsam.video.tracking.match.robust_costs`'
  support, the view read only inside the answer) count for the place;
* the answer's pixels the template leaves uncovered count against it;
* so do the template's pixels that fall outside the answer where the view shows something
  *farther* than the object (by :data:`FARTHER` disparity pixels): the object would be in
  front there, and seen. Pixels nearer than the object (its occluder) contradict nothing.

The shifts are ranked by the two counts of where the template lies (correlations, every shift
within ``reach``) and the :data:`CANDIDATES` best scored with the look too. A shift replaces
the match's only where it scores better and explains :data:`EXPLAINED` of the answer, and
only where the template lies :data:`INSIDE` the frame (an object cut by the frame's border is
partial because of the border: the template can slide out of the frame at no cost). The
tracker asks only where the match was poorly supported (under
:data:`lfsam.video.tracking.motion.VELOCITY_SUPPORT` of the template) and the answer is a part of
the object (under :data:`lfsam.video.tracking.motion.KEEP_TEMPLATE` of its largest area): asked for
every partly seen object it also moved well supported matches and lost more than it found
(docs/performance.md, issue 47, twelfth pass).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy import signal

from lfsam.video.tracking.carry import Template, window_within
from lfsam.video.tracking.match import support_in_answer

__all__ = ["CHECK", "answer_place", "placed_by_answer"]

#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.placement_check`.
CHECK = True
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.placement_farther`.
FARTHER = 0.5
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.placement_inside`.
INSIDE = 0.6
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.placement_candidates`.
CANDIDATES = 12
#: What it decides and why: :attr:`~lfsam.video.tracking.config.TrackerConfig.placement_explained`.
EXPLAINED = 0.5


def _inside_share(template: Template, shape: tuple[int, int]) -> float:
    """The share of the template's pixels inside a frame of ``shape``."""
    _, valid, _ = window_within(template, np.zeros((*shape, 1), np.float32), (0, 0, 0, 0))
    return float((template.mask * valid).sum()) / max(int(template.mask.sum()), 1)


def _counts(values: np.ndarray, template: Template, reach: int) -> np.ndarray:
    """How many of the template's pixels land on ``values`` (a ``(U, V)`` bool map; none
    outside the frame) at every shift within ``reach`` (rows first), one FFT correlation."""
    window = window_within(template, values[..., None].astype(np.float32), (reach,) * 4)[0]
    return np.rint(signal.correlate(window[..., 0], template.mask.astype(np.float32),
                                    mode="valid", method="fft")).ravel()


def answer_place(mask: np.ndarray, template: Template, image: np.ndarray,
                 disparity: np.ndarray, object_disparity: float, reach: int
                 ) -> tuple[int, int] | None:
    """The shift of ``template`` (placed where its match found it) within ``reach`` pixels
    at which it explains the accepted answer ``mask`` best (module docstring), or None where
    its place stands.

    Parameters
    ----------
    mask : (U, V) bool array
        The answer: the object's visible pixels in the view.
    template : Template
        The object's template where its match placed it in that view.
    image : (U, V, 3) array
        The view.
    disparity : (U, V) float array
        The view's disparity map (NaN: unknown, contradicting nothing).
    object_disparity : float
        The answer's disparity.
    reach : int
        The largest shift looked at, in either axis.

    Returns
    -------
    (du, dv) or None
    """
    total = int(mask.sum())
    if reach < 1 or total == 0 or _inside_share(template, mask.shape) < INSIDE:
        return None
    with np.errstate(invalid="ignore"):
        farther = ~mask & (np.asarray(disparity) < object_disparity - FARTHER)
    covered, contradicted = _counts(mask, template, reach), _counts(farther, template, reach)
    du, dv = (g.ravel() for g in np.mgrid[-reach:reach + 1, -reach:reach + 1])
    distance = du**2 + dv**2
    where = 2 * covered - total - contradicted
    ranked = np.lexsort((distance, -where))[:CANDIDATES]
    zero = int(np.flatnonzero(distance == 0)[0])
    chosen = np.unique(np.append(ranked, zero))
    explained = support_in_answer(template, image, mask, du[chosen], dv[chosen])
    score = explained - (total - covered[chosen]) - contradicted[chosen]
    best = int(np.lexsort((distance[chosen], -score))[0])
    here = int(np.flatnonzero(chosen == zero)[0])
    if explained[best] < EXPLAINED * total or score[best] <= score[here]:
        return None
    return int(du[chosen[best]]), int(dv[chosen[best]])


def placed_by_answer(located: Template, mask: np.ndarray, image: np.ndarray,
                     disparity: np.ndarray, object_disparity: float, reach: int) -> Template:
    """``located`` moved to :func:`answer_place`'s shift (unchanged where there is none)."""
    shift = answer_place(mask, located, np.asarray(image, np.float32), disparity,
                         object_disparity, reach)
    if shift is None:
        return located
    return replace(located, origin=(located.origin[0] + shift[0],
                                    located.origin[1] + shift[1]))
