"""A data set evaluated (:mod:`lfsam.evaluate`): :func:`discover_scenes` finds its scenes,
:func:`evaluate_dataset` runs one segmentation method on each (in this process, or through a
:data:`SceneMapper` such as :func:`lfsam.distributed.ray_mapper`), resumes where a scene's result
and metrics are on disk, and writes the run's tables (:mod:`lfsam.evaluate.table`).
"""

from __future__ import annotations

import json
import os
import sys
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path

from tqdm import tqdm

from lfsam.errors import LfsamError
from lfsam.evaluate.jobs import (
    Reader,
    SceneJob,
    SceneOutcome,
    SegmentFn,
    VideoScenes,
    describe_failure,
)
from lfsam.evaluate.table import (
    METRIC_KEYS,
    RECORD_SUFFIX,
    VIDEO_KEYS,
    EvaluationTable,
    SceneRow,
    _mean,
    write_text,
)
from lfsam.fileutil import atomic_output
from lfsam.io import detect_format, read_lightfield

__all__ = ["discover_scenes", "evaluate_dataset"]


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
    write_text(out / "metrics.csv", table.to_csv())
    write_text(out / "table.md", table.to_markdown(f"{method_label} on {Path(dataset_dir).name}"))
    return table


# --- internals ------------------------------------------------------------------------------


SceneMapper = Callable[[SceneJob, Sequence[tuple[str, Path]]], Iterable[SceneOutcome]]


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
    write_text(out / f"{row.scene}{RECORD_SUFFIX}", json.dumps(row.to_record(), indent=1))
    table.rows.append(row)
    table.ran.append(row.scene)


def _finished_records(out: Path, names: Sequence[str]) -> dict[str, SceneRow]:
    """Scenes whose result and error-free metrics record are both in ``out``."""
    done = {}
    for name in names:
        record_path = out / f"{name}{RECORD_SUFFIX}"
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
