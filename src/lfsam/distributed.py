"""Data-set runs on a Ray cluster: one task per scene (``lfsam evaluate --ray``; issues 18, 38).

:func:`ray_mapper` gives :func:`lfsam.evaluate.evaluate_dataset` a scene mapper that sends each
scene still to do to a Ray task and hands back the outcomes as the tasks finish. A light field's
task reads, segments and scores it and returns the result file's bytes; a light-field video's
task (the run's :class:`lfsam.evaluate.VideoScenes`, e.g. :class:`lfsam.video.evaluate.
VideoTracking`) tracks and scores it into a temporary folder on the worker and returns that
result folder's files (docs/design.md section 10). The calling process writes every file of the
output folder, so the folder is the same as a sequential run's (same files, same rows, same
resumability: an interrupted run keeps the scenes finished so far) and need not be visible to
the workers. The workers must see the data set at the same path (a shared file system) and have
lfsam installed (or ship it with Ray's ``runtime_env``). A video's result folder travels back
as one Ray object, held in memory until written (a long video of large views needs the room).

Each task (a light field or a whole video) asks Ray for ``num_cpus`` CPUs and, on CUDA,
``num_gpus`` GPUs (a fraction such as 0.5 packs two scenes per GPU; Ray sets
``CUDA_VISIBLE_DEVICES`` so the task's ``cuda`` device is its own GPU). Ray is an optional
dependency: ``pip install lfsam[ray]``.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from lfsam.errors import LfsamError
from lfsam.evaluate import SceneJob, SceneMapper, SceneOutcome, SceneRow

__all__ = ["import_ray", "ray_mapper", "task_resources"]


def import_ray() -> Any:
    """The ``ray`` module, or a one-line :class:`LfsamError` saying how to install it."""
    try:
        import ray
    except ImportError as exc:
        raise LfsamError(
            f"--ray needs Ray, which is not installed ({exc}); run: pip install 'lfsam[ray]'"
        ) from exc
    return ray


def task_resources(
    device: str | None, cluster_gpus: float, num_gpus: float | None = None, num_cpus: float = 1
) -> dict[str, float]:
    """Ray resources of one scene's task (a light field or a video).

    Parameters
    ----------
    device : str or None
        The run's ``--device``; None = the best available on the worker.
    cluster_gpus : float
        GPUs the cluster has (``ray.cluster_resources()["GPU"]``).
    num_gpus : float, optional
        GPUs (or a fraction) per task; default 1 when the run may use CUDA and the cluster has
        GPUs, else 0.
    num_cpus : float
        CPUs per task.

    Raises
    ------
    LfsamError
        If GPUs are asked for on a cluster without any, or with ``--device cpu``/``mps``.
    """
    if num_cpus <= 0:
        raise LfsamError(f"CPUs per task must be > 0, got {num_cpus}")
    wants_cuda = device is None or str(device).startswith("cuda")
    if num_gpus is None:
        num_gpus = 1.0 if wants_cuda and cluster_gpus > 0 else 0.0
    if num_gpus < 0:
        raise LfsamError(f"GPUs per task must be >= 0, got {num_gpus}")
    if num_gpus > 0 and not wants_cuda:
        raise LfsamError(f"--gpus-per-task {num_gpus} with --device {device}; use --device cuda")
    if num_gpus > cluster_gpus:
        raise LfsamError(
            f"each task asks for {num_gpus} GPU(s) but the Ray cluster has {cluster_gpus:g}; "
            "lower --gpus-per-task or add GPU nodes"
        )
    if str(device).startswith("cuda") and num_gpus == 0:
        raise LfsamError(
            "--device cuda but the Ray cluster has no GPUs; drop --device or add GPU nodes"
        )
    return {"num_cpus": float(num_cpus), "num_gpus": float(num_gpus)}


def _run_remote(job: SceneJob, name: str, path: str) -> SceneOutcome:
    """The body of one Ray task: the scene's job, its result file (a video's result folder)
    returned as bytes."""
    return job(name, Path(path), in_memory=True)


def ray_mapper(
    address: str | None = None,
    *,
    device: str | None = None,
    num_gpus: float | None = None,
    num_cpus: float = 1,
    init_options: dict[str, Any] | None = None,
) -> SceneMapper:
    """A scene mapper for :func:`lfsam.evaluate.evaluate_dataset` that runs on Ray.

    Parameters
    ----------
    address : str, optional
        Ray cluster address (``auto``, ``ray://host:10001``, ``host:6379``); None starts a local
        cluster on this machine. When Ray is already initialised in this process (a caller's
        own ``ray.init``) that connection is used and left open.
    device : str, optional
        The run's device (decides whether tasks ask for GPUs).
    num_gpus : float, optional
        GPUs per task (see :func:`task_resources`).
    num_cpus : float
        CPUs per task.
    init_options : dict, optional
        Extra keywords of ``ray.init`` (e.g. ``num_cpus`` of a local cluster, ``runtime_env``).

    Returns
    -------
    callable(SceneJob, list of (name, path)) -> iterator of SceneOutcome, in finishing order

    Raises
    ------
    LfsamError
        If Ray is not installed or the cluster cannot be reached.
    """
    ray = import_ray()

    def run(job: SceneJob, scenes: Sequence[tuple[str, Path]]) -> Iterator[SceneOutcome]:
        started_here = False
        if not ray.is_initialized():
            options = {"log_to_driver": False, "include_dashboard": False,
                       **(init_options or {})}
            try:
                ray.init(address=address, **options)
            except (ConnectionError, RuntimeError, ValueError) as exc:
                where = address or "a local cluster"
                raise LfsamError(
                    f"cannot start or reach Ray at {where} ({' '.join(str(exc).split())[:200]}); "
                    "check the --ray address (or `ray status` there)"
                ) from exc
            started_here = True
        try:
            gpus = float(ray.cluster_resources().get("GPU", 0.0))
            resources = task_resources(device, gpus, num_gpus, num_cpus)
            task = ray.remote(max_retries=0, **resources)(_run_remote)
            job_ref = ray.put(job)
            futures = {}
            for name, path in scenes:  # a result folder that may not be replaced: no task
                refused = job.refused(name, Path(path))
                if refused is not None:
                    yield refused
                else:
                    futures[task.remote(job_ref, name, str(path))] = (name, path)
            while futures:
                done, _ = ray.wait(list(futures), num_returns=1)
                name, path = futures.pop(done[0])
                try:
                    outcome = ray.get(done[0])
                except Exception as exc:  # a task that died (worker lost, out of memory)
                    text = " ".join(f"{type(exc).__name__}: {exc}".split())[:300]
                    row = SceneRow(scene=name, method=job.method_label,
                                   error=f"Ray task failed: {text}")
                    outcome = SceneOutcome(name=name, row=row, entry=Path(path).name)
                yield outcome
        finally:
            if started_here:
                ray.shutdown()

    return run
