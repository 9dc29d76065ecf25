"""The one entry point for batch use: :func:`segment` (``lfsam.segment``).

It builds the segmenter (:class:`ModelOptions`), runs LFSAM on the interactive predictor
(:class:`lfsam.predictor.LightFieldPredictor`: the four steps of paper section 3, from each
object's own reference view) or the SAM 2 video baseline (:mod:`lfsam.baseline`, paper section
4), and records everything needed to reproduce the run in the result's metadata. Options come in
three small groups (:class:`SegmentOptions`: the pipeline's :class:`PipelineConfig`, the model,
the run). ``lfsam segment``, ``lfsam evaluate``, the Ray path and the benchmarks are thin
layers over it; interactive use goes through :class:`lfsam.predictor.LightFieldPredictor`.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from lfsam.errors import LfsamError
from lfsam.generator import LightFieldMaskGenerator
from lfsam.lightfield import LightField
from lfsam.pipeline import PipelineConfig
from lfsam.pipeline.references import check_references
from lfsam.predictor import LightFieldPredictor
from lfsam.prompts import (
    BoxPrompt,
    ObjectPrompts,
    PointPrompt,
    Prompt,
    TextPrompt,
    load_prompts,
    split_prompts,
    validate_objects,
)
from lfsam.result import SegmentationResult
from lfsam.segmenters import load_segmenter
from lfsam.segmenters.base import Prompts, Segmenter
from lfsam.segmenters.registry import DEFAULT_MODEL, ORACLE
from lfsam.segmenters.text import (
    DEFAULT_TEXT_MODEL,
    TEXT_ORACLE,
    TextDetector,
    load_text_detector,
)
from lfsam.text_search import find_text

__all__ = [
    "METHODS",
    "ModelOptions",
    "RunOptions",
    "SegmentOptions",
    "as_objects",
    "make_prompts",
    "objects_from_prompts",
    "segment",
]

METHODS = ("lfsam", "video-baseline")


def make_prompts(
    points: Sequence[tuple[float, float]] = (),
    boxes: Sequence[tuple[float, float, float, float]] = (),
) -> list[Prompts] | None:
    """Prompts for the center view, each point or box one object.

    When as many points as boxes are given, point ``i`` and box ``i`` together prompt object
    ``i``; otherwise every point and every box is an object of its own (points first).

    Parameters
    ----------
    points : sequence of (x, y)
        Positive points, ``x`` = pixel column and ``y`` = pixel row.
    boxes : sequence of (x0, y0, x1, y1)

    Returns
    -------
    list of Prompts, or None when nothing was given (automatic generation)
    """
    points = [tuple(map(float, p)) for p in points]
    boxes = [tuple(map(float, b)) for b in boxes]
    if not points and not boxes:
        return None
    if points and boxes and len(points) == len(boxes):
        return [
            Prompts(
                points=np.array(points)[:, None, :],
                point_labels=np.ones((len(points), 1)),
                boxes=np.array(boxes),
            )
        ]
    groups = []
    if points:
        groups.append(
            Prompts(points=np.array(points)[:, None, :], point_labels=np.ones((len(points), 1)))
        )
    if boxes:
        groups.append(Prompts(boxes=np.array(boxes)))
    return groups


def objects_from_prompts(prompts: Prompts, first_id: int = 1) -> list[ObjectPrompts]:
    """Center-view :class:`~lfsam.segmenters.base.Prompts` rows as objects ``first_id, ...``
    (padding points, label -1, are dropped)."""
    objects = []
    for n in range(len(prompts)):
        points = []
        if prompts.points is not None:
            for (x, y), label in zip(prompts.points[n], prompts.point_labels[n], strict=True):
                if label in (0, 1):
                    points.append(PointPrompt(float(x), float(y), bool(label == 1)))
        box = None if prompts.boxes is None else BoxPrompt(*map(float, prompts.boxes[n]))
        objects.append(ObjectPrompts(first_id + n, tuple(points), box))
    return objects


def _check_references(
    references: str, method: str, prompts, texts: Sequence[TextPrompt] = ()
) -> None:
    """Reject ``references`` other than ``center`` where they mean nothing (one-line errors)."""
    check_references(references)
    if references != "center" and prompts is not None and not texts:
        raise LfsamError(
            f"--references {references} needs --auto or --text; clicks and boxes set their "
            "own views"
        )
    if texts and method != "lfsam":
        raise LfsamError("text prompts need --method lfsam (the video baseline takes clicks)")
    if references != "center" and method != "lfsam":
        raise LfsamError(f"--references {references} needs --method lfsam")


@dataclass(frozen=True)
class ModelOptions:
    """Which segmenter to build (:func:`lfsam.segmenters.load_segmenter`).

    Parameters
    ----------
    name : str
        A SAM 2 model name (``lfsam models``) or ``"oracle"`` (answers from ground truth).
    checkpoint : str, optional
        SAM 2 weights file; default: the model hub's weights (cached).
    random_weights : bool
        Untrained SAM 2 (tests and speed measurements only; recorded in the metadata).
    device : str
        ``auto`` (CUDA, then MPS, then CPU), ``cpu``, ``cuda``, ``cuda:N`` or ``mps``.
    amg : dict, optional
        Overrides of the paper's automatic-mask-generation settings.
    oracle : dict, optional
        The oracle's imperfections: ``merge_prob``, ``boundary_jitter``, ``min_area``.
    seed : int
        Seed of random weights or of the oracle's imperfections.
    text_model : str, optional
        The text detector of text prompts (docs/design.md section 9): ``sam3``,
        ``sam3-tiny-test`` or ``oracle``; default ``oracle`` with the oracle segmenter, else
        ``sam3``.
    text_checkpoint : str, optional
        A local copy of SAM 3's hub repository (a folder); default: the hub cache.
    text_threshold : float, optional
        The score a detected instance needs; default: the detector's (SAM 3's processor: 0.3).
    precision : {"auto", "float32", "bfloat16"}
        SAM 2 / EdgeTAM arithmetic: ``auto`` = bfloat16 autocast on CUDA, float32 elsewhere;
        ``bfloat16`` also on a CPU (about twice as fast where the CPU has native bfloat16;
        docs/performance.md).
    """

    name: str = DEFAULT_MODEL
    checkpoint: str | None = None
    random_weights: bool = False
    device: str | None = "auto"
    amg: dict[str, Any] | None = None
    oracle: dict[str, Any] | None = None
    seed: int = 0
    text_model: str | None = None
    text_checkpoint: str | None = None
    text_threshold: float | None = None
    precision: str = "auto"

    @property
    def text_model_name(self) -> str:
        """The text detector used: :attr:`text_model`, else the oracle's or SAM 3."""
        if self.text_model is not None:
            return self.text_model
        return TEXT_ORACLE if self.name == ORACLE else DEFAULT_TEXT_MODEL

    def build_text_detector(self, lightfield: LightField | None = None) -> TextDetector:
        """The text detector these options describe (SAM 3 with ``random_weights`` when the
        segmenter has them)."""
        return load_text_detector(
            self.text_model_name, checkpoint=self.text_checkpoint,
            random_weights=self.random_weights, device=self.device, lightfield=lightfield,
            seed=self.seed,
        )

    def segmenter_keywords(self) -> dict[str, Any]:
        """The keywords of :func:`lfsam.segmenters.load_segmenter` besides the model's name
        (the viewer's session keeps them to rebuild the segmenter when the model changes)."""
        return {
            "checkpoint": self.checkpoint,
            "random_weights": self.random_weights,
            "device": self.device,
            "amg_options": dict(self.amg) if self.amg else None,
            "oracle_options": dict(self.oracle) if self.oracle else None,
            "seed": self.seed,
            "precision": self.precision,
        }

    def build(
        self, lightfield: LightField | None = None, *, keep_decoder_state: bool = True
    ) -> Segmenter:
        """The segmenter these options describe (``keep_decoder_state``: see
        :func:`lfsam.segmenters.load_segmenter`; batch runs turn it off)."""

        return load_segmenter(
            self.name, lightfield=lightfield, keep_decoder_state=keep_decoder_state,
            **self.segmenter_keywords(),
        )


@dataclass(frozen=True)
class RunOptions:
    """How a run goes (not what it computes).

    Parameters
    ----------
    method : {"lfsam", "video-baseline"}
        Our method (paper section 3) or SAM 2 video tracking over the views (paper section 4).
    references : {"center", "corners", "ring", "all"}
        Automatic mode: where masks are generated (docs/design.md section 8; ``center`` is the
        paper's setting).
    cache_dir : str, optional
        On-disk embedding cache (:mod:`lfsam.embeddings`).
    memory_budget_mb : float
        In-memory embedding budget (a batch run visits each view once; reference views of
        objects stay pinned).
    progress : bool
        Progress bars.
    baseline : dict, optional
        Options of the video baseline (``objects_per_pass``, ``start``).
    """

    method: str = "lfsam"
    references: str = "center"
    cache_dir: str | None = None
    memory_budget_mb: float = 256.0
    progress: bool = True
    baseline: dict[str, Any] | None = None


@dataclass(frozen=True)
class SegmentOptions:
    """Every option of :func:`segment`, in three small groups."""

    pipeline: PipelineConfig = field(default_factory=PipelineConfig)
    model: ModelOptions = field(default_factory=ModelOptions)
    run: RunOptions = field(default_factory=RunOptions)


PromptsLike = None | str | os.PathLike | Sequence[Prompt] | Sequence[Prompts]


def as_objects(prompts: PromptsLike, lightfield: LightField) -> list[Prompt] | None:
    """Objects and text prompts from any prompt form :func:`segment` accepts (None stays None:
    automatic).

    A path is a prompt file (:func:`lfsam.prompts.load_prompts`); :class:`Prompts` groups are
    center-view prompts, each row one object, ids in order; :class:`TextPrompt` items are
    concepts (docs/design.md section 9).

    Raises
    ------
    TypeError
        For a sequence holding anything but :class:`ObjectPrompts` or :class:`Prompts` (the
        caller's code is at fault).
    LfsamError
        For prompts that do not fit the light field (:func:`lfsam.prompts.validate_objects`).
    """
    if prompts is None:
        return None
    if isinstance(prompts, (str, os.PathLike)):
        return load_prompts(prompts, lightfield.grid_shape, lightfield.view_shape)
    objects: list[Prompt] = []
    for item in prompts:
        if isinstance(item, (ObjectPrompts, TextPrompt)):
            objects.append(item)
        elif isinstance(item, Prompts):
            first = max((o.obj_id for o in objects if isinstance(o, ObjectPrompts)), default=0)
            objects.extend(objects_from_prompts(item, first_id=first + 1))
        else:
            raise TypeError(
                "prompts must be ObjectPrompts, TextPrompt or Prompts, got "
                f"{type(item).__name__}"
            )
    validate_objects(objects, lightfield.grid_shape, lightfield.view_shape)
    return objects


def segment(
    lightfield: LightField,
    prompts: PromptsLike = None,
    *,
    model: str | Segmenter | None = None,
    disparity: Any = "estimate",
    options: SegmentOptions | None = None,
) -> SegmentationResult:
    """Segment a light field: the one entry point for batch use (paper section 3).

    Parameters
    ----------
    lightfield : LightField
    prompts : None, prompt file, sequence of ObjectPrompts, TextPrompt or Prompts
        Objects to segment, each prompted in any view (docs/design.md section 8), and text
        prompts, each phrase's instances found by the text detector (``options.model``'s
        ``text_model``) and segmented as objects with the phrase as category (section 9;
        ``meta["text"]`` says what each phrase found where); None runs automatic mask
        generation (the paper's setting).
    model : str or Segmenter, optional
        A model name (overrides ``options.model.name``) or a ready segmenter.
    disparity : {"estimate", "gt"}, path to a .npy, or ndarray
        Where each reference view's disparity comes from (:mod:`lfsam.disparity.source`).
    options : SegmentOptions, optional
        Pipeline switches, model and run options.

    Returns
    -------
    SegmentationResult
        Labels (an object's label is its id), bit-packed masks in id order, per-view fallback
        flags and IoUs, timings (``total`` = wall clock of the whole run) and metadata with the
        prompts, so the result can be reopened and edited.

    Examples
    --------
    >>> import lfsam
    >>> from lfsam.synth import generate_scene
    >>> lf = generate_scene(grid=(3, 3), size=(32, 48), seed=0, num_objects=2)
    >>> result = lfsam.segment(lf, model="oracle", disparity="gt",
    ...                        options=SegmentOptions(run=RunOptions(progress=False)))
    >>> result.labels.shape, result.meta["views_encoded"]
    ((3, 3, 32, 48), 9)
    """
    options = options or SegmentOptions()
    run = options.run
    if run.method not in METHODS:
        raise LfsamError(f"unknown method {run.method!r}; use one of {', '.join(METHODS)}")
    mixed = as_objects(prompts, lightfield)
    objects, texts = (None, []) if mixed is None else split_prompts(mixed)
    _check_references(run.references, run.method, objects, texts)
    if options.pipeline.refine_views != "all" and run.method != "lfsam":
        raise LfsamError(
            f"--refine-views {options.pipeline.refine_views} needs --method lfsam (the video "
            "baseline tracks every view)"
        )
    start = time.perf_counter()
    # the text detector first: missing SAM 3 weights fail before SAM 2 is loaded
    name = model.name if isinstance(model, Segmenter) else (model or options.model.name)
    model_options = replace(options.model, name=name)
    detector = model_options.build_text_detector(lightfield) if texts else None
    if isinstance(model, Segmenter):
        segmenter, model_name = model, model.name
    else:
        # a batch run decodes each view once: no decoder state kept with the embeddings
        segmenter = model_options.build(lightfield, keep_decoder_state=False)
        model_name = model_options.name
    run_meta: dict[str, Any] = {
        "input": str(lightfield.meta.get("source", "<array>")),
        "input_format": lightfield.meta.get("format"),
        "model": model_name,
        "random_weights": bool(segmenter.random_weights),
        "checkpoint": options.model.checkpoint,
        "grid": list(lightfield.grid_shape),
        "view_size": list(lightfield.view_shape),
    }
    if run.method == "video-baseline":
        # imported here: the baseline brings in Meta's predictor and torchvision (about 4 s)
        from lfsam.baseline import video_baseline

        result = video_baseline(
            lightfield,
            segmenter,
            prompts=None if objects is None else _center_prompts(objects, lightfield),
            disparity=disparity,
            progress=run.progress,
            **(run.baseline or {}),
        )
        result.meta.update(run_meta)
        return result

    predictor = LightFieldPredictor(
        segmenter,
        options.pipeline,
        cache_dir=run.cache_dir,
        memory_budget_mb=run.memory_budget_mb,
        progress=run.progress,
    )
    predictor.set_lightfield(lightfield, disparity=disparity)
    predictor.engine.disparities.prefetch()  # estimated while the reference views are encoded
    if objects is None:
        LightFieldMaskGenerator(predictor, run.references).generate()
    else:
        for obj in objects:
            predictor.set_object(obj)
    finds = (
        find_text(predictor, detector, texts, run.references, options.model.text_threshold)
        if detector is not None
        else []
    )
    result = predictor.to_result()
    result.timings["total"] = time.perf_counter() - start
    result.meta.update(run_meta)
    result.meta["prompt_mode"] = "auto" if objects is None else "prompts"
    result.meta["ablation"] = options.pipeline.ablation
    if objects is None or texts:
        result.meta["references"] = run.references
    if detector is not None:
        result.meta["text"] = [find.to_dict() for find in finds]
        result.meta["text_model"] = detector.describe()
        result.meta["text_threshold"] = (
            detector.default_threshold
            if options.model.text_threshold is None
            else options.model.text_threshold
        )
    return result


def _center_prompts(objects: Sequence[ObjectPrompts], lightfield: LightField) -> list[Prompts]:
    """Center-view objects as one-row :class:`Prompts` each (the video baseline's input)."""
    groups = []
    for obj in objects:
        obj = obj.resolved(lightfield.center)
        if obj.views(lightfield.center) != {lightfield.center}:
            raise LfsamError(
                f"object {obj.obj_id}: the video baseline takes center-view prompts only"
            )
        points = [(p.x, p.y) for p in obj.points]
        groups.append(
            Prompts(
                points=np.array([points], dtype=np.float32) if points else None,
                point_labels=np.array([[int(p.positive) for p in obj.points]])
                if points
                else None,
                boxes=None if obj.box is None else np.array([obj.box.xyxy]),
            )
        )
    return groups
