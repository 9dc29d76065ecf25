"""The tables of a data-set evaluation (paper Tables 1 and 2; :mod:`lfsam.evaluate`): a scene's
row (:class:`SceneRow`), the run's table written as ``metrics.csv`` and ``table.md``
(:class:`EvaluationTable`), read back (:func:`read_metrics_csv`), and several runs' mean rows in
one table with the best value of each column in bold (:func:`compare_runs`).
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from lfsam.errors import LfsamError
from lfsam.fileutil import atomic_output
from lfsam.metrics import (
    OBJECT_METRICS,
    REPORT_METRICS,
    VIDEO_METRICS,
    Metric,
)
from lfsam.metrics.report import format_metrics_table

__all__ = ["CSV_COLUMNS", "EvaluationTable", "SceneRow", "compare_runs", "read_metrics_csv"]


METRIC_KEYS = tuple(m.key for m in REPORT_METRICS + VIDEO_METRICS)


VIDEO_KEYS = tuple(m.key for m in VIDEO_METRICS)


#: Columns of ``metrics.csv``.
CSV_COLUMNS = ("scene", "method", *METRIC_KEYS, "num_masks", "seconds", "error")


MEAN_ROW = "mean"


RECORD_SUFFIX = ".metrics.json"


@dataclass
class SceneRow:
    """The outcome of one scene.

    Attributes
    ----------
    scene : str
        Scene name (folder name or file stem).
    method : str
        Method label of the run.
    metrics : dict
        ``siou``, ``lpp``, ``aa``, ``ue``, ``coverage``, ``ms_per_mask_view``, ``recall``,
        ``siou_center`` (None when undefined
        or when the scene failed).
    num_masks : int or None
        N of the result.
    seconds : float or None
        Wall-clock seconds of the segmentation call.
    error : str or None
        Why the scene failed; None on success.
    """

    scene: str
    method: str
    metrics: dict[str, float | None] = field(default_factory=dict)
    num_masks: int | None = None
    seconds: float | None = None
    error: str | None = None

    def to_record(self) -> dict[str, Any]:
        """JSON-ready dictionary (the ``<scene>.metrics.json`` file; NaN written as null)."""
        return {
            "scene": self.scene,
            "method": self.method,
            **{key: _finite_or_none(self.metrics.get(key)) for key in METRIC_KEYS},
            "num_masks": self.num_masks,
            "seconds": self.seconds,
            "error": self.error,
        }

    @classmethod
    def from_record(cls, record: dict[str, Any]) -> SceneRow:
        """Inverse of :meth:`to_record`."""
        return cls(
            scene=str(record["scene"]),
            method=str(record["method"]),
            metrics={key: record.get(key) for key in METRIC_KEYS},
            num_masks=record.get("num_masks"),
            seconds=record.get("seconds"),
            error=record.get("error"),
        )


@dataclass
class EvaluationTable:
    """Everything one :func:`evaluate_dataset` run produced (a pandas-free table).

    Attributes
    ----------
    method : str
        Method label.
    rows : list of SceneRow
        One per scene, in name order.
    mean : dict
        Mean of each metric over the scenes that succeeded (NaN-free means; None if none);
        for :data:`lfsam.metrics.VIDEO_METRICS`, the total over the videos.
    skipped : list of (name, reason)
        Entries of the data-set folder that are not light fields.
    ran, resumed : list of str
        Scenes computed in this run and scenes whose earlier results were reused.
    out_dir : Path
        Where the files are.
    """

    method: str
    rows: list[SceneRow]
    mean: dict[str, float | None]
    skipped: list[tuple[str, str]] = field(default_factory=list)
    ran: list[str] = field(default_factory=list)
    resumed: list[str] = field(default_factory=list)
    out_dir: Path = Path(".")

    @property
    def failed(self) -> list[SceneRow]:
        """Rows of scenes that failed."""
        return [row for row in self.rows if row.error is not None]

    @property
    def columns(self) -> tuple[Metric, ...]:
        """The tables' columns: paper Table 1's and :data:`OBJECT_METRICS`, then
        :data:`VIDEO_METRICS` when a scored scene is a video."""
        videos = any(row.metrics.get("frames") is not None for row in self.rows
                     if row.error is None)
        return REPORT_METRICS + VIDEO_METRICS if videos else REPORT_METRICS

    def summary_markdown(self) -> str:
        """One-row table of the mean, in the layout of paper Table 1."""
        return format_metrics_table(
            [(self.method, self.mean)], mark_best=False, metrics=self.columns
        )

    def to_markdown(self, title: str | None = None) -> str:
        """The ``table.md`` text: the mean (paper Table 1 layout), each scene, failures, skips."""
        ok = len(self.rows) - len(self.failed)
        parts = [
            f"# {title or self.method}\n",
            self.summary_markdown(),
            f"Mean over {ok} scene(s)" + (f"; {len(self.failed)} failed." if self.failed else "."),
            "",
            "## Per scene\n",
        ]
        scored = [(row.scene, row.metrics) for row in self.rows if row.error is None]
        if scored:
            parts.append(
                format_metrics_table(
                    scored, first_column="Scene", mark_best=False, metrics=self.columns
                )
            )
        else:
            parts.append("(no scene was scored)\n")
        if self.failed:
            parts += ["## Failed scenes\n"]
            parts += [f"- `{row.scene}`: {row.error}" for row in self.failed]
            parts += [""]
        if self.skipped:
            parts += ["## Skipped (not light fields)\n"]
            parts += [f"- `{name}`: {reason}" for name, reason in self.skipped]
            parts += [""]
        return "\n".join(parts)

    def to_csv(self) -> str:
        """The ``metrics.csv`` text: one row per scene, then the ``mean`` row."""
        buffer = io.StringIO()
        writer = csv.DictWriter(buffer, fieldnames=CSV_COLUMNS, lineterminator="\n")
        writer.writeheader()
        for row in self.rows:
            writer.writerow({k: _csv_cell(v) for k, v in row.to_record().items()})
        ok = [row for row in self.rows if row.error is None]
        writer.writerow(
            {
                "scene": MEAN_ROW,
                "method": self.method,
                **{key: _csv_cell(self.mean.get(key)) for key in METRIC_KEYS},
                "num_masks": _csv_cell(_mean([row.num_masks for row in ok])),
                "seconds": _csv_cell(_mean([row.seconds for row in ok])),
                "error": "",
            }
        )
        return buffer.getvalue()


def read_metrics_csv(path: str | os.PathLike) -> list[dict[str, Any]]:
    """Read a ``metrics.csv`` written by :func:`evaluate_dataset`.

    Returns
    -------
    list of dict
        One per row (scenes, then ``mean``); metric values as float or None.

    Raises
    ------
    LfsamError
        If the file is missing or lacks the expected columns.
    """
    path = Path(path)
    if path.is_dir():
        path = path / "metrics.csv"
    if not path.is_file():
        raise LfsamError(
            f"{str(path)!r} not found; give a folder written by `lfsam evaluate ... --out DIR`"
        )
    with open(path, newline="", encoding="utf-8") as handle:
        reader = csv.DictReader(handle)
        # Files written before the object or video metrics existed lack their columns: None.
        optional = {m.key for m in OBJECT_METRICS + VIDEO_METRICS}
        missing = set(CSV_COLUMNS) - optional - set(reader.fieldnames or ())
        if missing:
            raise LfsamError(
                f"{str(path)!r} is not a metrics.csv of lfsam evaluate (missing {sorted(missing)})"
            )
        rows = []
        for raw in reader:
            row: dict[str, Any] = dict(raw)
            for key in (*METRIC_KEYS, "num_masks", "seconds"):
                row[key] = float(raw[key]) if raw.get(key) not in ("", None) else None
            row["error"] = raw["error"] or None
            rows.append(row)
    return rows


def compare_runs(dirs: Sequence[str | os.PathLike]) -> str:
    """One markdown table of several runs' mean rows, best value per column in bold.

    This is how the paper's Table 1 (baseline vs ours) and Table 2 (ablations) are laid out.

    Parameters
    ----------
    dirs : sequence of paths
        Output folders of :func:`evaluate_dataset` (or their ``metrics.csv`` files).

    Returns
    -------
    str
        The markdown table.

    Raises
    ------
    LfsamError
        If a folder has no ``metrics.csv`` or no ``mean`` row.
    """
    if not dirs:
        raise LfsamError("nothing to compare; give the --out folders of two or more runs")
    rows = []
    labels: list[str] = []
    for folder in dirs:
        mean = [row for row in read_metrics_csv(folder) if row["scene"] == MEAN_ROW]
        if not mean:
            raise LfsamError(f"{str(folder)!r} has no mean row; rerun lfsam evaluate there")
        label = mean[-1]["method"] or Path(folder).name
        if label in labels:
            label = f"{label} [{Path(folder).name}]"
        labels.append(label)
        rows.append((label, mean[-1]))
    return format_metrics_table(rows, metrics=REPORT_METRICS)


def write_text(path: Path, text: str) -> None:
    with atomic_output(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def _finite_or_none(value: Any) -> float | None:
    if value is None:
        return None
    value = float(value)
    return None if math.isnan(value) else value


def _mean(values: Sequence[float | None]) -> float | None:
    finite = [float(v) for v in values if v is not None and not math.isnan(float(v))]
    return sum(finite) / len(finite) if finite else None


def _csv_cell(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    return value
