"""A label palette: every label id gets the same colour in every view, figure and result.

The colour of label ``k`` depends on ``k`` alone (never on how many labels a result has), so the
same id is drawn in the same colour across views, across figures and across two compared results
(paper Figure 2 compares ours and the video baseline side by side). Label 0 means "no label"
(docs/design.md section 1) and gets no colour.

The hues follow the golden-angle sequence ``h_k = frac(k / phi)`` with ``phi = (1 + sqrt 5) / 2``
(the low-discrepancy sequence used for phyllotaxis and for quasi-random colour generation, see
M. Ankerl, "How to generate random colors programmatically", 2009): consecutive ids are
``360 deg / phi^2 ~ 137.5 deg`` apart in hue, and any ``n`` first ids spread almost evenly over the
colour wheel. Saturation and value cycle with small periods co-prime to each other so ids whose
hues nearly coincide (e.g. ``k`` and ``k + 21``) still differ in brightness or saturation.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["NO_LABEL_COLOR", "colorize_labels", "label_colors", "palette"]

#: Colour returned for label 0 ("no label"); overlays leave such pixels untouched.
NO_LABEL_COLOR = (0, 0, 0)

_INV_PHI = (np.sqrt(5.0) - 1.0) / 2.0  # 1 / golden ratio
_SATURATIONS = np.array([0.90, 0.65])
_VALUES = np.array([1.00, 0.82, 0.92])


def _hsv_to_rgb(h: np.ndarray, s: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Vectorised HSV -> RGB in [0, 1] (A. R. Smith, "Color gamut transform pairs", 1978)."""
    i = np.floor(h * 6.0).astype(np.int64) % 6
    f = h * 6.0 - np.floor(h * 6.0)
    p = v * (1.0 - s)
    q = v * (1.0 - s * f)
    t = v * (1.0 - s * (1.0 - f))
    # Rows: which of (v, t, p, q) each channel takes for hue sector i = 0..5.
    choices = np.stack([v, t, p, q], axis=-1)  # (..., 4)
    table = np.array(
        [[0, 1, 2], [3, 0, 2], [2, 0, 1], [2, 3, 0], [1, 2, 0], [0, 2, 3]], dtype=np.int64
    )
    return np.take_along_axis(choices, table[i], axis=-1)


def label_colors(ids: ArrayLike) -> np.ndarray:
    """The RGB colour of each label id.

    Parameters
    ----------
    ids : array_like of int
        Label ids, ``>= 0``; any shape.

    Returns
    -------
    colors : ndarray, shape ``ids.shape + (3,)``, uint8
        ``NO_LABEL_COLOR`` for id 0; for ``k >= 1`` hue ``frac(k / phi)``, saturation
        ``(0.90, 0.65)[k % 2]`` and value ``(1.00, 0.82, 0.92)[k % 3]`` (module docstring).

    Raises
    ------
    ValueError
        If an id is negative.
    """
    ids = np.asarray(ids)
    if ids.size and ids.min() < 0:
        raise ValueError("label ids must be >= 0 (0 = no label)")
    k = ids.astype(np.int64)
    # frac(k / phi) computed in float64 is exact enough for ids up to ~1e12.
    hue = np.mod(k * _INV_PHI, 1.0)
    rgb = _hsv_to_rgb(hue, _SATURATIONS[k % 2], _VALUES[k % 3])
    out = np.rint(rgb * 255.0).astype(np.uint8)
    out[k == 0] = NO_LABEL_COLOR
    return out


def palette(max_label: int) -> np.ndarray:
    """A lookup table ``palette[k] = label_colors(k)`` for ``k = 0 .. max_label``.

    Parameters
    ----------
    max_label : int
        The largest label id to cover.

    Returns
    -------
    table : ndarray, shape (max_label + 1, 3), uint8
        Row ``k`` is the colour of label ``k``; a longer table has the same rows.
    """
    return label_colors(np.arange(int(max_label) + 1))


def colorize_labels(labels: ArrayLike) -> np.ndarray:
    """Paint a label array with the palette (label 0 in ``NO_LABEL_COLOR``).

    Parameters
    ----------
    labels : array_like of int, any shape
        Label ids, ``>= 0``.

    Returns
    -------
    image : ndarray, shape ``labels.shape + (3,)``, uint8

    Raises
    ------
    ValueError
        If a label id is negative (a fault of the calling code; label fields are never negative).
    """
    labels = np.asarray(labels)
    if labels.size == 0:
        return np.zeros((*labels.shape, 3), dtype=np.uint8)
    if labels.min() < 0:
        raise ValueError("label ids must be >= 0 (0 = no label)")
    return palette(int(labels.max()))[labels]
