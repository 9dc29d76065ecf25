"""Label fusion: larger masks first, smaller on top (docs/design.md section 3.6)."""

from __future__ import annotations

import numpy as np
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

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


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31 - 1), st.booleans())
def test_view_labels_kept_on_the_device_come_back_as_fused_view_by_view(seed, defer):
    """``ViewLabels`` gives every view ``fuse_labels``'s answer (ids for ranks), whether the
    labels are written at once (CPU) or kept and read back in one copy (GPU), with objects'
    masks arriving in several parts and views left unfused staying 0."""
    from lfsam.pipeline.fusion import ViewLabels

    rng = np.random.default_rng(seed)
    grid, size = (2, 3), (5, 7)
    ids = [int(i) for i in rng.choice(np.arange(1, 50), size=int(rng.integers(1, 5)),
                                      replace=False)]
    order = [ids[k] for k in rng.permutation(len(ids))]
    sink = ViewLabels(grid, size, ids, order, torch.device("cpu"))
    sink._defer = defer
    masks = torch.as_tensor(rng.random((*grid, len(ids), *size)) < 0.4)
    skipped = (1, 2)
    for view in [(s, t) for s in range(2) for t in range(3) if (s, t) != skipped]:
        split = int(rng.integers(0, len(ids) + 1))
        first = {i: masks[view][k] for k, i in enumerate(ids) if k < split}
        rest = {i: masks[view][k] for k, i in enumerate(ids) if k >= split}
        if first:
            assert not sink.add(view, first) or not rest
        if rest:
            assert sink.add(view, rest)
    field = sink.field()
    rank = {i: k for k, i in enumerate(ids)}
    paint = torch.as_tensor([rank[i] for i in order])
    lookup = np.array([0, *ids])
    for s in range(2):
        for t in range(3):
            want = (np.zeros(size, dtype=int) if (s, t) == skipped
                    else lookup[fuse_labels(masks[s, t], paint).numpy()])
            assert np.array_equal(field[s, t], want)
