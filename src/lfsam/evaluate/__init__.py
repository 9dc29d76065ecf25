"""The data-set harness behind the paper's Tables 1 and 2 (paper section 4).

Metrics as in docs/design.md section 5.

:func:`evaluate_dataset` runs one segmentation method on every scene of a folder, saves each
result, scores it with :func:`lfsam.metrics.evaluate_result`, and writes ``metrics.csv`` (a row
per scene and a ``mean`` row) and ``table.md`` (the layout of paper Table 1). It is resumable:
a scene whose result and metrics are both on disk is not run again unless ``force``. A scene that
fails gets a row with its error and does not stop the others. :func:`compare_runs` puts the mean
rows of several runs in one table with the best value of each column in bold (paper Tables 1
and 2).

The package: :mod:`~lfsam.evaluate.dataset` (the harness), :mod:`~lfsam.evaluate.jobs` (one
scene, here or on a worker), :mod:`~lfsam.evaluate.table` (rows, ``metrics.csv``, ``table.md``,
the comparison of runs); every name below is importable from :mod:`lfsam.evaluate`.

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

from lfsam.evaluate.dataset import SceneMapper, discover_scenes, evaluate_dataset
from lfsam.evaluate.jobs import SceneJob, SceneOutcome, VideoScenes, describe_failure
from lfsam.evaluate.table import (
    CSV_COLUMNS,
    EvaluationTable,
    SceneRow,
    compare_runs,
    read_metrics_csv,
)

__all__ = [
    "CSV_COLUMNS",
    "EvaluationTable",
    "SceneJob",
    "SceneMapper",
    "SceneOutcome",
    "SceneRow",
    "VideoScenes",
    "compare_runs",
    "describe_failure",
    "discover_scenes",
    "evaluate_dataset",
    "read_metrics_csv",
]
