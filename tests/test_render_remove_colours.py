"""Removal's colours (docs/design.md section 13, "Remove"): a ray that lands next to the
object's mask takes the colour of its neighbours off the object only, never the object's."""

from __future__ import annotations

import numpy as np
import torch

from lfsam.render.remove import LOOSE, _gather


def _sources(off_col4: float) -> torch.Tensor:
    """Two views of 1 x 8 pixels: green background, view 1's column 4 red and masked (the
    object: off it 0, its keep weight 0)."""
    views = torch.zeros((2, 3, 1, 8))
    views[:, 1] = 200.0  # green
    views[1, :, 0, 4] = torch.tensor([255.0, 0.0, 0.0])  # the object, in view 1
    off = torch.ones((2, 1, 1, 8))
    off[1, 0, 0, 4] = off_col4
    keep = torch.ones((2, 1, 1, 8))
    keep[1, 0, 0, 4] = 0.0
    depth = torch.full((2, 1, 1, 8), 0.25)
    return torch.cat([views * off, keep, depth, off], dim=1)


def test_a_ray_beside_the_mask_takes_its_clear_neighbours_colour():
    # target view 0's pixel (0, 5) at disparity 0.25 lands in view 1 (one column step) at
    # column 4.75: a quarter on the masked red column 4, three quarters on green column 5
    offsets = torch.tensor([[0, 0], [0, 1]])
    ys, xs, d = torch.tensor([0]), torch.tensor([5]), torch.tensor([0.25])
    colour, rays, _ = _gather(_sources(0.0), 0, ys, xs, d, offsets, 1.0)
    assert 0.75 > LOOSE and rays.tolist() == [1]  # no ray is wholly clear: the loose one counts
    np.testing.assert_allclose(colour[:, 0].numpy(), [0.0, 200.0, 0.0], atol=1e-3)
    # were the red pixel not the object's, the ray's colour would be the bilinear mix
    colour, _, _ = _gather(_sources(1.0), 0, ys, xs, d, offsets, 1.0)
    np.testing.assert_allclose(colour[:, 0].numpy(), [63.75, 150.0, 0.0], atol=1e-3)
