"""The bundled demo: a synthetic light field segmented end to end, scored and drawn.

What ``make demo`` runs (through ``lfsam demo``): it generates the bundled synthetic scene
(:func:`lfsam.synth.demo_scene`), segments it with the best segmenter available — SAM 2
(``sam2.1-hiera-small``, the paper's model) when its weights are cached or can be downloaded,
otherwise the ground-truth oracle, saying which and why — with disparity estimated from the
views, prints the paper's metrics next to the scores of the ground-truth labels themselves, and
writes figures and an animation.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from lfsam import synth
from lfsam.api import ModelOptions, RunOptions, SegmentOptions, segment
from lfsam.errors import LfsamError
from lfsam.io import write_lightfield
from lfsam.metrics import evaluate_labels, evaluate_result
from lfsam.metrics.report import format_metrics_table
from lfsam.result import save_result
from lfsam.segmenters.hub import hub_offline, hub_reachable
from lfsam.segmenters.sam2.build import cached_checkpoint
from lfsam.viz import animation_frames, epi_figure, save_image, view_grid, write_animation

__all__ = ["DemoReport", "choose_segmenter", "run_demo"]

DEFAULT_SAM2 = "sam2.1-hiera-small"


@dataclass
class DemoReport:
    """What the demo did: the segmenter and why, metrics, files written, seconds."""

    model: str
    reason: str
    table: str
    metrics: dict[str, dict[str, Any]] = field(default_factory=dict)
    files: list[Path] = field(default_factory=list)
    seconds: float = 0.0


def choose_segmenter(requested: str | None = None) -> tuple[str, str]:
    """The segmenter the demo uses and a sentence saying why.

    Parameters
    ----------
    requested : str, optional
        A model name to use regardless (``oracle`` or a SAM 2 name).

    Returns
    -------
    name, reason : str
    """
    if requested:
        return requested, f"{requested} was requested with --model"
    if cached_checkpoint(DEFAULT_SAM2) is not None:
        return DEFAULT_SAM2, f"SAM 2 weights for {DEFAULT_SAM2} are cached"
    if not hub_offline() and hub_reachable():
        return DEFAULT_SAM2, f"SAM 2 weights for {DEFAULT_SAM2} will be downloaded once"
    return "oracle", (
        f"no SAM 2 weights are cached for {DEFAULT_SAM2} and the model hub cannot be reached, "
        "so the ground-truth oracle stands in for SAM 2 (an upper bound on segmentation "
        "quality; the geometry is the real pipeline's). Get weights with "
        f"`lfsam segment ... --model {DEFAULT_SAM2}` online once, or pass --checkpoint FILE"
    )


def run_demo(
    out_dir: str | os.PathLike = "demo_output",
    *,
    model: str | None = None,
    checkpoint: str | None = None,
    random_weights: bool = False,
    amg_options: dict[str, Any] | None = None,
    device: str | None = None,
    progress: bool = True,
    precision: str = "auto",
) -> DemoReport:
    """Generate, segment, score and draw the bundled scene; write everything to ``out_dir``.

    Parameters
    ----------
    out_dir : path-like
        Created if missing; receives ``scene/`` (the light field), ``result.npz``,
        ``metrics.md``, ``grid.png`` (corner and center views), ``epi.png`` (epipolar-plane
        images as in the paper's Figure 2) and ``views.gif`` (all views in snake order).
    model : str, optional
        Force a segmenter (default: :func:`choose_segmenter`).
    checkpoint : str, optional
        SAM 2 weights file (implies a SAM 2 model).
    random_weights : bool
        Untrained SAM 2 (implies a SAM 2 model; a speed check, the masks are meaningless).
    amg_options : dict, optional
        Overrides of the automatic mask generator's settings (SAM 2 only).
    device : str, optional
        ``auto`` (default), ``cpu``, ``cuda``, ``cuda:N`` or ``mps``
        (:func:`lfsam.devices.resolve_device`).
    progress : bool
        Progress bars.
    precision : {"auto", "float32", "bfloat16"}
        SAM 2 / EdgeTAM arithmetic (:class:`lfsam.api.ModelOptions`).

    Returns
    -------
    DemoReport
    """
    start = time.perf_counter()
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise LfsamError(f"{str(out)!r} exists and is not a folder; choose another --out")
    out.mkdir(parents=True, exist_ok=True)
    if (checkpoint or random_weights or precision != "auto") and not model:
        model = DEFAULT_SAM2
    name, reason = choose_segmenter(model)

    lightfield = synth.demo_scene()  # looked up on use (tests swap in a smaller scene)
    files = [write_lightfield(lightfield, out / "scene")]
    options = SegmentOptions(
        model=ModelOptions(
            name=name, checkpoint=checkpoint, random_weights=random_weights, device=device,
            amg=amg_options, precision=precision,
        ),
        run=RunOptions(progress=progress),
    )
    result = segment(lightfield, disparity="estimate", options=options)
    files.append(save_result(result, out / "result.npz"))

    ours = evaluate_result(result, lightfield, device=device)
    ceiling = evaluate_labels(lightfield.labels, lightfield, device=device)
    rows = [
        (f"lfsam ({name}, estimated disparity)", ours),
        ("ground-truth labels (ceiling)", ceiling),
    ]
    table = format_metrics_table(rows)
    with open(out / "metrics.md", "w", encoding="utf-8") as handle:
        handle.write(f"Segmenter: {name} — {reason}.\n\n{table}")
    files.append(out / "metrics.md")

    views, labels = lightfield.views, result.labels
    files.append(save_image(out / "grid.png", view_grid(views, labels, which="corners")))
    files.append(save_image(out / "epi.png", epi_figure(views, labels, upsample=6)))
    files.append(
        write_animation(
            out / "views.gif",
            animation_frames(views, labels, order=lightfield.snake_order()),
            total=lightfield.num_views,
            progress=progress,
        )
    )
    return DemoReport(
        model=name,
        reason=reason,
        table=table,
        metrics={"lfsam": ours, "ceiling": ceiling},
        files=files,
        seconds=time.perf_counter() - start,
    )
