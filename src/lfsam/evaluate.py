"""The data-set harness behind the paper's Tables 1 and 2 (paper section 4).

Metrics as in docs/design.md section 5.

:func:`evaluate_dataset` runs one segmentation method on every scene of a folder, saves each
result, scores it with :func:`lfsam.metrics.evaluate_result`, and writes ``metrics.csv`` (a row
per scene and a ``mean`` row) and ``table.md`` (the layout of paper Table 1). It is resumable:
a scene whose result and metrics are both on disk is not run again unless ``force``. A scene that
fails gets a row with its error and does not stop the others. :func:`compare_runs` puts the mean
rows of several runs in one table with the best value of each column in bold (paper Tables 1
and 2).

Files in ``out_dir``: ``<scene>.npz`` (the result), ``<scene>.metrics.json`` (its scores, or its
error), ``metrics.csv`` and ``table.md``, each written atomically.

A data set may hold light-field videos too (docs/design.md section 10): given ``videos`` (a
:class:`VideoScenes`, e.g. :class:`lfsam.video.evaluate.VideoTracking`), every scene it
recognises is tracked into the result folder ``<scene>/`` and scored frame by frame; its row
holds the means over the frames, the number of frames and the identity switches
(:data:`lfsam.metrics.VIDEO_METRICS`). On a Ray cluster (:mod:`lfsam.distributed`) a video's
task writes its result folder on the worker and sends back its files
(:meth:`VideoScenes.run_detached`), which this process writes into ``out_dir``
(:meth:`VideoScenes.store`): the same folder as a sequential run's.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import sys
import tempfile
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from tqdm import tqdm

from lfsam.errors import LfsamError
from lfsam.fileutil import atomic_output
from lfsam.io import detect_format, read_lightfield
from lfsam.lightfield import LightField
from lfsam.metrics import (
    OBJECT_METRICS,
    REPORT_METRICS,
    VIDEO_METRICS,
    Metric,
    check_ground_truth,
    evaluate_result,
)
from lfsam.metrics.report import format_metrics_table
from lfsam.result import SegmentationResult, save_result

__all__ = [
    "CSV_COLUMNS",
    "EvaluationTable",
    "SceneJob",
    "SceneOutcome",
    "SceneRow",
    "VideoScenes",
    "compare_runs",
    "describe_failure",
    "discover_scenes",
    "evaluate_dataset",
    "read_metrics_csv",
]

SegmentFn = Callable[[LightField], SegmentationResult]
Reader = Callable[[Path], LightField]

METRIC_KEYS = tuple(m.key for m in REPORT_METRICS + VIDEO_METRICS)
VIDEO_KEYS = tuple(m.key for m in VIDEO_METRICS)
#: Columns of ``metrics.csv``.
CSV_COLUMNS = ("scene", "method", *METRIC_KEYS, "num_masks", "seconds", "error")
MEAN_ROW = "mean"
_RECORD_SUFFIX = ".metrics.json"


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


def discover_scenes(
    dataset_dir: str | os.PathLike, exclude: Sequence[str | os.PathLike] = ()
) -> list[tuple[str, Path]]:
    """Candidate scenes of a data-set folder: every sub-folder and file, hidden ones excepted.

    Parameters
    ----------
    dataset_dir : path
        The folder holding one scene per sub-folder or file.
    exclude : sequence of paths
        Entries to leave out (e.g. the output folder when it lies inside the data set).

    Returns
    -------
    list of (name, path)
        Sorted by name. The name is the folder name or the file's stem (the full file name when
        two files share a stem).

    Raises
    ------
    LfsamError
        If ``dataset_dir`` is not a folder.
    """
    root = Path(dataset_dir)
    if not root.is_dir():
        raise LfsamError(
            f"data set {str(root)!r} is not a folder; give a folder with one scene per "
            "sub-folder or file"
        )
    skip = {Path(p).resolve() for p in exclude}
    entries = [
        p
        for p in sorted(root.iterdir())
        if not p.name.startswith((".", "_")) and p.resolve() not in skip
    ]
    stems = [p.stem if p.is_file() else p.name for p in entries]
    names = [
        stem if stems.count(stem) == 1 else entry.name
        for stem, entry in zip(stems, entries, strict=True)
    ]
    return sorted(zip(names, entries, strict=True))


def evaluate_dataset(
    dataset_dir: str | os.PathLike,
    out_dir: str | os.PathLike,
    segment_fn: SegmentFn,
    *,
    method_label: str,
    force: bool = False,
    reader: Reader | None = None,
    detect: Callable[[Path], object] | None = None,
    device: str | None = None,
    map_scenes: SceneMapper | None = None,
    videos: VideoScenes | None = None,
) -> EvaluationTable:
    """Segment and score every scene of a data set; write ``metrics.csv`` and ``table.md``.

    Parameters
    ----------
    dataset_dir : path
        A folder with one scene per sub-folder or file, each with per-view ground-truth
        disparity and labels (e.g. UrbanLF-Syn ``val``; scenes from ``lfsam synth``).
    out_dir : path
        Output folder (created if missing).
    segment_fn : callable(LightField) -> SegmentationResult
        The method, e.g. ``functools.partial(lfsam.segment, model="oracle", disparity="gt")``.
        When its result has no ``timings["total"]``, the harness's own wall-clock time of the
        call is stored there, so T is always the time of the whole segmentation.
    method_label : str
        Name of the method in the tables (recorded in every row).
    force : bool
        Recompute scenes whose result and metrics already exist.
    reader : callable(Path) -> LightField, optional
        Reads one scene; default :func:`lfsam.io.read_lightfield`. A scene it cannot read is a
        failed scene (a row with the error).
    detect : callable(Path), optional
        Raises :class:`LfsamError` for an entry that is not a light field at all (a README, an
        empty folder): such entries are skipped with a note. Default
        :func:`lfsam.io.detect_format`.
    device : str, optional
        Where the metrics are computed (default ``auto``, :func:`lfsam.devices.resolve_device`).
    map_scenes : callable(SceneJob, list of (name, path)) -> iterable of SceneOutcome, optional
        Runs the job on the scenes still to do and yields their outcomes as they finish, in any
        order; default: one after the other in this process. :func:`lfsam.distributed.ray_mapper`
        spreads them over a Ray cluster; the files written are the same either way.
    videos : VideoScenes, optional
        Runs the entries that are light-field videos (:class:`VideoScenes`; e.g.
        :class:`lfsam.video.evaluate.VideoTracking`): each is tracked into the result folder
        ``<scene>/`` instead of ``<scene>.npz`` (with ``map_scenes`` too: each video is then
        one job, its folder sent back and written here). Without it a video is skipped as not a
        light field.

    Returns
    -------
    EvaluationTable

    Raises
    ------
    LfsamError
        If ``dataset_dir`` is not a folder, or ``out_dir`` holds results of another method
        (without ``force``).
    """
    if reader is None or detect is None:
        reader = reader or read_lightfield
        detect = detect or detect_format
    out = Path(out_dir)
    scenes = discover_scenes(dataset_dir, exclude=[out])
    out.mkdir(parents=True, exist_ok=True)
    finished = {} if force else _finished_records(out, [name for name, _ in scenes])
    for record in finished.values():
        if record.method != method_label:
            raise LfsamError(
                f"{str(out)!r} holds results of method {record.method!r}, not {method_label!r}; "
                "choose another --out or pass --force to overwrite them"
            )

    rows: list[SceneRow] = []
    table = EvaluationTable(method=method_label, rows=rows, mean={}, out_dir=out)
    bar = tqdm(
        total=len(scenes), desc=f"evaluate {method_label}", unit="scene", disable=None,
        file=sys.stderr,
    )
    pending = []
    for name, path in scenes:
        if name in finished:
            rows.append(finished[name])
            table.resumed.append(name)
            bar.update(1)
        else:
            pending.append((name, path))
    job = SceneJob(segment_fn, method_label, out, device, reader, detect, videos)
    for outcome in (map_scenes or _map_in_order)(job, pending):
        _record_outcome(outcome, job, table)
        bar.set_postfix_str(outcome.name)
        bar.update(1)
    bar.close()
    order = {name: i for i, (name, _) in enumerate(scenes)}
    rows.sort(key=lambda row: order[row.scene])
    table.ran.sort(key=order.__getitem__)

    ok = [row for row in rows if row.error is None]
    table.mean = {key: _mean([row.metrics.get(key) for row in ok]) for key in METRIC_KEYS}
    for key in VIDEO_KEYS:  # totals, not means: frames scored and identity switches in all
        values = [row.metrics.get(key) for row in ok if row.metrics.get(key) is not None]
        # float, as in the rows' records: a resumed run writes the mean row of a fresh one
        table.mean[key] = float(sum(values)) if values else None
    _write_text(out / "metrics.csv", table.to_csv())
    _write_text(out / "table.md", table.to_markdown(f"{method_label} on {Path(dataset_dir).name}"))
    return table


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


# --- internals ------------------------------------------------------------------------------


@dataclass
class SceneOutcome:
    """What one scene's job produced, for the process that writes the output folder.

    Attributes
    ----------
    name : str
        Scene name.
    row : SceneRow or None
        Its row; None when the entry is not a light field (then ``skipped`` says why).
    skipped : str or None
        Why the entry was skipped.
    entry : str
        The entry's file or folder name (for the skip note).
    result_bytes : bytes or None
        The result's ``.npz`` file, when the job ran with ``in_memory`` (on another machine);
        otherwise the job wrote it into the output folder itself.
    result_files : dict of str to bytes, or None
        A video's result folder (path inside it -> file contents), when the job ran with
        ``in_memory`` (:meth:`VideoScenes.run_detached`).
    """

    name: str
    row: SceneRow | None
    skipped: str | None = None
    entry: str = ""
    result_bytes: bytes | None = None
    result_files: dict[str, bytes] | None = None


@dataclass
class SceneJob:
    """Detect, read, segment, score and save one scene: the unit of work of
    :func:`evaluate_dataset`, picklable so that it can run in another process (a Ray task)."""

    segment_fn: SegmentFn
    method_label: str
    out: Path
    device: str | None
    reader: Reader
    detect: Callable[[Path], object]
    videos: VideoScenes | None = None

    def __call__(self, name: str, path: Path, in_memory: bool = False) -> SceneOutcome:
        """Run the scene; with ``in_memory`` the result file (a video's result folder) comes
        back as bytes instead of being written to the output folder (for a machine that may not
        see it; docs/design.md section 10)."""
        if self.videos is not None and self.videos.is_video(path):
            if in_memory:
                row, files = self.videos.run_detached(name, path, self.out / name)
                return SceneOutcome(name=name, row=row, entry=path.name, result_files=files)
            row = self.videos.run(name, path, self.out / name)
            return SceneOutcome(name=name, row=row, entry=path.name)
        try:
            self.detect(path)
        except LfsamError as exc:
            return SceneOutcome(name=name, row=None, skipped=str(exc), entry=path.name)
        try:
            lightfield = self.reader(path)
        except Exception as exc:  # an unreadable scene is a failed scene, not the end of the run
            row = SceneRow(scene=name, method=self.method_label, error=describe_failure(exc))
            return SceneOutcome(name=name, row=row, entry=path.name)
        if not in_memory:
            row = _run_scene(
                name, lightfield, self.segment_fn, self.method_label, self.out, self.device
            )
            return SceneOutcome(name=name, row=row, entry=path.name)
        with tempfile.TemporaryDirectory(prefix="lfsam-scene-") as tmp:
            row = _run_scene(
                name, lightfield, self.segment_fn, self.method_label, Path(tmp), self.device
            )
            saved = Path(tmp) / f"{name}.npz"
            data = saved.read_bytes() if saved.is_file() else None
        return SceneOutcome(name=name, row=row, entry=path.name, result_bytes=data)


    def refused(self, name: str, path: Path) -> SceneOutcome | None:
        """The error row of a video whose result folder may not be replaced, found before any
        work (a Ray run asks before sending its task, issue 46), else None."""
        if self.videos is None or not self.videos.is_video(path):
            return None
        try:
            self.videos.check_target(self.out / name)
        except LfsamError as exc:
            row = SceneRow(scene=name, method=self.method_label, error=describe_failure(exc))
            return SceneOutcome(name=name, row=row, entry=path.name)
        return None


SceneMapper = Callable[[SceneJob, Sequence[tuple[str, Path]]], Iterable[SceneOutcome]]


class VideoScenes(Protocol):
    """How :func:`evaluate_dataset` runs the light-field videos of a data set (docs/design.md
    section 10); :class:`lfsam.video.evaluate.VideoTracking` is the implementation."""

    def is_video(self, path: Path) -> bool:
        """Whether the data-set entry ``path`` is a light-field video."""

    def run(self, name: str, path: Path, result_folder: Path) -> SceneRow:
        """Track, write the result folder ``result_folder`` and score one video; any failure
        is the row's error."""

    def run_detached(self, name: str, path: Path, result_folder: Path
                     ) -> tuple[SceneRow, dict[str, bytes] | None]:
        """As :meth:`run` on a machine that may not see ``result_folder`` (a Ray task): the
        row, and the result folder's files (path inside it -> contents; None on error)."""

    def store(self, files: dict[str, bytes], result_folder: Path) -> None:
        """Write the files of :meth:`run_detached` as ``result_folder``, as :meth:`run` would
        have written it; raises when it cannot."""

    def check_target(self, result_folder: Path) -> None:
        """Raise :class:`LfsamError` (as :meth:`run` would) if ``result_folder`` may not be
        written, before any work."""


def _map_in_order(job: SceneJob, scenes: Sequence[tuple[str, Path]]) -> Iterator[SceneOutcome]:
    """The default :data:`SceneMapper`: each scene in this process, in name order."""
    for name, path in scenes:
        yield job(name, path)


def _record_outcome(outcome: SceneOutcome, job: SceneJob, table: EvaluationTable) -> None:
    """Write a finished scene's files (result before record: resumability) and tabulate it."""
    out = job.out
    if outcome.row is None:
        table.skipped.append((outcome.entry, str(outcome.skipped)))
        note = f"lfsam evaluate: skipping {outcome.entry}: not a light field ({outcome.skipped})"
        tqdm.write(note, file=sys.stderr)
        return
    row = outcome.row
    if outcome.result_bytes is not None and row.error is None:
        with atomic_output(out / f"{row.scene}.npz") as tmp:
            tmp.write_bytes(outcome.result_bytes)
    if outcome.result_files is not None and row.error is None and job.videos is not None:
        try:
            job.videos.store(outcome.result_files, out / row.scene)
        except Exception as exc:  # as the sequential run's failure to write the folder
            row = SceneRow(scene=row.scene, method=row.method, error=describe_failure(exc))
    if row.error is not None:
        tqdm.write(f"lfsam evaluate: scene {row.scene} failed: {row.error}", file=sys.stderr)
    _write_text(out / f"{row.scene}{_RECORD_SUFFIX}", json.dumps(row.to_record(), indent=1))
    table.rows.append(row)
    table.ran.append(row.scene)


def _run_scene(
    name: str,
    lightfield: LightField,
    segment_fn: SegmentFn,
    method_label: str,
    out: Path,
    device: str | None,
) -> SceneRow:
    """Segment, save and score one scene; any exception becomes the row's error."""
    row = SceneRow(scene=name, method=method_label)
    try:
        check_ground_truth(lightfield.views.shape[:4], lightfield)
        start = time.perf_counter()
        result = segment_fn(lightfield)
        row.seconds = time.perf_counter() - start
        if result.timings.get("total") is None:
            result.timings["total"] = row.seconds
        result.meta.setdefault("evaluation_method", method_label)
        metrics = evaluate_result(result, lightfield, device=device)
        row.num_masks = int(metrics.pop("num_masks"))
        row.metrics = metrics
        save_result(result, out / f"{name}.npz")
    except Exception as exc:  # one broken scene must not stop the data set
        row.metrics = {}
        row.error = describe_failure(exc)
    return row


def _finished_records(out: Path, names: Sequence[str]) -> dict[str, SceneRow]:
    """Scenes whose result and error-free metrics record are both in ``out``."""
    done = {}
    for name in names:
        record_path = out / f"{name}{_RECORD_SUFFIX}"
        result = out / f"{name}.npz"
        if not (record_path.is_file() and (result.is_file() or (out / name).is_dir())):
            continue
        try:
            row = SceneRow.from_record(json.loads(record_path.read_text(encoding="utf-8")))
        except (ValueError, KeyError, TypeError):
            continue  # unreadable record: run the scene again
        if row.error is None:
            done[name] = row
    return done


def describe_failure(exc: BaseException) -> str:
    """One line naming an exception: the message of an LfsamError, else type and message."""
    text = str(exc) if isinstance(exc, LfsamError) else f"{type(exc).__name__}: {exc}"
    return " ".join(text.split())


def _write_text(path: Path, text: str) -> None:
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

