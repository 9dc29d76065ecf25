"""A small learned correction of the estimated disparity at depth jumps (issue 45, fourth round;
docs/design.md section 3.2, step 8).

The estimate's remaining errors sit mostly in bands along depth jumps, where the foreground's
disparity has spread onto the background (on HCI antinous and cotton 94-100 % of the bad pixels
within 3 px of a jump are off towards the nearer surface). The right value is usually that of
a pixel a few pixels away. So a fully convolutional network of a few dilated 3 x 3 layers reads,
per pixel of the reference view, its colour, its locally normalised intensity (dark regions then
look like bright ones), the disparity (centred, scaled by the searched range) and its
confidence, and scores 25 candidates: the pixel's own disparity and those 2, 4 and 6 px away in
8 directions (:data:`OFFSETS`); each pixel takes the candidate with the highest score. A chosen
value is thus always one the estimator found nearby, and where the network is unsure the own
value wins.

It was trained **only on lfsam's own synthetic scenes** (:mod:`lfsam.synth`, dimmed, unevenly
lit and noisy copies included), never on a benchmark scene, by
``scripts/train_disparity_refiner.py`` from a fixed seed; its weights (:data:`DEFAULT_WEIGHTS`,
about 110 kB) ship inside the package as a NumPy ``.npz`` file (no pickle).

Optional (``estimate_disparity(..., learned_refinement=True)``, ``lfsam disparity
--learned-refinement``): it lowers BadPix(0.07) on HCI antinous (5.40 -> 5.30 % over all pixels)
and cotton (2.33 -> 2.06 %) but raises the synthetic +-3 and glossy scenes' errors and can move a
small near object's pixels to the background (docs/performance.md, "Fourth round").

Whole-image torch operations, any device (CUDA when the estimate runs there); deterministic.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from lfsam.errors import LfsamError

__all__ = [
    "DEFAULT_WEIGHTS",
    "DILATIONS",
    "WIDTH",
    "DisparityRefiner",
    "load_refiner",
    "refine_with_network",
    "refiner_inputs",
]

#: The weights shipped with the package (written by ``scripts/train_disparity_refiner.py``).
DEFAULT_WEIGHTS = Path(__file__).resolve().parent / "weights" / "disparity_refiner.npz"
#: Channels of every hidden layer.
WIDTH = 24
#: Dilation of each hidden 3 x 3 layer (receptive field 2 * (1 + sum) + 1 = 39 pixels).
DILATIONS = (1, 2, 4, 8, 2, 1)
#: Input channels: R, G, B, locally normalised gray, disparity, confidence.
IN_CHANNELS = 6
#: Where the candidates come from: the pixel itself, then these (row, column) offsets (8
#: directions at 2, 4 and 6 pixels).
OFFSETS = (
    (0, 0),
    *(
        (dy * r, dx * r)
        for r in (2, 4, 6)
        for dy, dx in ((-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1))
    ),
)
_NORMALISE_RADIUS = 4


def candidates(disparity: torch.Tensor) -> torch.Tensor:
    """The disparity at each pixel and at the :data:`OFFSETS` around it (replicated borders):
    ``(N, 1, H, W)`` to ``(N, len(OFFSETS), H, W)``."""
    reach = max(max(abs(dy), abs(dx)) for dy, dx in OFFSETS)
    padded = F.pad(disparity, (reach,) * 4, mode="replicate")
    rows, cols = disparity.shape[-2:]
    return torch.cat(
        [padded[..., reach + dy : reach + dy + rows, reach + dx : reach + dx + cols]
         for dy, dx in OFFSETS],
        1,
    )


class DisparityRefiner(nn.Module):
    """Dilated 3 x 3 convolutions (ReLU) with a linear 1 x 1 head: ``(N, 6, H, W)`` inputs of
    :func:`refiner_inputs` to ``(N, len(OFFSETS), H, W)`` scores, one per candidate of
    :func:`candidates`; the refined disparity is the candidate with the highest score
    (:meth:`refine`). Untrained, the pixel's own value scores highest.

    Parameters
    ----------
    width : int
        Channels of every hidden layer.
    dilations : tuple of int
        Dilation of each hidden layer (replicated padding keeps the size).
    """

    def __init__(self, width: int = WIDTH, dilations: tuple[int, ...] = DILATIONS) -> None:
        super().__init__()
        self.dilations = tuple(int(d) for d in dilations)
        channels = [IN_CHANNELS] + [width] * len(self.dilations)
        self.layers = nn.ModuleList(
            nn.Conv2d(channels[i], channels[i + 1], 3, dilation=d)
            for i, d in enumerate(self.dilations)
        )
        self.head = nn.Conv2d(width, len(OFFSETS), 1)
        nn.init.zeros_(self.head.weight)
        with torch.no_grad():
            self.head.bias.zero_()
            self.head.bias[0] = 2.0

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """The candidates' scores (class docstring)."""
        for layer, d in zip(self.layers, self.dilations, strict=True):
            x = F.relu(layer(F.pad(x, (d, d, d, d), mode="replicate")))
        return self.head(x)

    def refine(self, inputs: torch.Tensor, disparity: torch.Tensor) -> torch.Tensor:
        """The refined disparity, ``(N, 1, H, W)``: per pixel the candidate with the highest
        score (the pixel's own value unless another one scores higher)."""
        choice = self(inputs).argmax(1, keepdim=True)
        return candidates(disparity).gather(1, choice)


def _box(x: torch.Tensor, radius: int) -> torch.Tensor:
    """Mean over a ``(2 radius + 1)^2`` window, replicated borders; ``x`` is (N, C, H, W).
    ``avg_pool2d``, not :func:`lfsam.disparity.filters.box_blur` (separable at this radius,
    equal up to rounding): the shipped weights were trained on these exact values."""
    k = 2 * radius + 1
    return F.avg_pool2d(F.pad(x, (radius,) * 4, mode="replicate"), k, stride=1)


def refiner_inputs(
    colour: torch.Tensor,
    disparity: torch.Tensor,
    confidence: torch.Tensor,
    disparity_range: tuple[float, float],
) -> torch.Tensor:
    """The network's input stack.

    Parameters
    ----------
    colour : torch.Tensor, shape (N, 3, H, W)
        The reference view, float in [0, 1].
    disparity, confidence : torch.Tensor, shape (N, 1, H, W)
        The estimate and its confidence in [0, 1].
    disparity_range : (lo, hi)
        The range searched (pixels per view step).

    Returns
    -------
    torch.Tensor, shape (N, 6, H, W)
        Colour, locally normalised gray (mean and deviation over 9 x 9), the disparity minus its
        image mean divided by the half range (at least 0.25), the confidence.
    """
    lo, hi = (float(x) for x in disparity_range)
    scale = max((hi - lo) / 2.0, 0.25)
    gray = colour.mean(1, keepdim=True)
    mean = _box(gray, _NORMALISE_RADIUS)
    spread = (_box(gray * gray, _NORMALISE_RADIUS) - mean * mean).clamp(min=0).sqrt()
    normalised = (gray - mean) / (spread + 0.01)
    centred = (disparity - disparity.mean(dim=(2, 3), keepdim=True)) / scale
    return torch.cat([colour, (normalised / 3.0).clamp(-1.0, 1.0), centred, confidence], 1)


@lru_cache(maxsize=4)
def _load_cached(path: str) -> DisparityRefiner:
    try:
        stored = np.load(path)
    except (OSError, ValueError) as error:
        raise LfsamError(
            f"cannot read the disparity refiner's weights {path}: {error}; reinstall lfsam or "
            "run scripts/train_disparity_refiner.py"
        ) from error
    try:
        with stored:
            width = int(stored["width"])
            dilations = tuple(int(d) for d in stored["dilations"])
            model = DisparityRefiner(width, dilations)
            state = {key: torch.from_numpy(stored[key]) for key in model.state_dict()}
        model.load_state_dict(state)
    except (KeyError, TypeError, ValueError, RuntimeError) as error:
        raise LfsamError(
            f"{path} is not a weights file of the disparity refiner ({error}); reinstall lfsam "
            "or run scripts/train_disparity_refiner.py"
        ) from error
    return model.eval()


def load_refiner(path: str | Path | None = None) -> DisparityRefiner:
    """The refiner with the weights of ``path`` (default :data:`DEFAULT_WEIGHTS`), on the CPU,
    in evaluation mode; loaded once per path and shared (do not train the returned module).

    Raises
    ------
    LfsamError
        If the file is missing or not a weights file of this network.
    """
    return _load_cached(str(Path(path) if path is not None else DEFAULT_WEIGHTS))


def refine_with_network(
    colour: torch.Tensor,
    disparity: torch.Tensor,
    confidence: torch.Tensor,
    disparity_range: tuple[float, float],
    model: DisparityRefiner | None = None,
) -> torch.Tensor:
    """The disparity corrected by the refiner (module docstring), clamped to the range.

    Parameters
    ----------
    colour : torch.Tensor, shape (3, H, W)
        The reference view, float in [0, 1].
    disparity, confidence : torch.Tensor, shape (H, W)
    disparity_range : (lo, hi)
    model : DisparityRefiner, optional
        Default :func:`load_refiner`'s.

    Returns
    -------
    torch.Tensor, shape (H, W), float32, on the disparity's device
    """
    model = load_refiner() if model is None else model
    device = disparity.device
    with torch.no_grad():
        inputs = refiner_inputs(
            colour.float()[None].to(device),
            disparity.float()[None, None],
            confidence.float()[None, None].to(device),
            disparity_range,
        )
        refined = model.to(device).refine(inputs, disparity.float()[None, None])[0, 0]
    lo, hi = disparity_range
    return refined.clamp(float(lo), float(hi))
