"""The chunked result of a light-field video (docs/design.md section 10).

A folder::

    lfsam_video_result.json   format, version, frames, grid, view_size, object ids, meta
    frame_0000.npz ...        one result per frame (:func:`lfsam.result.save_result`)

The manifest's ``meta["objects"]`` keeps each object as the track was given it, so that the
folder reopens editable (:meth:`VideoResult.stored_prompts`): one entry per object in id order,
in the prompt-file format (:func:`lfsam.prompts.prompts_to_json`: every point and the box with
its view and its ``frame``), or ``"mask": "automatic"`` for an object without prompts (found by
the automatic mode), with ``"category"`` where the frames' results name one. Folders written
before lfsam stored them have no ``meta["objects"]``: they open, with no prompts.

written frame by frame into a temporary folder next to the target and renamed onto it when
the last frame is in (:func:`lfsam.fileutil.atomic_folder_output`): a failed run leaves
nothing. Memory stays flat in the number of frames. :func:`load_video_result` (and
``lfsam.load_result``, which detects the folder) reads frames lazily: the labels
``[F, S, T, U, V]`` are :class:`FrameLabels`, one frame loaded per index.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from lfsam.errors import LfsamError
from lfsam.fileutil import atomic_folder_output
from lfsam.prompts import ObjectPrompts, prompts_from_json, prompts_to_json
from lfsam.result import (
    FAST_LEVEL,
    SegmentationResult,
    label_ids,
    load_result,
    save_result,
)

__all__ = [
    "RESULT_MARKER",
    "FrameLabels",
    "VideoResult",
    "hidden_spans",
    "is_video_result",
    "load_video_result",
    "record_states",
    "video_result_writer",
]

RESULT_MARKER = "lfsam_video_result.json"
FORMAT = "lfsam-video-result"
#: The keys of a ``meta["objects"]`` entry that are prompts (the prompt-file format's).
_PROMPT_KEYS = ("id", "points", "labels", "box", "view", "frame")


def frame_name(index: int) -> str:
    """``frame_0003.npz``."""
    return f"frame_{index:04d}.npz"


def is_video_result(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a video result folder."""
    return (Path(path) / RESULT_MARKER).is_file()


def check_result_folder(path: str | os.PathLike) -> Path:
    """Check that a video result can be written to ``path`` (a new name, an earlier video
    result, or an empty folder, in an existing parent folder).

    Raises
    ------
    LfsamError
        One line naming the problem.
    """
    path = Path(path)
    if path.suffix.lower() == ".npz":
        raise LfsamError(
            f"the result of a light-field video is a folder (one file per frame); give --out "
            f"without .npz, e.g. {path.with_suffix('')}"
        )
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise LfsamError(f"the folder {str(parent)!r} for {str(path)!r} does not exist")
    if path.exists() and not (path.is_dir() and (is_video_result(path) or not any(
            path.iterdir()))):
        raise LfsamError(
            f"{str(path)!r} exists and is not a video result; choose a new name (an earlier "
            "video result or an empty folder is replaced)"
        )
    return path


class FrameWriter:
    """Writes frames into the temporary folder; :func:`video_result_writer` finishes it."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.frames = 0
        self.object_ids: set[int] = set()
        self.grid: list[int] | None = None
        self.view_size: list[int] | None = None
        self.categories: dict[int, str] = {}

    def write(self, result: SegmentationResult) -> None:
        """Append the next frame's result."""
        self.check(result, self.frames)
        self.store(result)

    def check(self, result: SegmentationResult, index: int) -> None:
        """Check that frame ``index``'s labels have the first frame's shape.

        Raises
        ------
        LfsamError
            One line naming both shapes.
        """
        shape = list(np.shape(result.labels))
        if self.grid is None:
            self.grid, self.view_size = shape[:2], shape[2:]
        elif shape != [*self.grid, *self.view_size]:
            raise LfsamError(f"frame {index} has labels {shape}, the first frame "
                             f"{[*self.grid, *self.view_size]}")

    def store(self, result: SegmentationResult) -> None:
        """Write the next frame's file (zlib :data:`lfsam.result.FAST_LEVEL`: a video's frames
        are written as they come, issue 44) and note its objects and categories."""
        save_result(result, self.folder / frame_name(self.frames), level=FAST_LEVEL)
        self.object_ids.update(int(i) for i in label_ids(result.labels) if i > 0)
        for key, phrase in (result.meta.get("categories") or {}).items():
            self.categories.setdefault(int(key), str(phrase))
        self.frames += 1

    def manifest(self, meta: dict[str, Any] | None, objects: Sequence[ObjectPrompts] | None,
                 complete: bool | None = None) -> dict[str, Any]:
        """The manifest of the frames written so far (``complete`` only for live folders)."""
        manifest = {
            "format": FORMAT,
            "version": 1,
            "frames": self.frames,
            "grid": self.grid,
            "view_size": self.view_size,
            "object_ids": sorted(self.object_ids),
            "meta": {**(meta or {}),
                     **({} if objects is None else {"objects": self.object_entries(objects)})},
        }
        if complete is not None:
            manifest["complete"] = bool(complete)
        return manifest

    def object_entries(self, objects: Sequence[ObjectPrompts]) -> list[dict[str, Any]]:
        """``meta["objects"]`` (see the module docstring): ``objects``' prompts, the other ids
        of the labels as automatic masks, each with its category if a frame gave one."""
        prompted = {int(obj.obj_id): obj for obj in objects}
        entries = []
        for obj_id in sorted({*prompted, *self.object_ids}):
            obj = prompted.get(obj_id)
            entry = (prompts_to_json([obj])[0] if obj is not None
                     else {"id": obj_id, "mask": "automatic"})
            if obj_id in self.categories:
                entry["category"] = self.categories[obj_id]
            entries.append(entry)
        return entries


def hidden_spans(tracks: Mapping[str, Sequence[str]]) -> dict[str, list[list[int]]]:
    """Each object's runs of frames where it was *hidden* (``meta["tracks"]``, docs/design.md
    section 10), as ``[first, last]`` frame indices (inclusive); objects never hidden are left
    out. A run ending before the last frame ended with the object found again (or prompted).

    Examples
    --------
    >>> hidden_spans({"1": ["prompted", "tracked"],
    ...               "2": ["prompted", "hidden", "hidden", "found", "hidden"]})
    {'2': [[1, 2], [4, 4]]}
    """
    spans: dict[str, list[list[int]]] = {}
    for key, states in tracks.items():
        runs: list[list[int]] = []
        for index, state in enumerate(states):
            if state != "hidden":
                continue
            if runs and runs[-1][1] == index - 1:
                runs[-1][1] = index
            else:
                runs.append([index, index])
        if runs:
            spans[key] = runs
    return spans


def record_states(history: dict[str, list[str]], states: dict[str, str], index: int) -> None:
    """Append frame ``index``'s object states (``meta["tracks"]`` of its result) to the
    manifest's ``meta["tracks"]``: one list per object id (a string), one state per frame,
    ``"waiting"`` for the frames before the object was known (docs/design.md section 10)."""
    for key, state in states.items():
        history.setdefault(key, ["waiting"] * index).append(state)
    for states_so_far in history.values():
        if len(states_so_far) < index + 1:
            states_so_far.append("waiting")


@contextlib.contextmanager
def video_result_writer(path: str | os.PathLike, meta: dict[str, Any] | None = None,
                        objects: Sequence[ObjectPrompts] | None = None) -> Iterator[FrameWriter]:
    """Write a video result frame by frame; it appears at ``path`` only when complete.

    Parameters
    ----------
    path : path-like
        The result folder (:func:`check_result_folder`).
    meta : dict, optional
        The manifest's ``meta``, read when the last frame is in (so it may be completed
        meanwhile).
    objects : sequence of ObjectPrompts, optional
        The objects' frame-tagged prompts the frames were tracked from (an empty sequence for
        the automatic mode), kept as ``meta["objects"]`` (see the module docstring) so that
        the folder reopens editable; None keeps no objects.

    Examples
    --------
    >>> import tempfile
    >>> labels = np.zeros((1, 1, 2, 3), np.int32)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     with video_result_writer(f"{folder}/out") as writer:
    ...         for f in range(3):
    ...             writer.write(SegmentationResult(labels=labels + f))
    ...     video = load_video_result(f"{folder}/out")
    ...     video.labels.shape, int(video.labels[2].max()), video.object_ids
    ((3, 1, 1, 2, 3), 2, [1, 2])
    """
    path = check_result_folder(path)
    with atomic_folder_output(path) as tmp:
        writer = FrameWriter(tmp)
        yield writer
        if writer.frames == 0:
            raise LfsamError("a video result needs at least one frame")
        (tmp / RESULT_MARKER).write_text(json.dumps(writer.manifest(meta, objects), indent=1,
                                                    default=str), encoding="utf-8")


class FrameLabels:
    """The labels ``[F, S, T, U, V]`` of a video result, one frame read per index."""

    def __init__(self, result: VideoResult) -> None:
        self._result = result

    @property
    def shape(self) -> tuple[int, int, int, int, int]:
        """``(F, S, T, U, V)``."""
        return self._result.shape

    def __len__(self) -> int:
        return len(self._result)

    def __getitem__(self, index: int) -> np.ndarray:
        return self._result.frame(index).labels

    def __iter__(self) -> Iterator[np.ndarray]:
        for index in range(len(self)):
            yield self[index]


class VideoResult:
    """A video result folder, read lazily (:func:`load_video_result`)."""

    def __init__(self, path: Path, manifest: dict[str, Any]) -> None:
        self.path = path
        self.num_frames = int(manifest["frames"])
        self.grid_shape = tuple(int(x) for x in manifest["grid"])
        self.view_shape = tuple(int(x) for x in manifest["view_size"])
        self.object_ids = [int(i) for i in manifest.get("object_ids", [])]
        self.meta: dict[str, Any] = manifest.get("meta") or {}
        #: False while a followed stream is still writing the folder (issue 35).
        self.complete = bool(manifest.get("complete", True))
        self.labels = FrameLabels(self)

    def __len__(self) -> int:
        return self.num_frames

    @property
    def shape(self) -> tuple[int, int, int, int, int]:
        """``(F, S, T, U, V)``."""
        return (self.num_frames, *self.grid_shape, *self.view_shape)

    def frame(self, index: int) -> SegmentationResult:
        """The result of frame ``index``, read now.

        Raises
        ------
        LfsamError
            For an index outside the video or a missing or damaged frame file.
        """
        if not -self.num_frames <= int(index) < self.num_frames:
            raise LfsamError(
                f"frame {index} is outside the result (frames 0..{self.num_frames - 1})"
            )
        index = int(index) % self.num_frames
        result = load_result(self.path / frame_name(index))
        if result.labels.shape != self.shape[1:]:
            raise LfsamError(f"{frame_name(index)} in {self.path} has labels "
                             f"{result.labels.shape}, the video {self.shape[1:]}")
        return result

    def __iter__(self) -> Iterator[SegmentationResult]:
        for index in range(self.num_frames):
            yield self.frame(index)

    def stored_prompts(self) -> list[ObjectPrompts] | None:
        """The prompted objects as the track was given them, each point and box with its frame
        (``meta["objects"]``, see the module docstring), in id order, to reopen the folder for
        editing; objects without prompts (automatic masks) are left out.

        Returns
        -------
        list of ObjectPrompts, or None
            None for a folder that keeps no objects (written before lfsam stored them).

        Raises
        ------
        LfsamError
            If the stored objects are damaged (one line naming the folder).
        """
        entries = self.meta.get("objects")
        if entries is None:
            return None
        try:
            if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
                raise LfsamError("a list of objects is expected")
            objects = prompts_from_json([{k: v for k, v in e.items() if k in _PROMPT_KEYS}
                                         for e in entries if "mask" not in e])
        except LfsamError as exc:
            raise LfsamError(f"the objects stored in {self.path / RESULT_MARKER} are damaged "
                             f"({exc}); track the video again") from None
        return [obj for obj in objects if isinstance(obj, ObjectPrompts)]

    @property
    def categories(self) -> dict[int, str]:
        """Each object's category (``meta["objects"]``), for the objects that have one."""
        entries = self.meta.get("objects")
        if not isinstance(entries, list):
            return {}
        return {int(e["id"]): str(e["category"]) for e in entries
                if isinstance(e, dict) and e.get("category") and "id" in e}


def load_video_result(path: str | os.PathLike) -> VideoResult:
    """Open a video result folder (frames are read when asked for).

    Raises
    ------
    LfsamError
        If the folder or its manifest is missing or damaged.
    """
    path = Path(path)
    try:
        manifest = json.loads((path / RESULT_MARKER).read_text(encoding="utf-8"))
        if manifest.get("format") != FORMAT:
            raise LfsamError(f"format {manifest.get('format')!r}, not {FORMAT!r}")
        VideoResult(path, manifest)
    except (OSError, LfsamError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise LfsamError(
            f"{str(path)!r} is not a readable video result ({exc}); give the folder written "
            "by `lfsam segment VIDEO --out FOLDER`"
        ) from None
    return VideoResult(path, manifest)
