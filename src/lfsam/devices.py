"""One device vocabulary for the whole package: ``auto``, ``cpu``, ``cuda``, ``cuda:N``, ``mps``.

Every place that takes a device (the CLI's ``--device``, :func:`lfsam.segmenters.load_segmenter`,
:func:`lfsam.disparity.estimate_disparity`, the metrics, the synthetic renderer) turns it into a
``torch.device`` with :func:`resolve_device`, so the same spelling means the same device
everywhere and a wrong one gives the same one-line :class:`~lfsam.errors.LfsamError`.
``auto`` (the default, also ``None``) picks CUDA, then MPS, then the CPU.

What depends on the device is decided here too: :func:`default_encode_batch_size`, the number of
views the SAM 2 image encoder takes at once (docs/design.md section 3, "efficiency facts"), and on
a CPU how many views are worked on at a time (:func:`view_workers`) and how torch's threads are
shared between threads that compute beside each other (:func:`thread_share`, :func:`threads_of`;
docs/design.md section 3.2).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager

import torch

from lfsam.errors import LfsamError

__all__ = [
    "CUDA_CROSS_VIEW_ROWS",
    "CUDA_ENCODE_BATCH_SIZE",
    "CUDA_PROMPT_BATCH_SIZE",
    "DEVICE_HELP",
    "check_device_spec",
    "default_encode_batch_size",
    "default_prompt_batch_size",
    "resolve_device",
    "thread_share",
    "threads_of",
    "view_workers",
]

DEVICE_HELP = "auto (CUDA, then MPS, then CPU), cpu, cuda, cuda:N or mps"
"""The vocabulary, as the CLI's help and the error messages spell it."""

CUDA_ENCODE_BATCH_SIZE = 4
"""Views per image-encoder call on CUDA (batching pays off there; on a CPU it only costs memory)."""

CUDA_PROMPT_BATCH_SIZE = 128
"""Prompts of one view per mask-decoder call on CUDA: the paper's 100 masks of a view in one call
(chunks of 16 were launch-bound on an H100; benchmarks/bench_gpu.py, docs/performance.md)."""

CPU_PROMPT_BATCH_SIZE = 64
"""Prompts per mask-decoder call elsewhere (bounds the N x 3 x U x V logits in memory)."""

CUDA_CROSS_VIEW_ROWS = 512
"""Prompts of several views per mask-decoder pass on CUDA when views share decoder calls
(:meth:`lfsam.segmenters.sam2.backend.Sam2Segmenter.predict_many`): about 13 MB each in bfloat16
at 480 x 640 with the upsampled logits, some 7 GB a pass (not yet timed on a GPU: issue 44)."""

_SPEC = re.compile(r"auto|cpu|mps|cuda(:\d+)?")


def check_device_spec(spec: str) -> str:
    """``spec`` normalised (stripped, lower case) if it is a word of the vocabulary.

    Only the spelling is checked (availability is :func:`resolve_device`'s job), so the CLI can
    reject ``--device gpu`` before reading any input.

    Raises
    ------
    LfsamError
        If ``spec`` is not ``auto``, ``cpu``, ``cuda``, ``cuda:N`` or ``mps``.
    """
    text = str(spec).strip().lower()
    if not _SPEC.fullmatch(text):
        raise LfsamError(f"--device {spec}: unknown device; use {DEVICE_HELP}")
    return text


def resolve_device(spec: str | torch.device | None = None) -> torch.device:
    """The torch device ``spec`` names, checked to be available here.

    Parameters
    ----------
    spec : str, torch.device or None
        ``"auto"`` (or None: CUDA, then MPS, then CPU), ``"cpu"``, ``"cuda"``, ``"cuda:N"`` or
        ``"mps"``; a ``torch.device`` of one of these types is checked the same way.

    Returns
    -------
    torch.device

    Raises
    ------
    LfsamError
        One line naming the device and the fix, if ``spec`` is not in the vocabulary or the device
        is not available here (e.g. ``--device cuda`` without a CUDA device).

    Examples
    --------
    >>> resolve_device("cpu")
    device(type='cpu')
    """
    if isinstance(spec, torch.device):
        dev = spec
        name = str(spec)
        if dev.type not in ("cpu", "cuda", "mps"):
            raise LfsamError(f"--device {name}: unsupported device type; use {DEVICE_HELP}")
    else:
        name = check_device_spec("auto" if spec is None else spec)
        if name == "auto":
            if torch.cuda.is_available():
                return torch.device("cuda")
            if _mps_available():
                return torch.device("mps")
            return torch.device("cpu")
        dev = torch.device(name)
    if dev.type == "cuda":
        if not torch.cuda.is_available():
            raise LfsamError(
                f"--device {name}: CUDA is not available here; use --device auto or cpu"
            )
        count = torch.cuda.device_count()
        if dev.index is not None and dev.index >= count:
            raise LfsamError(
                f"--device {name}: this machine has {count} CUDA device(s); use cuda:0 or auto"
            )
    elif dev.type == "mps" and not _mps_available():
        raise LfsamError(f"--device {name}: MPS is not available here; use --device auto or cpu")
    return dev


def default_encode_batch_size(device: str | torch.device) -> int:
    """Views the SAM 2 image encoder takes at once on ``device``: 4 on CUDA, 1 elsewhere.

    The single source of this choice: :class:`lfsam.pipeline.PipelineConfig` (``None`` = from the
    device) and :class:`lfsam.segmenters.sam2.backend.Sam2Segmenter` both ask here.

    Examples
    --------
    >>> default_encode_batch_size("cpu")
    1
    """
    return CUDA_ENCODE_BATCH_SIZE if torch.device(device).type == "cuda" else 1


def default_prompt_batch_size(device: str | torch.device) -> int:
    """Prompts of one view the mask decoder takes per call on ``device``: 128 on CUDA, 64
    elsewhere; the single source for refinement (:class:`lfsam.pipeline.PipelineConfig`) and
    :class:`lfsam.segmenters.sam2.backend.Sam2Segmenter`.

    Examples
    --------
    >>> default_prompt_batch_size("cpu")
    64
    """
    cuda = torch.device(device).type == "cuda"
    return CUDA_PROMPT_BATCH_SIZE if cuda else CPU_PROMPT_BATCH_SIZE


def _mps_available() -> bool:
    mps = getattr(torch.backends, "mps", None)
    return bool(mps is not None and mps.is_available())


def view_workers(device: torch.device) -> int:
    """Views processed at a time (docs/design.md sections 12 and 13): two on the CPU, each in a
    thread (torch, OpenCV and NumPy release the GIL, and one view's many small operations leave
    a core idle), as many as torch's threads allow; one on a GPU, which runs one view's work at
    once."""
    return max(1, min(2, torch.get_num_threads())) if device.type == "cpu" else 1


def thread_share(streams: int, device: torch.device) -> int:
    """torch's intra-op threads for each of ``streams`` threads that compute at once on
    ``device`` (docs/design.md section 3.2): on the CPU the process's threads split between
    them (at least one each), so that they do not take turns on the same cores; elsewhere
    torch's own setting."""
    total = torch.get_num_threads()
    if device.type != "cpu" or streams <= 1:
        return total
    return max(1, total // streams)


@contextmanager
def threads_of(count: int) -> Iterator[None]:
    """Run the block with ``count`` torch intra-op threads in the calling thread, then put its
    own back (docs/design.md section 3.2).

    With OpenMP (torch's CPU builds) the count is the calling thread's own: other threads keep
    theirs. Threads that compute beside each other each take their :func:`thread_share`.
    """
    before = torch.get_num_threads()
    if count == before:
        yield
        return
    torch.set_num_threads(count)
    try:
        yield
    finally:
        torch.set_num_threads(before)
