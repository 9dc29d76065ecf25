"""SAM 2's video predictor with the very weights of an image segmenter.

The baseline and LFSAM must run the same network (paper section 4: both use SAM 2 Hiera-S). The
video predictor (``SAM2VideoPredictor``, built by
:func:`lfsam.segmenters.sam2.build.build_sam2_video` with the settings of Meta's
``build_sam2_video_predictor``) has the same parameters as the image model ``SAM2Base``; it is
built once per image model, untrained, and then takes the image model's tensors themselves
(``load_state_dict(..., assign=True)``): same weights whether they came from a checkpoint or a
random seed, and no second copy in memory.
"""

from __future__ import annotations

import contextlib
import warnings
import weakref
from collections.abc import Iterator
from typing import Any

import torch

from lfsam.errors import LfsamError
from lfsam.segmenters.base import Segmenter
from lfsam.segmenters.registry import MODELS
from lfsam.segmenters.sam2.build import build_sam2_video

__all__ = ["MASK_THRESHOLD", "quiet_sam2_video", "video_predictor_for"]

_PREDICTORS: weakref.WeakKeyDictionary[torch.nn.Module, Any] = weakref.WeakKeyDictionary()


MASK_THRESHOLD = 0.0
"""SAM 2's mask threshold on logits (Meta's ``mask_threshold``): the video baseline's and the
video memory's masks are the logits above it."""


def video_predictor_for(segmenter: Segmenter) -> Any:
    """Meta's ``SAM2VideoPredictor`` sharing the weights of a SAM 2 image segmenter.

    Parameters
    ----------
    segmenter : Segmenter
        A :class:`~lfsam.segmenters.sam2.backend.Sam2Segmenter` (anything with a ``model``
        attribute holding a ``SAM2Base`` built by lfsam).

    Returns
    -------
    predictor : SAM2VideoPredictor
        In eval mode on the segmenter's device; cached per image model.

    Raises
    ------
    LfsamError
        If the segmenter is not SAM 2 (the oracle cannot track video) or its model is not one
        lfsam knows how to build.
    """
    from sam2.modeling.sam2_base import SAM2Base

    model = getattr(segmenter, "model", None)
    if not isinstance(model, SAM2Base):
        name = getattr(segmenter, "name", type(segmenter).__name__)
        raise LfsamError(
            f"the video baseline needs SAM 2's video tracker, which the {name!r} segmenter does "
            "not have; choose a SAM 2 --model (e.g. sam2.1-hiera-small) for --method "
            "video-baseline"
        )
    cached = _PREDICTORS.get(model)
    if cached is not None:
        return cached
    info = dict(getattr(model, "lfsam_info", {}) or {})
    name = info.get("name", getattr(segmenter, "name", None))
    if name not in MODELS:
        raise LfsamError(
            f"cannot build SAM 2's video predictor for model {name!r}; build the segmenter with "
            "lfsam.segmenters.load_segmenter (see `lfsam models`)"
        )
    device = next(model.parameters()).device
    predictor = build_sam2_video(name, random_weights=True, device=device, seed=0)
    predictor.load_state_dict(model.state_dict(), strict=True, assign=True)
    predictor.eval()
    predictor.lfsam_info = {**info, "video_predictor": type(predictor).__name__}
    _PREDICTORS[model] = predictor
    return predictor


@contextlib.contextmanager
def quiet_sam2_video() -> Iterator[None]:
    """Silence ``sam2``'s own video progress bar and its CUDA-extension warning.

    ``SAM2VideoPredictor.propagate_in_video`` always draws a ``tqdm`` bar (the baseline draws
    its own), and without the optional compiled extension (CPU installs) ``sam2`` warns that it
    skips filling small holes in the tracked masks (``fill_hole_area``, a post-processing step);
    tracking is otherwise the same. Both are restored on exit.
    """
    from lfsam.segmenters.sam2.adapter import quiet_video_progress

    with quiet_video_progress(), warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"cannot import name '_C'")
        yield
