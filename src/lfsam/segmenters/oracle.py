"""A segmenter that answers prompts from ground-truth labels: the upper bound of any backend.

The oracle (docs/design.md section 6) stands in for SAM 2 where a light field has ground-truth
labels, so every geometric step of the pipeline can be tested with exact numbers: a positive point
selects the ground-truth region under it, negative points remove the regions under them, a box
restricts the answer to the box (a box alone selects the region covering most of it), automatic
generation returns every region, and the "features" are one-hot labels, so semantic occluding (paper
section
3.3) separates objects perfectly. Optional, seeded imperfections (boundary jitter, merges with a
neighbouring region) make it a noisy segmenter for robustness tests; they are off by default.

Everything is vectorised over the prompts of a view with torch (selection tables indexed by the
label map), and runs on any device.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F
from skimage.measure import label as connected_components

from lfsam.devices import resolve_device
from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.segmenters.base import AutoMasks, MaskPrediction, Prompts, Segmenter, ViewEmbedding

__all__ = ["OracleSegmenter", "OracleView"]

_CHUNK = 32  # prompts handled together (bounds the (chunk, U * V) counting buffers)


@dataclass
class OracleView:
    """The oracle's "embedding" of a view: its label map and connected components.

    Parameters
    ----------
    labels : (U, V) int64 tensor or None
        Ground-truth labels (0 = none); None if the light field has none for this view.
    components : (U, V) int64 tensor or None
        Connected components of equal labels (4-connectivity, 0 on label 0).
    component_labels : (num_components + 1,) int64 tensor or None
        The label of each component (0 for component 0).
    """

    labels: torch.Tensor | None
    components: torch.Tensor | None = None
    component_labels: torch.Tensor | None = None

    @classmethod
    def from_labels(cls, labels: np.ndarray | None, device: torch.device) -> OracleView:
        """Label map, its connected components and their labels, on ``device``."""
        if labels is None:
            return cls(labels=None)
        comps = connected_components(np.asarray(labels), background=0, connectivity=1)
        lab = torch.as_tensor(np.asarray(labels), dtype=torch.int64, device=device)
        comp = torch.as_tensor(comps, dtype=torch.int64, device=device)
        comp_labels = torch.zeros(int(comps.max()) + 1, dtype=torch.int64, device=device)
        comp_labels[comp.flatten()] = lab.flatten()
        return cls(labels=lab, components=comp, component_labels=comp_labels)


class OracleSegmenter(Segmenter):
    """Answers prompts with ground-truth regions (``--model oracle``).

    Parameters
    ----------
    lightfield : LightField
        Must have labels, for every view (or for the center only, if only the center is
        prompted).
    min_area : int
        :meth:`generate` returns regions of at least this many pixels.
    boundary_jitter : int
        Imperfection: each answer is dilated or eroded by a random radius in
        ``[-boundary_jitter, boundary_jitter]`` pixels (0 = exact boundaries).
    merge_prob : float
        Imperfection: probability that an answer is merged with the neighbouring region that
        shares the longest border with it.
    seed : int
        Seed of the imperfections. Each draw is a hash of the seed, the view and the regions
        the prompt selects, so an answer does not depend on what was asked before (an
        interactive edit reproduces a full run exactly).
    device : str or torch.device, optional
        Default ``auto``: CUDA, then MPS, then CPU (:func:`lfsam.devices.resolve_device`).

    Raises
    ------
    LfsamError
        If the light field has no labels or an option is out of range.
    """

    name = "oracle"
    random_weights = False  # answers come from ground truth, not from a model

    skips_absent_points = True
    """Only labels 1 and 0 select or exclude regions; any other point is ignored."""

    def __init__(
        self,
        lightfield: LightField,
        *,
        min_area: int = 1,
        boundary_jitter: int = 0,
        merge_prob: float = 0.0,
        seed: int = 0,
        device: str | torch.device | None = None,
    ) -> None:
        super().__init__()
        if lightfield is None or lightfield.labels is None:
            raise LfsamError(
                "the oracle answers from ground-truth labels, but this light field has none; "
                "use one with labels (e.g. made by `lfsam synth`) or choose a SAM 2 --model"
            )
        if boundary_jitter < 0 or not 0.0 <= merge_prob <= 1.0 or min_area < 0:
            raise LfsamError(
                "oracle options out of range: need boundary_jitter >= 0, 0 <= merge_prob <= 1 "
                "and min_area >= 0"
            )
        self.lightfield = lightfield
        self.device = resolve_device(device)
        self.min_area = int(min_area)
        self.boundary_jitter = int(boundary_jitter)
        self.merge_prob = float(merge_prob)
        self.seed = int(seed)
        self.num_labels = int(lightfield.labels.max())

    def describe(self) -> dict[str, Any]:
        """A JSON-ready description for result metadata."""
        return {
            "backend": "oracle",
            "name": self.name,
            "random_weights": False,
            "device": str(self.device),
            "num_labels": self.num_labels,
            "min_area": self.min_area,
            "boundary_jitter": self.boundary_jitter,
            "merge_prob": self.merge_prob,
            "seed": self.seed,
        }

    # --- encoding -----------------------------------------------------------------------------
    def encode(
        self, images: np.ndarray, keys: list[tuple[int, int]] | None = None
    ) -> list[ViewEmbedding]:
        """Look up the ground truth of each view ``(s, t)`` in ``keys`` (required)."""
        images = np.asarray(images)
        if images.ndim == 3:
            images = images[None]
        if keys is None:
            raise LfsamError(
                "the oracle needs to know which views these are; pass keys=[(s, t), ...] "
                "to encode()"
            )
        if images.ndim != 4 or images.shape[-1] != 3 or len(keys) != len(images):
            raise LfsamError(
                f"encode() needs (B, U, V, 3) views and one (s, t) key per view, got "
                f"{images.shape} and {len(keys)} keys"
            )
        size = self.lightfield.view_shape
        if tuple(images.shape[1:3]) != size:
            raise LfsamError(
                f"views of size {tuple(images.shape[1:3])} given, but the oracle's light field "
                f"has {size}; encode views of the same light field"
            )
        grid = self.lightfield.grid_shape
        out = []
        for key in keys:
            s, t = (int(k) for k in key)
            if not (0 <= s < grid[0] and 0 <= t < grid[1]):
                raise LfsamError(f"view key {(s, t)} is outside the {grid[0]}x{grid[1]} grid")
            view = OracleView.from_labels(self.lightfield.view_labels(s, t), self.device)
            out.append(ViewEmbedding(image_size=size, key=(s, t), data=view))
        self.encode_calls += len(keys)
        return out

    def _view(self, embedding: ViewEmbedding) -> OracleView:
        view = embedding.data
        if not isinstance(view, OracleView):
            raise LfsamError(
                "this embedding was not made by the oracle; encode the view with the same "
                "segmenter that answers its prompts"
            )
        if view.labels is None:
            raise LfsamError(
                f"no ground-truth labels for view {embedding.key}: this light field has labels "
                "for the center view only; prompt the center view or use a SAM 2 --model"
            )
        return view

    # --- prompting ----------------------------------------------------------------------------
    def predict(
        self, embedding: ViewEmbedding, prompts: Prompts, multimask_output: bool = True
    ) -> MaskPrediction:
        """Ground-truth answers to N prompts.

        For each prompt: the regions under its positive points (label 0 selects nothing, also
        with a box) minus the regions under its negative points; with a box, intersected with
        the box; a box without positive points selects the region (not excluded by negative
        points) with most pixels inside the box. Points are rounded to the nearest pixel; a box
        covers pixels ``x0 <= column <= x1`` and ``y0 <= row <= y1``.

        Returns
        -------
        MaskPrediction
            ``multimask_output``: K = 3 candidates (the answer, the whole region ignoring the box,
            the answer's connected part under the positive points, or for a box alone the largest
            part in the box); else K = 1 (the answer). ``iou_predictions`` is 1.0 for non-empty
            masks and 0.0 for empty ones; ``low_res_logits`` is empty (N, K, 0, 0).
        """
        view = self._view(embedding)
        n = len(prompts)
        candidates = []
        for start in range(0, n, _CHUNK):
            sub = prompts.subset(slice(start, start + _CHUNK))
            candidates.append(self._answer(view, sub, multimask_output, embedding.key))
        u_size, v_size = embedding.image_size
        k = 3 if multimask_output else 1
        masks = (
            torch.cat(candidates)
            if candidates
            else torch.zeros((0, k, u_size, v_size), dtype=torch.bool, device=self.device)
        )
        ious = masks.flatten(2).any(-1).float()
        return MaskPrediction(
            masks=masks,
            iou_predictions=ious,
            low_res_logits=torch.zeros((n, k, 0, 0), device=self.device),
        )

    def _answer(
        self, view: OracleView, prompts: Prompts, multimask: bool, key: tuple[int, int] | None
    ) -> torch.Tensor:
        """Candidate masks ``(n, K, U, V)`` for a chunk of prompts."""
        labels, comps = view.labels, view.components
        n = len(prompts)
        u_size, v_size = labels.shape
        dev = self.device
        n_labels = self.num_labels + 1
        n_comps = len(view.component_labels)
        rows = torch.arange(n, device=dev)

        pos_labels = torch.zeros((n, n_labels), dtype=torch.bool, device=dev)
        neg_labels = torch.zeros_like(pos_labels)
        pos_comps = torch.zeros((n, n_comps), dtype=torch.bool, device=dev)
        has_pos = torch.zeros(n, dtype=torch.bool, device=dev)
        if prompts.points is not None:
            pts = torch.as_tensor(prompts.points, dtype=torch.float32, device=dev)
            col = pts[..., 0].round().long().clamp(0, v_size - 1)
            row = pts[..., 1].round().long().clamp(0, u_size - 1)
            kind = torch.as_tensor(prompts.point_labels, device=dev)
            under, comp_under = labels[row, col], comps[row, col]
            who = rows[:, None].expand_as(under)
            pos, neg = kind == 1, kind == 0
            pos_labels[who[pos], under[pos]] = True
            neg_labels[who[neg], under[neg]] = True
            pos_comps[who[pos], comp_under[pos]] = True
            has_pos = pos.any(1)
        pos_labels[:, 0] = False
        pos_comps[:, 0] = False

        box = None
        if prompts.boxes is not None:
            b = torch.as_tensor(prompts.boxes, dtype=torch.float32, device=dev)
            r = torch.arange(u_size, device=dev, dtype=torch.float32)
            c = torch.arange(v_size, device=dev, dtype=torch.float32)
            in_r = (r[None] >= b[:, 1:2]) & (r[None] <= b[:, 3:4])
            in_c = (c[None] >= b[:, 0:1]) & (c[None] <= b[:, 2:3])
            box = in_r[:, :, None] & in_c[:, None, :]
            box_only = ~has_pos
            if box_only.any():
                # region (and connected part) with most pixels in the box, not excluded
                inside = box[box_only].flatten(1).float()
                lab_count = _count(labels, inside, n_labels)
                lab_count[:, 0] = -1
                lab_count[neg_labels[box_only]] = -1
                best = lab_count.argmax(1)
                found = lab_count.max(1).values > 0
                pos_labels[box_only.nonzero()[:, 0][found], best[found]] = True
                comp_count = _count(comps, inside, n_comps)
                comp_count[~pos_labels[box_only][:, view.component_labels]] = -1
                best_c = comp_count.argmax(1)
                found_c = comp_count.max(1).values > 0
                pos_comps[box_only.nonzero()[:, 0][found_c], best_c[found_c]] = True

        selected = pos_labels & ~neg_labels
        if self.merge_prob > 0:
            selected = self._merge(labels, selected, key, neg_labels)
        region = selected[:, labels]  # (n, U, V)
        answer = region if box is None else region & box
        if not multimask:
            out = answer[:, None]
        else:
            part = pos_comps[:, comps] & region
            if box is not None:
                part &= box
            out = torch.stack([answer, region, part], dim=1)
        if self.boundary_jitter > 0:
            out = self._jitter(out, self._draws(key, selected, salt=2))
        return out

    # --- imperfections ------------------------------------------------------------------------
    def _draws(
        self, key: tuple[int, int] | None, selected: torch.Tensor, salt: int
    ) -> np.ndarray:
        """One uniform number in [0, 1) per prompt: a splitmix64 hash of the seed, the view,
        the selected regions and ``salt`` (no generator state: order-independent)."""
        weights = (np.arange(selected.shape[1], dtype=np.uint64) + np.uint64(1)) * np.uint64(
            0x9E3779B1
        )
        chosen = selected.cpu().numpy().astype(np.uint64)
        x = (chosen * weights[None]).sum(axis=1, dtype=np.uint64)
        s, t = key if key is not None else (0, 0)
        base = (self.seed * 1_000_003 + (s + 1) * 7_919 + (t + 1) * 104_729) * 31 + salt
        x = x ^ np.uint64(base % 2**63)
        x = x + np.uint64(0x9E3779B97F4A7C15)
        x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        x = x ^ (x >> np.uint64(31))
        return (x >> np.uint64(11)).astype(np.float64) / float(2**53)

    def _merge(
        self,
        labels: torch.Tensor,
        selected: torch.Tensor,
        key: tuple[int, int] | None = None,
        negative: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """With probability ``merge_prob``, add the neighbour with the longest shared border,
        unless a negative point lies on that neighbour: then nothing is merged (as a negative
        click removes a leak in SAM; no other region takes its place)."""
        n = len(selected)
        draw = torch.as_tensor(
            self._draws(key, selected, salt=1) < self.merge_prob, device=selected.device
        )
        if n == 0 or not draw.any():
            return selected
        sel = selected[draw]
        region = sel[:, labels].float()[:, None]  # (m, 1, U, V)
        ring = (F.max_pool2d(region, 3, stride=1, padding=1) > 0) & (region == 0)
        counts = _count(labels, ring.flatten(1).float(), selected.shape[1])
        counts[:, 0] = 0
        counts[sel] = 0
        best = counts.argmax(1)
        found = counts.max(1).values > 0
        if negative is not None:
            rows = torch.arange(len(best), device=best.device)
            found &= ~negative[draw][rows, best]
        sel[found.nonzero()[:, 0], best[found]] = True
        selected = selected.clone()
        selected[draw] = sel
        return selected

    def _jitter(self, masks: torch.Tensor, draws: np.ndarray) -> torch.Tensor:
        """Dilate (radius > 0) or erode (radius < 0) each prompt's masks by a radius drawn
        from ``draws`` (uniform in [0, 1), one per prompt)."""
        j = self.boundary_jitter
        radius = torch.as_tensor(
            np.floor(draws * (2 * j + 1)).astype(np.int64) - j, device=masks.device
        )
        out = masks.clone()
        for r in radius.unique().tolist():  # one pass per radius value, not per pixel
            if r == 0:
                continue
            pick = radius == r
            x = masks[pick].float()
            k = 2 * abs(r) + 1
            if r > 0:
                y = F.max_pool2d(x, k, stride=1, padding=abs(r)) > 0
            else:
                y = -F.max_pool2d(-x, k, stride=1, padding=abs(r)) > 0
            out[pick] = y
        return out

    # --- automatic generation -----------------------------------------------------------------
    def generate(
        self, embedding: ViewEmbedding, image: np.ndarray, points: np.ndarray | None = None
    ) -> AutoMasks:
        """Every ground-truth region of the view with at least :attr:`min_area` pixels (with
        ``points``: only the regions under at least one of them).

        Returns
        -------
        AutoMasks
            Masks in increasing label order, scores 1.0 (imperfections applied as in
            :meth:`predict`).
        """
        view = self._view(embedding)
        labels = view.labels
        ids, areas = torch.unique(labels, return_counts=True)
        keep = (ids > 0) & (areas >= max(self.min_area, 1))
        if points is not None:
            pts = torch.as_tensor(np.asarray(points, dtype=np.float32).reshape(-1, 2))
            rows = pts[:, 1].floor().long().clamp(0, labels.shape[0] - 1)
            cols = pts[:, 0].floor().long().clamp(0, labels.shape[1] - 1)
            under = torch.zeros(int(labels.max()) + 1, dtype=torch.bool, device=labels.device)
            under[labels[rows.to(labels.device), cols.to(labels.device)]] = True
            keep &= under[ids]
        ids = ids[keep]
        if len(ids) == 0:
            u_size, v_size = embedding.image_size
            return AutoMasks(
                masks=np.zeros((0, u_size, v_size), dtype=bool), scores=np.zeros(0, np.float32)
            )
        selected = torch.zeros(
            (len(ids), self.num_labels + 1), dtype=torch.bool, device=self.device
        )
        selected[torch.arange(len(ids), device=self.device), ids] = True
        regions = selected
        if self.merge_prob > 0:
            selected = self._merge(labels, selected, embedding.key)
        masks = selected[:, labels]
        if self.boundary_jitter > 0:
            masks = self._jitter(masks[:, None], self._draws(embedding.key, regions, salt=2))[:, 0]
        return AutoMasks(masks=masks.cpu().numpy(), scores=np.ones(len(masks), dtype=np.float32))

    # --- features -----------------------------------------------------------------------------
    def sample_features(self, embedding: ViewEmbedding, rows_cols: torch.Tensor) -> torch.Tensor:
        """One-hot ground-truth labels at the nearest pixels: ``(P, num_labels + 1)`` float32.

        Cosine similarity between two such features is 1 for the same label and 0 otherwise,
        so semantic occluding (paper section 3.3) keeps exactly the pixels of the source label.
        """
        labels = self._view(embedding).labels
        u_size, v_size = labels.shape
        rc = torch.as_tensor(rows_cols, dtype=torch.float32, device=self.device).reshape(-1, 2)
        row = rc[:, 0].round().long().clamp(0, u_size - 1)
        col = rc[:, 1].round().long().clamp(0, v_size - 1)
        return F.one_hot(labels[row, col], self.num_labels + 1).float()


def _count(label_map: torch.Tensor, weights: torch.Tensor, size: int) -> torch.Tensor:
    """Per row of ``weights`` (m, U * V): the summed weight of each label value, (m, size)."""
    index = label_map.flatten()[None].expand(len(weights), -1)
    counts = torch.zeros((len(weights), size), dtype=torch.float32, device=weights.device)
    return counts.scatter_add_(1, index, weights)
