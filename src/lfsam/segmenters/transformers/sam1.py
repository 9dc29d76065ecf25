"""SAM (v1)'s padded input geometry for the ``transformers`` backend (docs/design.md section 3.8).

SAM 2 resizes a view to its square input, each axis separately. SAM v1 (Kirillov et al. 2023,
"Segment Anything"; ``transformers``' ``SamModel``, also SlimSAM and MedSAM checkpoints) keeps
the aspect: ``SamImageProcessor`` resizes the longest side to the input size ``S`` (1024), the
other to ``int(side * S / longest + 0.5)``, normalises, and pads bottom and right with zeros to
``S x S``. So a view of ``U x V`` pixels covers the top-left ``h' x w'`` of the input
(:func:`resized_size`), and:

- prompts move by the resized-to-original ratio of each axis, ``w' / V`` and ``h' / U``
  (``SamProcessor._normalize_coordinates``; one factor up to the rounding of ``h'`` and ``w'``);
- masks are the low-resolution logits upsampled to ``S x S``, cropped to ``h' x w'`` and resized
  to the view (``SamImageProcessor.post_process_masks``);
- the embedding grid covers the view with its top-left ``ceil(h'/16) x ceil(w'/16)`` cells
  (:func:`view_grid`), which semantic occluding samples.

:class:`PaddedTransforms` has the methods of Meta's ``SAM2Transforms`` that lfsam's SAM 2 code
and ``SAM2AutomaticMaskGenerator`` call, so ``Sam2Segmenter.predict`` and ``generate`` run SAM
v1 unchanged once it is the predictors' transforms.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from lfsam.segmenters.sam2.adapter import IMAGENET_MEAN, IMAGENET_STD

__all__ = ["PaddedTransforms", "preprocess_padded", "resized_size", "view_grid"]



def resized_size(hw: tuple[int, int], size: int) -> tuple[int, int]:
    """``(h', w')``: a ``(U, V)`` view resized to longest side ``size``, as
    ``SamImageProcessor._get_preprocess_shape`` rounds it."""
    old_h, old_w = int(hw[0]), int(hw[1])
    scale = size * 1.0 / max(old_h, old_w)
    return int(old_h * scale + 0.5), int(old_w * scale + 0.5)


def view_grid(hw: tuple[int, int], size: int, grid: int) -> tuple[int, int]:
    """Rows and columns of a ``grid x grid`` embedding of a ``size`` input that the resized
    ``(U, V)`` view covers: ``ceil(h' / cell)`` and ``ceil(w' / cell)``, ``cell = size / grid``."""
    h, w = resized_size(hw, size)
    cell = size / grid
    return min(grid, math.ceil(h / cell)), min(grid, math.ceil(w / cell))


def preprocess_padded(views: torch.Tensor, size: int) -> torch.Tensor:
    """``SamImageProcessor``'s pixel values of a batch of uint8 views of one size, vectorised.

    The uint8 view is resized (bilinear, antialiased, rounded back to uint8) to longest side
    ``size`` (:func:`resized_size`), normalised with ImageNet's mean and deviation (scaled to
    0-255, as the processor fuses rescaling and normalisation) and padded bottom/right with
    zeros to ``size x size``.

    Parameters
    ----------
    views : (B, U, V, 3) uint8 tensor
    size : int
        The model's input side.

    Returns
    -------
    (B, 3, size, size) float32 tensor
    """
    from torchvision.transforms.v2 import functional as tvf

    h, w = resized_size((views.shape[1], views.shape[2]), size)
    x = views.permute(0, 3, 1, 2).contiguous()
    x = tvf.resize(x, [h, w], interpolation=tvf.InterpolationMode.BILINEAR, antialias=True)
    mean = torch.tensor(IMAGENET_MEAN, device=x.device).view(1, 3, 1, 1) * 255.0
    std = torch.tensor(IMAGENET_STD, device=x.device).view(1, 3, 1, 1) * 255.0
    x = (x.float() - mean) / std
    return F.pad(x, (0, size - w, 0, size - h))


class PaddedTransforms:
    """SAM v1's input, prompt and mask geometry in the shape of Meta's ``SAM2Transforms``.

    Parameters
    ----------
    resolution : int
        The model's input side ``S``.
    mask_threshold : float
    max_hole_area, max_sprinkle_area : float
        As ``SAM2Transforms``: holes and specks up to that many low-resolution pixels are
        filled / removed before upsampling (0: off).
    """

    def __init__(
        self, resolution: int, mask_threshold: float = 0.0, max_hole_area: float = 0.0,
        max_sprinkle_area: float = 0.0,
    ) -> None:
        self.resolution = int(resolution)
        self.mask_threshold = float(mask_threshold)
        self.max_hole_area = max_hole_area
        self.max_sprinkle_area = max_sprinkle_area

    @classmethod
    def like(cls, transforms: Any) -> PaddedTransforms:
        """The padded geometry with the settings of a ``SAM2Transforms``."""
        return cls(transforms.resolution, transforms.mask_threshold, transforms.max_hole_area,
                   transforms.max_sprinkle_area)

    def __call__(self, image: np.ndarray) -> torch.Tensor:
        """One ``(U, V, 3)`` uint8 view as ``(3, S, S)`` pixel values (``set_image``'s call)."""
        view = torch.from_numpy(np.ascontiguousarray(image, dtype=np.uint8))
        return preprocess_padded(view[None], self.resolution)[0]

    def forward_batch(self, img_list: list[np.ndarray]) -> torch.Tensor:
        """Views of one size as a ``(B, 3, S, S)`` batch."""
        return torch.stack([self(img) for img in img_list])

    def transforms(self, x: torch.Tensor) -> torch.Tensor:
        """A ``(B, 3, U, V)`` float batch in [0, 1] resized (longest side), normalised, padded."""
        h, w = resized_size((x.shape[-2], x.shape[-1]), self.resolution)
        x = F.interpolate(x, (h, w), mode="bilinear", align_corners=False, antialias=True)
        mean = torch.tensor(IMAGENET_MEAN, device=x.device).view(1, 3, 1, 1)
        std = torch.tensor(IMAGENET_STD, device=x.device).view(1, 3, 1, 1)
        x = (x - mean) / std
        return F.pad(x, (0, self.resolution - w, 0, self.resolution - h))

    def transform_coords(
        self, coords: torch.Tensor, normalize: bool = False, orig_hw: tuple[int, int] | None = None
    ) -> torch.Tensor:
        """``(..., 2)`` ``(x, y)`` view pixels (``normalize=True``) or fractions of the view to
        model-input pixels: scaled by ``w' / V`` and ``h' / U`` (``SamProcessor``).

        Raises
        ------
        ValueError
            Without ``orig_hw`` (the caller's code is at fault: Meta's predictors always pass
            it).
        """
        if orig_hw is None:
            raise ValueError("SAM's padded input needs the view size (orig_hw) for coordinates")
        h, w = resized_size(orig_hw, self.resolution)
        scale_x, scale_y = (w / orig_hw[1], h / orig_hw[0]) if normalize else (w, h)
        coords = coords.clone()
        coords[..., 0] = coords[..., 0] * scale_x
        coords[..., 1] = coords[..., 1] * scale_y
        return coords

    def transform_boxes(
        self, boxes: torch.Tensor, normalize: bool = False, orig_hw: tuple[int, int] | None = None
    ) -> torch.Tensor:
        """``(N, 4)`` boxes as ``(N, 2, 2)`` corners in model-input pixels."""
        return self.transform_coords(boxes.reshape(-1, 2, 2), normalize, orig_hw)

    def postprocess_masks(self, masks: torch.Tensor, orig_hw: tuple[int, int]) -> torch.Tensor:
        """``(N, K, S/4, S/4)`` logits to the view: ``SamImageProcessor.post_process_masks``
        (bilinear to ``S x S``, crop to ``h' x w'``, bilinear to the view), unthresholded.

        Only the input rows and columns the crop reads are upsampled (at most
        ``ceil(h' / f) + 1`` of them, ``f = S / (S/4)``): bilinear weights and neighbours are the
        full upsampling's, so the values are too, and a batch of prompts never holds
        ``N x K x S x S`` floats.
        """
        from sam2.utils.transforms import SAM2Transforms

        masks = masks.float()
        if self.max_hole_area > 0 or self.max_sprinkle_area > 0:  # at low resolution, as SAM 2
            masks = SAM2Transforms.postprocess_masks(self, masks, tuple(masks.shape[-2:]))
        h, w = resized_size(orig_hw, self.resolution)
        low_h, low_w = masks.shape[-2:]
        fy, fx = self.resolution / low_h, self.resolution / low_w
        rows, cols = min(low_h, math.ceil(h / fy) + 1), min(low_w, math.ceil(w / fx) + 1)
        up = F.interpolate(masks[..., :rows, :cols], (round(rows * fy), round(cols * fx)),
                           mode="bilinear", align_corners=False)
        return F.interpolate(up[..., :h, :w], tuple(orig_hw), mode="bilinear",
                             align_corners=False)
