"""Label fusion: larger masks first, smaller on top (docs/design.md section 3.6)."""

from __future__ import annotations

import torch

from lfsam.pipeline.fusion import fuse_labels


def test_smaller_mask_ends_on_top_and_ids_start_at_one():
    masks = torch.zeros((3, 6, 6), dtype=torch.bool)
    masks[0, :, :] = True  # large
    masks[1, 1:4, 1:4] = True  # medium
    masks[2, 2:3, 2:3] = True  # small
    order = torch.tensor([0, 1, 2])
    labels = fuse_labels(masks, order)
    assert labels[0, 0] == 1
    assert labels[1, 1] == 2
    assert labels[2, 2] == 3
    assert labels.dtype == torch.int32


def test_paint_order_not_identity():
    masks = torch.zeros((2, 4, 4), dtype=torch.bool)
    masks[0, 1, 1] = True  # small mask listed first
    masks[1] = True  # large mask second
    labels = fuse_labels(masks, torch.tensor([1, 0]))
    assert labels[1, 1] == 1 and labels[0, 0] == 2


def test_many_masks_in_chunks_and_unlabeled_zero():
    n = 70  # more than one chunk
    masks = torch.zeros((n, 1, n + 1), dtype=torch.bool)
    for i in range(n):
        masks[i, 0, i] = True
    labels = fuse_labels(masks, torch.arange(n))
    assert labels[0, :n].tolist() == list(range(1, n + 1))
    assert labels[0, n] == 0
