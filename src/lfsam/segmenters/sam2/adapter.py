"""Every use lfsam makes of the private parts of Meta's ``sam2``, in one place.

lfsam runs SAM 2's own modules but reaches past their public API in a few places: to feed the
image predictor an embedding it already has (so no view is encoded twice), to run its
post-processing on masks from our batched decoder (:mod:`lfsam.segmenters.sam2.decoder`), to
read the backbone's multi-scale features, and to silence the video predictor's progress bar.
Those accesses are the small functions below and the one predictor subclass that must override
a private method (``SAM2ImagePredictor._predict``, which ``SAM2AutomaticMaskGenerator`` calls).
No other lfsam module touches a ``sam2`` name that starts with an underscore.

They are checked against the ``sam2`` versions the tests cover (``pyproject.toml`` bounds the
dependency to them): :data:`SAM2_CLASS_ATTRIBUTES`, :data:`SAM2_PREDICTOR_STATE` and
:data:`SAM2_MODULE_ATTRIBUTES` list what this module needs, :func:`missing_sam2_api` says which of
them the installed ``sam2`` lacks, and ``tests/test_sam2_adapter.py`` fails naming this module
and the attribute when an upgrade removes one (docs/design.md section 3, "efficiency facts", for why
lfsam reaches this deep).
"""

from __future__ import annotations

import contextlib
import importlib
from collections.abc import Iterator
from typing import Any

import numpy as np
import torch
from sam2.sam2_image_predictor import SAM2ImagePredictor

from lfsam.segmenters.sam2.decoder import (
    DEFAULT_CHUNK_SIZE,
    LOGIT_CLAMP,
    decode_prompts,
    prepare_image,
    stability_scores,  # re-exported: it lived here before the decoder owned it
)

__all__ = [
    "IMAGENET_MEAN",
    "IMAGENET_STD",
    "SAM2_CLASS_ATTRIBUTES",
    "SAM2_MODULE_ATTRIBUTES",
    "SAM2_PREDICTOR_STATE",
    "CachedFeaturePredictor",
    "backbone_features",
    "fit_feature_sizes",
    "image_transforms",
    "missing_sam2_api",
    "quiet_video_progress",
    "stability_scores",
    "use_image_transforms",
]

IMAGENET_MEAN = (0.485, 0.456, 0.406)
"""SAM 2's input normalisation mean (``SAM2Transforms``, ``load_video_frames``; also the
``transformers`` image processors of SAM, SAM 2 and EdgeTAM)."""

IMAGENET_STD = (0.229, 0.224, 0.225)
"""SAM 2's input normalisation standard deviation (the same places)."""

SAM2_CLASS_ATTRIBUTES: dict[str, tuple[str, ...]] = {
    "sam2.sam2_image_predictor.SAM2ImagePredictor": ("_predict", "reset_predictor", "set_image"),
    "sam2.modeling.sam2_base.SAM2Base": ("_prepare_backbone_features", "forward_image"),
}
"""Methods of ``sam2`` classes this module calls or overrides (class -> attribute names)."""

SAM2_PREDICTOR_STATE: tuple[str, ...] = (
    "_transforms",
    "_features",
    "_orig_hw",
    "_is_image_set",
    "_bb_feat_sizes",
)
"""Private attributes of a ``SAM2ImagePredictor`` instance this module reads or sets."""

SAM2_MODULE_ATTRIBUTES: dict[str, tuple[str, ...]] = {
    "sam2.sam2_video_predictor": ("tqdm",),
}
"""Module globals of ``sam2`` this module replaces for a while (module -> names)."""


def missing_sam2_api(predictor: Any | None = None) -> list[str]:
    """The attributes this module needs that the installed ``sam2`` lacks (empty when all fit).

    Parameters
    ----------
    predictor : SAM2ImagePredictor, optional
        An instance, to check :data:`SAM2_PREDICTOR_STATE` too (instance attributes are set in
        ``__init__`` and cannot be seen on the class).

    Returns
    -------
    list of str
        Dotted names such as ``"sam2.modeling.sam2_base.SAM2Base._prepare_backbone_features"``.
    """
    missing = []
    for dotted, names in SAM2_CLASS_ATTRIBUTES.items():
        module_name, _, class_name = dotted.rpartition(".")
        owner = getattr(importlib.import_module(module_name), class_name, None)
        missing += [f"{dotted}.{name}" for name in names if not hasattr(owner, name)]
    for module_name, names in SAM2_MODULE_ATTRIBUTES.items():
        module = importlib.import_module(module_name)
        missing += [f"{module_name}.{name}" for name in names if not hasattr(module, name)]
    if predictor is not None:
        owner = "sam2.sam2_image_predictor.SAM2ImagePredictor()"
        missing += [
            f"{owner}.{name}" for name in SAM2_PREDICTOR_STATE if not hasattr(predictor, name)
        ]
    return missing


# --- image predictor --------------------------------------------------------------------------
def image_transforms(predictor: SAM2ImagePredictor) -> Any:
    """The predictor's ``SAM2Transforms``: input resize + normalisation (``.transforms``), prompt
    coordinates (``.transform_coords``, ``.transform_boxes``) and mask post-processing."""
    return predictor._transforms


def use_image_transforms(predictor: SAM2ImagePredictor, transforms: Any) -> None:
    """Make ``transforms`` (an object with ``SAM2Transforms``' methods, e.g.
    :class:`lfsam.segmenters.transformers.sam1.PaddedTransforms`) the predictor's input, prompt and
    mask
    geometry."""
    predictor._transforms = transforms


def fit_feature_sizes(predictor: SAM2ImagePredictor, image_size: int) -> None:
    """Set the backbone feature sizes the predictor assumes to those of a square ``image_size``
    input (``SAM2ImagePredictor`` hard-codes those of 1024 pixels): image_size / 4, / 8, / 16."""
    size = int(image_size)
    predictor._bb_feat_sizes = [(size // k, size // k) for k in (4, 8, 16)]


def backbone_features(
    model: torch.nn.Module, backbone_out: dict[str, Any]
) -> tuple[list[torch.Tensor], list[tuple[int, int]]]:
    """The flattened multi-scale features of ``SAM2Base.forward_image``'s output and their sizes,
    finest first (``SAM2Base._prepare_backbone_features``), as ``set_image`` uses them."""
    _, vision_feats, _, feat_sizes = model._prepare_backbone_features(backbone_out)
    return vision_feats, feat_sizes


class CachedFeaturePredictor(SAM2ImagePredictor):
    """``SAM2ImagePredictor`` that takes embeddings lfsam already has and decodes with lfsam's
    batched decoder.

    - :meth:`use_features` sets an image's embedding without running the encoder.
    - ``SAM2AutomaticMaskGenerator`` calls ``set_image`` on each crop; the first crop is the whole
      view, whose embedding :meth:`lfsam.segmenters.sam2.backend.Sam2Segmenter.encode` already
      made (:attr:`cached`). Other crops (``crop_n_layers > 0``) are encoded here and counted in
      :attr:`encoder_passes`.
    - ``_predict`` (what :meth:`predict_prompts` and the generator call) decodes through
      :func:`lfsam.segmenters.sam2.decoder.decode_prompts`: the same results as Meta's, the image
      side shared across the prompts; with a mask input (the generator's optional mask-to-mask
      pass) Meta's own code runs.
    """

    cached: tuple[Any, tuple[int, int]] | None = None
    """``(Sam2Features, (U, V))`` of the view :meth:`set_image` may take without encoding."""
    encoder_passes: int = 0
    #: Prompts decoded together by :func:`~lfsam.segmenters.sam2.decoder.decode_prompts`.
    decode_chunk_size: int = DEFAULT_CHUNK_SIZE
    image_state: Any = None
    """The prompt-independent part of the decoder for the current image (made once per image)."""

    def reset_predictor(self) -> None:
        """Forget the image (and its decoder state)."""
        super().reset_predictor()
        self.image_state = None

    def use_features(self, features: dict[str, Any], image_size: tuple[int, int]) -> None:
        """Take ``features`` (``{"image_embed", "high_res_feats"}``) as the encoded image of
        ``image_size`` = (U, V) pixels, as ``set_image`` would have made them."""
        self.reset_predictor()
        self._orig_hw = [tuple(int(x) for x in image_size)]
        self._features = features
        self._is_image_set = True

    def set_image(self, image: Any) -> None:
        """Take the cached features if ``image`` is the cached view, else encode it."""
        hw = tuple(np.asarray(image).shape[:2])
        if self.cached is not None and hw == self.cached[1]:
            self.use_features(self.cached[0].as_predictor_features(), hw)
            return
        self.encoder_passes += 1
        super().set_image(image)

    def predict_prompts(
        self,
        point_coords: torch.Tensor | None,
        point_labels: torch.Tensor | None,
        boxes: torch.Tensor | None = None,
        multimask_output: bool = True,
        absent_points: bool = False,
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Masks, IoU predictions and low-resolution logits of prompts in model-input pixels
        (as ``SAM2ImagePredictor._prep_prompts`` makes them), on the image set last;
        ``absent_points``: points labelled :data:`~lfsam.segmenters.base.ABSENT_POINT` are
        masked out (:func:`~lfsam.segmenters.sam2.decoder.decode_prompts`)."""
        return self._predict(point_coords, point_labels, boxes, multimask_output=multimask_output,
                             absent_points=absent_points)

    def _predict(
        self,
        point_coords: torch.Tensor | None,
        point_labels: torch.Tensor | None,
        boxes: torch.Tensor | None = None,
        mask_input: torch.Tensor | None = None,
        multimask_output: bool = True,
        return_logits: bool = False,
        img_idx: int = -1,
        absent_points: bool = False,
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        if mask_input is not None:
            return super()._predict(
                point_coords, point_labels, boxes, mask_input, multimask_output, return_logits,
                img_idx,
            )
        if not self._is_image_set:
            raise RuntimeError("An image must be set with .set_image(...) before mask prediction.")
        image_embed = self._features["image_embed"][img_idx].unsqueeze(0)
        high_res = [level[img_idx].unsqueeze(0) for level in self._features["high_res_feats"]]
        if self.image_state is None:  # once per image: the prompt-independent part
            self.image_state = prepare_image(self.model, image_embed, high_res)
        low_res, iou = decode_prompts(
            self.model, image_embed, high_res, point_coords, point_labels, boxes,
            multimask_output, chunk_size=self.decode_chunk_size, clamp=False,
            state=self.image_state, absent_points=absent_points,
        )
        masks = self._transforms.postprocess_masks(low_res, self._orig_hw[img_idx])
        low_res = torch.clamp(low_res, -LOGIT_CLAMP, LOGIT_CLAMP)
        if not return_logits:
            masks = masks > self.mask_threshold
        return masks, iou, low_res


# --- video predictor --------------------------------------------------------------------------
@contextlib.contextmanager
def quiet_video_progress() -> Iterator[None]:
    """Replace the ``tqdm`` bar that ``SAM2VideoPredictor.propagate_in_video`` always draws by a
    plain iteration, restoring it on exit."""
    import sam2.sam2_video_predictor as video_module

    original = video_module.tqdm
    video_module.tqdm = _no_bar
    try:
        yield
    finally:
        video_module.tqdm = original


def _no_bar(iterable: Any, *args: Any, **kwargs: Any) -> Any:
    return iterable
