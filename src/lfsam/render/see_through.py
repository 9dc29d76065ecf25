"""Synthetic-aperture see-through (docs/design.md section 13).

Vaish et al. (2004), "Using plane + parallax for calibrating dense camera arrays", and (2006),
"Reconstructing occluded surfaces using synthetic apertures": focused behind an occluder, a
wide aperture averages it away. With view-consistent masks it need not be averaged at all:
every ray that hits a chosen object in its view (its mask there, grown by a pixel against
anti-aliased edges) is left out, and each pixel is normalised by the rays kept. The coverage
is the share of the aperture's views whose ray was kept (0 where none was: nothing seen).
Other objects in front of the focal plane (:func:`objects_in_front`) veil what lies behind
the chosen ones in the views that see them across it; their rays can be left out as well.
"""

from __future__ import annotations

import numpy as np
import torch

from lfsam.devices import resolve_device
from lfsam.errors import LfsamError
from lfsam.render.background_disparity import dilate, rim_disparity
from lfsam.render.shift import shift_and_add
from lfsam.render.views import check_masks, clip_focus, select_views, views_tensor

__all__ = ["GROW", "IN_FRONT", "behind_focus", "objects_in_front", "see_through"]

#: Pixels by which the object masks grow before their rays are left out.
GROW = 1
#: Disparity above the focus (pixels per view step) of an object in front of the focal plane.
IN_FRONT = 0.25


def objects_in_front(labels: np.ndarray, chosen: list[int], disparity: np.ndarray,
                     focus: float, margin: float = IN_FRONT) -> np.ndarray:
    """The masks of the other objects in front of the focal plane, in every view.

    Parameters
    ----------
    labels : (S, T, U, V) int array
        A result's label maps (0 = no object).
    chosen : list of int
        The objects seen through (left out of the answer).
    disparity : (U, V) float array
        The center view's disparity.
    focus : float
        The focal plane's disparity.
    margin : float
        How much nearer than the focus an object's median center disparity must be.

    Returns
    -------
    (S, T, U, V) bool array
        The union of the objects whose median disparity in the center view exceeds
        ``focus + margin`` (objects absent from the center view are left out).
    """
    labels = np.asarray(labels)
    center = labels[labels.shape[0] // 2, labels.shape[1] // 2]
    disparity = np.asarray(disparity)
    front = []
    for label in np.unique(center):
        if label <= 0 or int(label) in chosen:
            continue
        values = disparity[(center == label) & np.isfinite(disparity)]
        if values.size and float(np.median(values)) > focus + margin:
            front.append(int(label))
    return np.isin(labels, front)


def behind_focus(masks: np.ndarray, disparity: np.ndarray) -> float:
    """The disparity of what lies behind the objects: the surface their rim shows in the
    center view (:func:`lfsam.render.background_disparity.rim_disparity`).

    Raises
    ------
    LfsamError
        If the objects are not in the center view (give a focus instead).
    """
    masks = np.asarray(masks, dtype=bool)
    s_count, t_count = masks.shape[:2]
    value = rim_disparity(masks[s_count // 2, t_count // 2], disparity)
    if value is None:
        raise LfsamError("the objects are not seen in the center view; give --focus")
    return value


def see_through(
    views: np.ndarray,
    masks: np.ndarray,
    *,
    focus: float | None = None,
    disparity: np.ndarray | None = None,
    present: np.ndarray | None = None,
    aperture: float | None = None,
    disparity_range: tuple[float, float] | None = None,
    grow: int = GROW,
    occluders: np.ndarray | None = None,
    device: str | torch.device | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """See through the objects of ``masks``: refocus leaving out every ray that hits them.

    Parameters
    ----------
    views : (S, T, U, V, 3) uint8 array
    masks : (S, T, U, V) bool array
        The objects to see through, in every view (e.g. the union of a result's masks).
    focus : float, optional
        Disparity of the focal plane; default: what lies behind the objects
        (:func:`behind_focus`, needs ``disparity``).
    disparity : (U, V) float array, optional
        The center view's disparity (for the default focus).
    present, aperture, disparity_range, device
        As :func:`lfsam.render.refocus`.
    grow : int
        Pixels by which the masks grow before their rays are left out.
    occluders : (S, T, U, V) bool array, optional
        Other surfaces in front of the focal plane whose rays are left out too (e.g.
        :func:`objects_in_front`); they do not count in the coverage's "seen".

    Returns
    -------
    image : (U, V, 3) float32 array in [0, 255]
        The mean of the kept rays (0 where none was kept).
    coverage : (U, V) float32 array in [0, 1]
        Share of the aperture's views whose ray was kept.
    """
    views = np.asarray(views)
    masks = check_masks(masks, views)
    if focus is None:
        if disparity is None:
            raise LfsamError("see-through needs a focus or the center view's disparity")
        focus = behind_focus(masks, disparity)
    focus = clip_focus(focus, disparity_range)
    device = resolve_device("cpu" if device is None else device)
    chosen, offsets = select_views(views.shape[:2], present, aperture)
    images = views_tensor(views, chosen, device)
    blocked = masks if occluders is None else masks | check_masks(occluders, views)
    hit = torch.from_numpy(np.stack([blocked[s, t] for s, t in chosen])).to(device)
    keep = (~dilate(hit, grow)).float()
    total, weight = shift_and_add(images, offsets, focus, keep)
    kept = weight > 1e-3
    image = torch.where(kept, total / weight.clamp_min(1e-3), torch.zeros_like(total))
    coverage = (weight / max(len(chosen), 1)).clamp(0, 1)
    coverage = torch.where(kept, coverage, torch.zeros_like(coverage))
    return (
        image.permute(1, 2, 0).clamp(0, 255).cpu().numpy().astype(np.float32),
        coverage.cpu().numpy().astype(np.float32),
    )
