"""Projecting the labels of every view into the center view with ground-truth disparity.

The cross-view metrics of paper section 4.1 compare masks in one frame: "we first backproject the
masks from each view into the reference view using the ground truth disparity". A pixel ``(u, v)``
of view ``(s, t)`` with disparity ``d`` is seen in the center view ``(s_c, t_c)`` at
``(u + d (s - s_c), v + d (t - t_c))`` (:func:`lfsam.warp.landing_pixels` with the step
``(s_c - s, t_c - t)``; docs/design.md section 1). Here each landing point is rounded to the
nearest pixel (halves round up), pixels landing outside the frame are dropped, and so are pixels
with a non-finite disparity. Label 0 means "unlabeled" and is never projected.

A projected view is a *set* of ``(center pixel, label)`` pairs: several pixels of one view may
land on the same center pixel (a surface hidden in the center view lands on its occluder), so one
center pixel may receive several labels from one view.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import torch

from lfsam.warp import landing_pixels

__all__ = [
    "ProjectedViews",
    "distinct",
    "iter_projected_views",
    "project_view_to_center",
    "project_views_to_center",
]


# Pixels projected per batch of views: big enough that per-operation overhead (thread start-up,
# which is severe on a CPU shared with other jobs) is amortised, small enough to bound memory.
BATCH_PIXELS = 1 << 21


@dataclass
class ProjectedViews:
    """The distinct ``(view, center pixel, label)`` triples that a batch of views projects.

    Attributes
    ----------
    views : list of (s, t)
        The source views of the batch; ``view`` indexes this list.
    view : (P,) int64 tensor
        Index into ``views`` of the source view of each triple.
    pixels : (P,) int64 tensor
        Flat index ``u * V + v`` of the center pixel hit.
    labels : (P,) int64 tensor
        The label that reaches it (never 0). Triples are unique, sorted by (view, pixel, label).
    """

    views: list[tuple[int, int]]
    view: torch.Tensor
    pixels: torch.Tensor
    labels: torch.Tensor


def project_views_to_center(
    labels: torch.Tensor,
    disparity: torch.Tensor,
    ds: torch.Tensor | list[int],
    dt: torch.Tensor | list[int],
    num_labels: int,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Project the labeled pixels of a batch of views into the center view.

    Parameters
    ----------
    labels : (B, U, V) integer tensor
        Labels of each view, ``0 <= label < num_labels``, 0 = unlabeled.
    disparity : (B, U, V) float tensor
        Ground-truth disparity of the same views (pixels per view step).
    ds, dt : (B,) ints
        Offsets ``(s - s_c, t - t_c)`` of each view from the center view.
    num_labels : int
        One more than the largest label (used to encode triples as single integers).

    Returns
    -------
    view, pixels, labels : (P,) int64 tensors
        The distinct ``(batch index, center pixel, label)`` triples, sorted. A pixel ``(u, v)``
        with disparity ``d`` lands on ``(u + d ds, v + d dt)`` rounded to the nearest pixel
        (paper section 4.1; convention of :mod:`lfsam.geometry`); out-of-frame landings and
        non-finite disparities are dropped.
    """
    count, height, width = labels.shape
    npix = height * width
    device = labels.device
    # The step from view (s, t) to the center is (s_c - s, t_c - t) = (-ds, -dt).
    steps = torch.as_tensor(ds, dtype=torch.float32, device=device).view(count, 1, 1)
    steps_t = torch.as_tensor(dt, dtype=torch.float32, device=device).view(count, 1, 1)
    target, valid = landing_pixels(disparity.float(), -steps, -steps_t, halves="up")
    flat_labels = labels.reshape(count, npix)
    keep = (flat_labels > 0) & valid
    view = torch.arange(count, device=device).view(count, 1).expand(count, npix)
    cell = view[keep] * npix + target[keep]
    keys = distinct(cell * num_labels + flat_labels[keep].long())
    cell = torch.div(keys, num_labels, rounding_mode="floor")
    view_out = torch.div(cell, npix, rounding_mode="floor")
    return view_out, cell - view_out * npix, keys - cell * num_labels


def project_view_to_center(
    labels: torch.Tensor,
    disparity: torch.Tensor,
    ds: int,
    dt: int,
    num_labels: int,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Project the labeled pixels of one view into the center view.

    Parameters
    ----------
    labels : (U, V) integer tensor
        Labels of the view (0 = unlabeled).
    disparity : (U, V) float tensor
        Its ground-truth disparity.
    ds, dt : int
        Offsets ``(s - s_c, t - t_c)`` of the view from the center view.
    num_labels : int
        One more than the largest label.

    Returns
    -------
    pixels, labels : (P,) int64 tensors
        The distinct ``(center pixel, label)`` pairs, sorted by pixel then label; see
        :func:`project_views_to_center`.
    """
    _, pixels, labs = project_views_to_center(
        labels[None], disparity[None], [ds], [dt], num_labels
    )
    return pixels, labs


def distinct(values: torch.Tensor) -> torch.Tensor:
    """The sorted distinct values of a 1-D tensor (sort, then drop repeats).

    Faster than :func:`torch.unique` on int64 on CPU, where the latter takes a slower path.
    """
    ordered = torch.sort(values).values
    if ordered.numel() < 2:
        return ordered
    keep = torch.ones_like(ordered, dtype=torch.bool)
    keep[1:] = ordered[1:] != ordered[:-1]
    return ordered[keep]


def iter_projected_views(
    labels: torch.Tensor,
    disparity: torch.Tensor,
    num_labels: int,
    batch_pixels: int = BATCH_PIXELS,
) -> Iterator[ProjectedViews]:
    """Project every view of a light field into its center view ``(S // 2, T // 2)``.

    Parameters
    ----------
    labels : (S, T, U, V) integer tensor
        Label field with labels in ``0 .. num_labels - 1`` (0 = unlabeled).
    disparity : (S, T, U, V) float tensor
        Ground-truth disparity of every view, on the same device.
    num_labels : int
        One more than the largest label.
    batch_pixels : int
        About how many pixels to project at once (whole views per batch, at least one).

    Yields
    ------
    ProjectedViews
        Batches of consecutive views in row-major order; the center view projects onto itself.
    """
    s_count, t_count, height, width = labels.shape
    s_c, t_c = s_count // 2, t_count // 2
    all_views = [(s, t) for s in range(s_count) for t in range(t_count)]
    flat_labels = labels.reshape(-1, height, width)
    flat_disp = disparity.reshape(-1, height, width)
    per_batch = max(1, batch_pixels // max(1, height * width))
    for first in range(0, len(all_views), per_batch):
        views = all_views[first : first + per_batch]
        view, pixels, labs = project_views_to_center(
            flat_labels[first : first + len(views)],
            flat_disp[first : first + len(views)],
            [s - s_c for s, _ in views],
            [t - t_c for _, t in views],
            num_labels,
        )
        yield ProjectedViews(views, view, pixels, labs)
