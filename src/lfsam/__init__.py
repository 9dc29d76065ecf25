"""lfsam: Segment Anything 2 in light fields via constrained prompting.

Implements Goncharov & Dansereau, "Segment Anything in Light Fields for Real-Time Applications via
Constrained Prompting", WACV 2025 workshops. The pipeline's four steps are
:mod:`lfsam.pipeline.initial` (initial segmentation), :mod:`lfsam.pipeline.propagation`
(disparity propagation), :mod:`lfsam.pipeline.occlusion` (semantic occluding) and
:mod:`lfsam.pipeline.refinement` (segmentation refinement). Batch use: :func:`lfsam.segment`;
interactive use: :class:`lfsam.LightFieldPredictor`, wrapped by
:class:`lfsam.LightFieldMaskGenerator` for the automatic mode.
"""

import os as _os

# OpenMP threads that wait by sleeping, not spinning, unless the user chose otherwise: spinning
# threads of two processes on the same cores (lfsam beside another PyTorch process, a test
# runner, a browser) starve each other's work. Measured on a 2-core CPU (docs/performance.md,
# "Depth in 8 seconds"): `lfsam disparity` on HCI antinous beside one busy single-thread process
# took 585 s with the default policy, its estimator 16.4 s with this one; alone, the command
# took 18.2-19.1 s with spinning threads and 19.7-20.2 s with sleeping ones. Read when
# PyTorch's OpenMP runtime loads, so it acts only if lfsam is imported
# first (the CLI, the viewer plugin and the tests do). docs/design.md section 6.
_os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField, snake_order
from lfsam.prompts import TextPrompt
from lfsam.result import SegmentationResult, save_result
from lfsam.result import load_result as _load_file_result
from lfsam.version import __version__


def load_result(path):
    """Read a result: a ``.npz`` (:func:`lfsam.result.load_result`, a
    :class:`SegmentationResult`) or a light-field video's result folder
    (:func:`lfsam.video.io.result.load_video_result`, a lazy
    :class:`~lfsam.video.io.result.VideoResult` whose ``labels[f]`` reads frame ``f``;
    docs/design.md section 10)."""
    from lfsam.video.io.result import is_video_result, load_video_result

    if is_video_result(path):
        return load_video_result(path)
    return _load_file_result(path)


def __getattr__(name: str):
    # lfsam.segment, lfsam.LightFieldPredictor and the option groups load torch and the
    # pipeline; importing them lazily keeps `import lfsam` (and the CLI's --help) light.
    if name in ("segment", "SegmentOptions", "ModelOptions", "RunOptions"):
        from lfsam import api

        return getattr(api, name)
    if name == "LightFieldPredictor":
        from lfsam.predictor import LightFieldPredictor

        return LightFieldPredictor
    if name in ("LightFieldVideo", "read_video", "OnlineTracker"):
        from lfsam import video

        return getattr(video, name)
    if name == "LightFieldMaskGenerator":
        from lfsam.generator import LightFieldMaskGenerator

        return LightFieldMaskGenerator
    raise AttributeError(f"module 'lfsam' has no attribute {name!r}")

__all__ = [
    "LfsamError",
    "LightField",
    "LightFieldMaskGenerator",
    "LightFieldPredictor",
    "LightFieldVideo",
    "ModelOptions",
    "OnlineTracker",
    "RunOptions",
    "SegmentOptions",
    "SegmentationResult",
    "TextPrompt",
    "__version__",
    "load_result",
    "read_video",
    "save_result",
    "segment",
    "snake_order",
]
