"""Epipolar-plane images (EPIs) through the center view, with labels overlaid.

An EPI stacks one pixel row (or column) of every view along a line of the view grid
(Bolles, Baker & Marimont, "Epipolar-plane image analysis", IJCV 1987). With the package's
convention (docs/design.md section 1; :mod:`lfsam.geometry`) a scene point at ``(u, v)`` of the
center view ``(s_c, t_c)`` with disparity ``d`` lies at column ``v - d (t - t_c)`` of view ``(s_c,
t)`` and at row ``u - d (s - s_c)`` of view ``(s, t_c)``. So

- the *horizontal* EPI ``E_h[t, v] = L[s_c, t, u*, v]`` (one row per view column ``t``) shows the
  point as a straight line of slope ``dv/dt = -d``;
- the *vertical* EPI ``E_v[s, u] = L[s, t_c, u, v*]`` (one row per view row ``s``) shows it as a
  line of slope ``du/ds = -d``.

A segmentation that is consistent across views paints each such line in a single colour; paper
section 4.3 (Figure 2) reads consistency off EPIs taken along a line and *upsampled along the
subview axis*, which :func:`upsample_views` does by repeating each view's row ``k`` times (nearest
neighbour, so labels stay labels and every view keeps equal height).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from lfsam.errors import LfsamError
from lfsam.viz.layout import _matching_labels, _to_numpy, as_rgb_uint8, blank
from lfsam.viz.overlay import overlay_labels

__all__ = [
    "MARK_COLOR",
    "epi_figure",
    "epi_overlays",
    "horizontal_epi",
    "upsample_views",
    "vertical_epi",
]

#: Colour of the dotted line marking where the EPIs are taken (yellow, as in paper Figure 2).
MARK_COLOR = (255, 220, 0)


def _check_index(value: int, size: int, name: str, option: str) -> int:
    if not -size <= value < size:
        raise LfsamError(
            f"{name} {value} is outside the view (0..{size - 1}); choose {option} in that range"
        )
    return value % size


def horizontal_epi(array: ArrayLike, row: int, view_row: int | None = None) -> np.ndarray:
    """The horizontal EPI ``array[view_row, :, row]``: pixel row ``row`` of every view column.

    Parameters
    ----------
    array : array_like, shape (S, T, U, V, ...)
        Views ``(S, T, U, V, 3)``, labels ``(S, T, U, V)`` or any per-pixel field.
    row : int
        Pixel row ``u*``.
    view_row : int, optional
        View row ``s``; default the center ``S // 2``.

    Returns
    -------
    epi : ndarray, shape (T, V, ...)
        Row ``t`` is pixel row ``row`` of view ``(view_row, t)``; a point of disparity ``d``
        traces the line ``v(t) = v(t_c) - d (t - t_c)``.
    """
    array = _to_numpy(array)
    s_count, _, u_count = array.shape[:3]
    row = _check_index(row, u_count, "pixel row", "--row")
    if view_row is None:
        view_row = s_count // 2
    view_row = _check_index(view_row, s_count, "view row", "a view row")
    return array[view_row, :, row]


def vertical_epi(array: ArrayLike, col: int, view_col: int | None = None) -> np.ndarray:
    """The vertical EPI ``array[:, view_col, :, col]``: pixel column ``col`` of every view row.

    Parameters
    ----------
    array : array_like, shape (S, T, U, V, ...)
    col : int
        Pixel column ``v*``.
    view_col : int, optional
        View column ``t``; default the center ``T // 2``.

    Returns
    -------
    epi : ndarray, shape (S, U, ...)
        Row ``s`` is pixel column ``col`` of view ``(s, view_col)``; a point of disparity ``d``
        traces ``u(s) = u(s_c) - d (s - s_c)``. Transpose the first two axes to display it
        beside a view (``U`` rows, one column per view).
    """
    array = _to_numpy(array)
    _, t_count, _, v_count = array.shape[:4]
    col = _check_index(col, v_count, "pixel column", "--col")
    if view_col is None:
        view_col = t_count // 2
    view_col = _check_index(view_col, t_count, "view column", "a view column")
    return array[:, view_col, :, col]


def upsample_views(epi: ArrayLike, factor: int, axis: int = 0) -> np.ndarray:
    """Repeat every view of an EPI ``factor`` times along its view axis (nearest neighbour).

    Returns
    -------
    epi : ndarray
        ``epi.shape`` with ``factor`` times as many entries along ``axis``.
    """
    if int(factor) < 1:
        raise LfsamError(f"upsampling factor must be >= 1, got {factor}; use --upsample 1 or more")
    return np.repeat(_to_numpy(epi), int(factor), axis=axis)


def epi_overlays(
    views: ArrayLike,
    labels: ArrayLike | None = None,
    *,
    row: int | None = None,
    col: int | None = None,
    upsample: int = 8,
    center: tuple[int, int] | None = None,
    alpha: float = 0.5,
    boundaries: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal and vertical EPIs of the views, upsampled, with labels overlaid.

    Parameters
    ----------
    views : (S, T, U, V, 3) array_like, uint8
    labels : (S, T, U, V) array_like of int, optional
        Label field of every view (0 = no label).
    row, col : int, optional
        Pixel row of the horizontal EPI and pixel column of the vertical EPI; default ``U // 2``
        and ``V // 2``.
    upsample : int
        Each view's line is repeated this many times (paper Figure 2).
    center : (s, t), optional
        The view row of the horizontal EPI and view column of the vertical EPI; default
        ``(S // 2, T // 2)``.
    alpha, boundaries
        As in :func:`lfsam.viz.overlay.overlay_labels`; boundaries are found on the upsampled
        EPI, so a label change between neighbouring views shows as an edge.

    Returns
    -------
    horizontal : (T * upsample, V, 3) uint8 ndarray
    vertical : (U, S * upsample, 3) uint8 ndarray
        Displayed beside the view: pixel row ``u`` of the figure is pixel row ``u`` of the views,
        and view ``s`` occupies columns ``s * upsample .. (s + 1) * upsample - 1``.
    """
    views = _to_numpy(views)
    s_count, t_count, u_count, v_count = views.shape[:4]
    labels = _matching_labels(views, labels)
    s_c, t_c = (s_count // 2, t_count // 2) if center is None else center
    row = u_count // 2 if row is None else row
    col = v_count // 2 if col is None else col

    h_img = upsample_views(horizontal_epi(views, row, s_c), upsample)
    v_img = upsample_views(vertical_epi(views, col, t_c), upsample).transpose(1, 0, 2)
    h_lab = v_lab = None
    if labels is not None:
        h_lab = upsample_views(horizontal_epi(labels, row, s_c), upsample)
        v_lab = upsample_views(vertical_epi(labels, col, t_c), upsample).T
    kwargs = {"alpha": alpha, "boundaries": boundaries}
    return (
        overlay_labels(h_img, h_lab, **kwargs),
        overlay_labels(np.ascontiguousarray(v_img), None if v_lab is None else v_lab, **kwargs),
    )


def _mark_lines(image: np.ndarray, row: int, col: int, dash: int = 3) -> np.ndarray:
    """Dotted lines (``dash`` on, ``dash`` off) along pixel row ``row`` and column ``col``."""
    out = image.copy()
    on_v = (np.arange(out.shape[1]) // dash) % 2 == 0
    on_u = (np.arange(out.shape[0]) // dash) % 2 == 0
    out[row, on_v] = MARK_COLOR
    out[on_u, col] = MARK_COLOR
    return out


def epi_figure(
    views: ArrayLike,
    labels: ArrayLike | None = None,
    *,
    row: int | None = None,
    col: int | None = None,
    upsample: int = 8,
    center: tuple[int, int] | None = None,
    alpha: float = 0.5,
    boundaries: bool = True,
    gap: int = 4,
    mark: bool = True,
    background: int | tuple[int, int, int] = 255,
) -> np.ndarray:
    """The center view with its horizontal EPI below and its vertical EPI to the right.

    The classic EPI layout (paper Figure 2 shows such EPIs beside the views)::

        +-------------+---+-------------+
        | center view |gap| vertical EPI|   U rows
        +-------------+---+-------------+
        |            gap                |
        +-------------+---+-------------+
        |  horiz. EPI |   |   (blank)   |   T * upsample rows
        +-------------+---+-------------+
           V columns        S * upsample columns

    The horizontal EPI is aligned column for column with the view and the vertical EPI row for row;
    the dotted yellow lines (``mark``) show the row and column the EPIs are taken along.

    Parameters
    ----------
    views, labels, row, col, upsample, center, alpha, boundaries
        As in :func:`epi_overlays`.
    gap : int
        Pixels of ``background`` between the panels.
    mark : bool
        Draw the dotted lines on the center view.

    Returns
    -------
    figure : ndarray, shape (U + gap + T * upsample, V + gap + S * upsample, 3), uint8
    """
    views = _to_numpy(views)
    s_count, t_count, u_count, v_count = views.shape[:4]
    s_c, t_c = (s_count // 2, t_count // 2) if center is None else center
    row = _check_index(u_count // 2 if row is None else row, u_count, "pixel row", "--row")
    col = _check_index(v_count // 2 if col is None else col, v_count, "pixel column", "--col")
    h_img, v_img = epi_overlays(
        views,
        labels,
        row=row,
        col=col,
        upsample=upsample,
        center=(s_c, t_c),
        alpha=alpha,
        boundaries=boundaries,
    )
    view_labels = None if labels is None else _to_numpy(labels)[s_c, t_c]
    view = overlay_labels(
        as_rgb_uint8(views[s_c, t_c]), view_labels, alpha=alpha, boundaries=boundaries
    )
    if mark:
        view = _mark_lines(view, row, col)
    k = int(upsample)
    out = blank(u_count + gap + t_count * k, v_count + gap + s_count * k, background)
    out[:u_count, :v_count] = view
    out[:u_count, v_count + gap :] = v_img
    out[u_count + gap :, :v_count] = h_img
    return out
