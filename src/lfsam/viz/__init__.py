"""Visualising light fields and their segmentations (paper section 4.3, Figure 2).

Plain arrays in, ``(H, W, 3)`` uint8 RGB images out, each of a size documented from its inputs:

- :mod:`~lfsam.viz.colors`: one colour per label id, the same in every view and figure;
- :mod:`~lfsam.viz.overlay`: labels and region boundaries over one view;
- :mod:`~lfsam.viz.epi`: horizontal and vertical epipolar-plane images through the center view,
  upsampled along the view axis, with labels;
- :mod:`~lfsam.viz.grid`: a figure of all views, or of the corners and center;
- :mod:`~lfsam.viz.animation`: GIF/MP4 running through the views in snake order;
- :mod:`~lfsam.viz.timeline`: animations over the frames of a light-field video;
- :mod:`~lfsam.viz.compare`: two results side by side;
- :mod:`~lfsam.viz.layout`: tiling, captions and stacking used by the above.

Write images with :func:`save_image` (atomic, format from the suffix).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from PIL import Image

from lfsam.errors import LfsamError
from lfsam.fileutil import atomic_output
from lfsam.viz.animation import (
    ANIMATION_SUFFIXES,
    animation_frames,
    ffmpeg_available,
    indicator_strip,
    write_animation,
)
from lfsam.viz.colors import NO_LABEL_COLOR, colorize_labels, label_colors, palette
from lfsam.viz.compare import (
    compare_epi,
    compare_frames,
    compare_grid,
    match_labels,
    side_by_side,
)
from lfsam.viz.epi import (
    MARK_COLOR,
    epi_figure,
    epi_overlays,
    horizontal_epi,
    upsample_views,
    vertical_epi,
)
from lfsam.viz.grid import VIEW_SELECTIONS, grid_layout, select_views, view_grid
from lfsam.viz.layout import CAPTION_HEIGHT, as_rgb_uint8, rescale
from lfsam.viz.overlay import label_boundaries, mask_boundaries, overlay_labels
from lfsam.viz.timeline import time_frames, time_strip

__all__ = [
    "ANIMATION_SUFFIXES",
    "CAPTION_HEIGHT",
    "IMAGE_SUFFIXES",
    "MARK_COLOR",
    "NO_LABEL_COLOR",
    "VIEW_SELECTIONS",
    "animation_frames",
    "as_rgb_uint8",
    "colorize_labels",
    "compare_epi",
    "compare_frames",
    "compare_grid",
    "epi_figure",
    "epi_overlays",
    "ffmpeg_available",
    "grid_layout",
    "horizontal_epi",
    "indicator_strip",
    "label_boundaries",
    "label_colors",
    "mask_boundaries",
    "match_labels",
    "overlay_labels",
    "palette",
    "rescale",
    "save_image",
    "select_views",
    "side_by_side",
    "time_frames",
    "time_strip",
    "upsample_views",
    "vertical_epi",
    "view_grid",
    "write_animation",
]

#: Still-image suffixes :func:`save_image` writes (lossless ones keep label colours exact).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".webp")


def save_image(path: str | os.PathLike, image: np.ndarray) -> Path:
    """Write an RGB image atomically; the format follows the suffix (:data:`IMAGE_SUFFIXES`).

    Raises
    ------
    LfsamError
        If the suffix is not an image format, or the folder does not exist.
    """
    path = Path(path)
    if path.suffix.lower() not in IMAGE_SUFFIXES:
        raise LfsamError(
            f"cannot write an image to {str(path)!r}; give a file ending in "
            f"{', '.join(IMAGE_SUFFIXES)}"
        )
    options = {"compress_level": 3} if path.suffix.lower() == ".png" else {}
    with atomic_output(path) as tmp:
        # PNG level 3: about 3x faster than the default 6 for 10% larger files.
        Image.fromarray(as_rgb_uint8(image)).save(tmp, **options)
    return path
