"""Step 1 of the pipeline: initial segmentation of the center view.

Paper section 3.1, equation (1): ``M[s_m, t_m] = SAM2_img(L[s_m, t_m], P[s_m, t_m])`` for a user
prompt (points with labels and/or a box), or SAM 2's automatic mask generation (paper section 4,
implementation details; docs/design.md section 3.1).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from lfsam.errors import LfsamError
from lfsam.segmenters.base import Prompts, Segmenter, ViewEmbedding

__all__ = ["SourceMasks", "initial_segmentation", "validate_prompts"]


@dataclass
class SourceMasks:
    """The masks of the prompted view that the pipeline carries into every other view.

    Attributes
    ----------
    masks : (N, U, V) bool tensor
        Mask ``n`` becomes label ``n + 1``.
    scores : (N,) float ndarray
        The segmenter's quality estimate of each mask.
    paint_order : (N,) int64 ndarray
        Mask indices from the largest to the smallest center area: label fusion writes them in
        this order so smaller masks end on top (docs/design.md section 3.6).
    """

    masks: torch.Tensor
    scores: np.ndarray
    paint_order: np.ndarray

    def __len__(self) -> int:
        return int(self.masks.shape[0])


def validate_prompts(prompts: Prompts, view_size: tuple[int, int]) -> None:
    """Check that prompts lie inside the view and boxes are not empty.

    Raises
    ------
    LfsamError
        Naming the offending point or box and the view size.
    """
    height, width = view_size
    if prompts.points is not None:
        for x, y in prompts.points.reshape(-1, 2):
            if not (0 <= x <= width - 1 and 0 <= y <= height - 1):
                raise LfsamError(
                    f"point X,Y = {x:g},{y:g} lies outside the center view "
                    f"(columns 0..{width - 1}, rows 0..{height - 1}); points are X,Y = column,row"
                )
    if prompts.boxes is not None:
        for x0, y0, x1, y1 in prompts.boxes:
            if not (x1 > x0 and y1 > y0):
                raise LfsamError(
                    f"box {x0:g},{y0:g},{x1:g},{y1:g} is empty; give X0,Y0,X1,Y1 with X1 > X0 "
                    "and Y1 > Y0"
                )
            if x1 < 0 or y1 < 0 or x0 > width - 1 or y0 > height - 1:
                raise LfsamError(
                    f"box {x0:g},{y0:g},{x1:g},{y1:g} lies outside the center view "
                    f"(columns 0..{width - 1}, rows 0..{height - 1})"
                )


def initial_segmentation(
    segmenter: Segmenter,
    embedding: ViewEmbedding,
    image: np.ndarray,
    prompts: Sequence[Prompts] | None = None,
    *,
    min_area: int = 1,
    points: np.ndarray | None = None,
) -> SourceMasks:
    """Segment the prompted (center) view: equation (1) of the paper.

    Parameters
    ----------
    segmenter : Segmenter
    embedding : ViewEmbedding
        The encoded view; encoded once, it also gives the source features of section 3.3.
    image : (U, V, 3) uint8 ndarray
        The view itself (automatic generation needs the pixels).
    prompts : sequence of Prompts, optional
        Groups of prompts, each prompt one object, in the order of the resulting labels. A
        prompt of a single point is ambiguous, so SAM 2's three candidates are asked for and the
        one with the highest predicted IoU kept; other prompts ask for one mask. None: automatic
        mask generation, keeping masks of at least ``min_area`` pixels.
    points : (P, 2) float ndarray, optional
        Automatic generation only: ask at these pixels instead of the generator's own grid.

    Returns
    -------
    SourceMasks
    """
    height, width = embedding.image_size
    if prompts is None:
        auto = segmenter.generate(embedding, image, points=points)
        masks = torch.as_tensor(np.asarray(auto.masks, dtype=bool)).reshape(-1, height, width)
        scores = np.asarray(auto.scores, dtype=np.float32).reshape(-1)
        areas = masks.flatten(1).sum(1).cpu().numpy()
        keep = areas >= max(min_area, 1)
        order = np.argsort(-areas[keep], kind="stable")
        masks = masks[torch.as_tensor(np.flatnonzero(keep)[order])]
        return SourceMasks(
            masks=masks.to(segmenter.device),
            scores=scores[keep][order],
            paint_order=np.arange(len(order)),
        )
    chosen_masks, chosen_scores = [], []
    for group in prompts:
        validate_prompts(group, (height, width))
        single_point = group.boxes is None and group.points.shape[1] == 1
        prediction = segmenter.predict(embedding, group, multimask_output=single_point)
        best = prediction.iou_predictions.argmax(dim=1)
        rows = torch.arange(len(group), device=best.device)
        chosen_masks.append(prediction.masks[rows, best.to(prediction.masks.device)])
        chosen_scores.append(prediction.iou_predictions[rows, best].float().cpu().numpy())
    masks = torch.cat(chosen_masks).to(segmenter.device)
    areas = masks.flatten(1).sum(1).cpu().numpy()
    return SourceMasks(
        masks=masks,
        scores=np.concatenate(chosen_scores),
        paint_order=np.argsort(-areas, kind="stable"),
    )
