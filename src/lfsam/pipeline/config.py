"""Settings of the LFSAM pipeline, including the paper's ablation switches."""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from typing import Any

import torch

from lfsam.devices import default_encode_batch_size, default_prompt_batch_size
from lfsam.errors import LfsamError
from lfsam.pipeline.propagation import PROPAGATION_MODES
from lfsam.pipeline.sparse import check_refine_views

__all__ = ["ABLATIONS", "OCCLUSION_MODES", "PipelineConfig"]

OCCLUSION_MODES = ("none", "semantic", "geometric", "both")

# Paper Table 2 rows: (refinement, occluding).
ABLATIONS: dict[str, dict[str, Any]] = {
    "none": {"refine": False, "occlusion": "none"},
    "ref": {"refine": True, "occlusion": "none"},
    "ref+occ": {"refine": True, "occlusion": "semantic"},
}


@dataclass(frozen=True)
class PipelineConfig:
    """Switches and thresholds of the pipeline (:class:`lfsam.pipeline.engine.StreamingEngine`).

    Parameters
    ----------
    refine : bool
        Re-prompt the segmenter in every view (paper section 3.4).
    occlusion : {"semantic", "geometric", "both", "none"}
        Semantic occluding with encoder features (paper section 3.3), geometric occluding by
        z-buffering the center disparity (beyond the paper), both, or none.
    propagation : {"pixel", "mean", "median"}
        Move every pixel by its own disparity (paper equation 2) or the whole mask by its
        mean/median disparity (the authors' code).
    t_sim : float
        Semantic occluding threshold on cosine similarity (paper: 0.7), in [0, 1].
    t_iou : float
        Refined masks with IoU against the coarse mask not above this fall back (paper: 0.1),
        in [0, 1].
    zbuffer_tolerance : float
        Geometric occluding: a pixel is hidden when a center pixel with disparity larger by more
        than this lands on the same spot (pixels per view step).
    fill_holes : bool
        Close the gaps of per-pixel forward warping.
    encode_batch_size : int, optional
        Views encoded per encoder call; None (default) decides from the segmenter's device
        (:func:`lfsam.devices.default_encode_batch_size`: batched on CUDA, 1 on a CPU).
    refine_views : {"all", "sparse"} or int
        Which views are encoded and refined (docs/design.md section 3.7): ``"all"`` (the
        paper), ``"sparse"`` (about one in six, :func:`lfsam.pipeline.sparse.sparse_view_count`)
        or that many views spread over the grid; every other view is filled from the refined
        views nearest to it (:mod:`lfsam.pipeline.fill`). A string of digits is read as N.
    consensus : bool
        Multi-view consensus (docs/design.md section 3.9): after refinement, each refined
        view's mask of each object is voted by its own and its nearest refined views' masks,
        carried by disparity (:mod:`lfsam.pipeline.voting`); a refined mask the vote changes
        beyond recognition is replaced and counted (result ``meta["consensus_replaced"]``).
    surface_depth : bool
        With an estimated disparity: an object whose inside shows something else than its
        surface (glass, a mirror) gets its silhouette's depth there before its mask is carried
        (:func:`lfsam.disparity.non_lambertian.surface_disparity`, docs/design.md section 3.2).

    Raises
    ------
    LfsamError
        An unknown occluding or propagation mode, an encode batch size below 1, or a
        ``refine_views`` that is none of the three forms.
    """

    refine: bool = True
    occlusion: str = "semantic"
    propagation: str = "pixel"
    t_sim: float = 0.7
    t_iou: float = 0.1
    zbuffer_tolerance: float = 0.2
    fill_holes: bool = True
    encode_batch_size: int | None = None
    refine_views: str | int = "all"
    consensus: bool = False
    surface_depth: bool = True

    def __post_init__(self) -> None:
        object.__setattr__(self, "refine_views", check_refine_views(self.refine_views))
        if self.occlusion not in OCCLUSION_MODES:
            raise LfsamError(
                f"unknown occlusion {self.occlusion!r}; use one of {', '.join(OCCLUSION_MODES)}"
            )
        if self.propagation not in PROPAGATION_MODES:
            raise LfsamError(
                f"unknown propagation {self.propagation!r}; use one of "
                f"{', '.join(PROPAGATION_MODES)}"
            )
        if self.encode_batch_size is not None and self.encode_batch_size < 1:
            raise LfsamError(
                f"encode_batch_size must be at least 1, got {self.encode_batch_size}; "
                "or None to decide from the device"
            )
        for name in ("t_sim", "t_iou"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not 0.0 <= value <= 1.0:  # NaN fails too
                raise LfsamError(
                    f"{name} must be a number in [0, 1], got {value!r}; "
                    f"use e.g. --{name.replace('_', '-')} {getattr(PipelineConfig, name)}"
                )

    @classmethod
    def from_ablation(cls, name: str, **overrides: Any) -> PipelineConfig:
        """The configuration of a row of the paper's Table 2 (``none``, ``ref``, ``ref+occ``).

        Raises
        ------
        LfsamError
            If ``name`` is not a row of Table 2.
        """
        if name not in ABLATIONS:
            raise LfsamError(f"unknown ablation {name!r}; use one of {', '.join(ABLATIONS)}")
        return replace(cls(**ABLATIONS[name]), **overrides)

    def batch_size_for(self, device: str | torch.device) -> int:
        """Views per encoder call on ``device``: :attr:`encode_batch_size`, else the device's
        default (:func:`lfsam.devices.default_encode_batch_size`)."""
        if self.encode_batch_size is not None:
            return int(self.encode_batch_size)
        return default_encode_batch_size(device)

    def refine_chunk_for(self, device: str | torch.device) -> int:
        """Prompts of one view refined per decoder call on ``device``
        (:func:`lfsam.devices.default_prompt_batch_size`)."""
        return default_prompt_batch_size(device)

    @property
    def semantic(self) -> bool:
        """Whether semantic occluding runs."""
        return self.occlusion in ("semantic", "both")

    @property
    def geometric(self) -> bool:
        """Whether geometric (z-buffer) occluding runs."""
        return self.occlusion in ("geometric", "both")

    @property
    def ablation(self) -> str | None:
        """The row of the paper's Table 2 this configuration is (``none``, ``ref``,
        ``ref+occ``), or None (e.g. geometric occluding)."""
        for name, switches in ABLATIONS.items():
            if all(getattr(self, key) == value for key, value in switches.items()):
                return name
        return None

    @property
    def needs_view_encoding(self) -> bool:
        """Whether views other than the center must be encoded (refinement or semantic)."""
        return self.refine or self.semantic

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready settings for result metadata."""
        return asdict(self)
