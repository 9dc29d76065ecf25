"""The plugin's reader and writer: light fields and lfsam results as napari layers.

Layer data are returned as napari "layer data tuples" ``(data, kwargs, layer_type)``, which need
no napari import. The light field is ONE image layer: the ``(S, T, U, V, 3)`` uint8 views with
``rgb=True``, so ``s`` and ``t`` become slider dimensions and no view is copied. Its metadata
keeps the :class:`~lfsam.lightfield.LightField` (``metadata["lfsam_lightfield"]``) for the
widget. A light-field video is one lazy RGB image layer ``(F, S, T, U, V, 3)`` with a ``frame``
slider (:func:`lfsam.viewer.video.video_layers`; section 10). A result is a labels layer
``(S, T, U, V)`` with the result in its metadata
(``metadata["lfsam_result"]``) so the widget can reopen its objects. docs/design.md sections 1
and 8.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField

__all__ = [
    "LayerData",
    "get_reader",
    "is_result_file",
    "lightfield_layers",
    "read_path",
    "result_layers",
    "write_result",
]

LayerData = tuple[Any, dict[str, Any], str]

#: Metadata keys the widget looks for.
LIGHTFIELD_KEY = "lfsam_lightfield"
RESULT_KEY = "lfsam_result"
SESSION_KEY = "lfsam_session"


def is_result_file(path: str | os.PathLike) -> bool:
    """Whether ``path`` is an ``.npz`` holding a result (``labels``, no ``views``)."""
    path = Path(path)
    if path.suffix.lower() != ".npz" or not path.is_file():
        return False
    try:
        with np.load(path, allow_pickle=False) as npz:
            keys = set(npz.files)
    except Exception:  # not a readable zip: not ours to read
        return False
    return "labels" in keys and "views" not in keys


def lightfield_layers(lightfield: LightField, name: str | None = None) -> list[LayerData]:
    """Layers for a light field: the views (one RGB image layer) and any full ground truth.

    Parameters
    ----------
    lightfield : LightField
        The light field; its ``views`` array is the layer's data (not copied).
    name : str, optional
        Layer name; default the source's file name.

    Returns
    -------
    list of (data, kwargs, "image" | "labels")
        The image layer, then (hidden) ground-truth labels when every view has them.
    """
    source = lightfield.meta.get("source")
    name = name or (Path(str(source)).name if source else "light field")
    layers: list[LayerData] = [
        (
            lightfield.views,
            {
                "name": name,
                "rgb": True,
                "axis_labels": ("s", "t", "u", "v"),
                "metadata": {LIGHTFIELD_KEY: lightfield},
            },
            "image",
        )
    ]
    if lightfield.has_full_labels:
        layers.append(
            (lightfield.labels, {"name": f"{name} ground truth", "visible": False}, "labels")
        )
    return layers


def result_layers(result: Any, name: str = "result") -> list[LayerData]:
    """A result's label field as a labels layer, the result kept in its metadata; a video
    result folder's ``(F, S, T, U, V)`` labels are read one frame at a time (section 10)."""
    labels = result.labels
    kwargs: dict[str, Any] = {"name": name, "metadata": {RESULT_KEY: result}}
    if getattr(result, "num_frames", None) is not None:  # a VideoResult
        from lfsam.viewer.video import VIDEO_AXES, FrameStore

        labels = FrameStore(result.shape)
        labels.attach_result(result)
        kwargs["axis_labels"] = VIDEO_AXES
    return [(labels, kwargs, "labels")]


def read_path(path: str | os.PathLike) -> list[LayerData]:
    """Layers for a light field (any format lfsam reads) or an lfsam result file.

    Raises
    ------
    LfsamError
        If the path holds neither.
    """
    from lfsam.io import read_lightfield
    from lfsam.result import load_result
    from lfsam.video import is_video, read_video
    from lfsam.video.io.result import is_video_result, load_video_result
    from lfsam.viewer.video import video_layers

    path = Path(path)
    if is_result_file(path):
        return result_layers(load_result(path), name=path.stem)
    if is_video_result(path):
        return result_layers(load_video_result(path), name=path.name)
    if is_video(path):
        return video_layers(read_video(path))
    return lightfield_layers(read_lightfield(path))


def get_reader(path: str | list[str]) -> Callable[[Any], list[LayerData]] | None:
    """npe2 reader: a function that reads ``path``, or None if it is not a light field or result.

    Detection is cheap (``lfsam.io.detect_format`` looks at names and headers); read errors
    appear as napari notifications with lfsam's one-line message.
    """
    from lfsam.io import detect_format
    from lfsam.video import is_video
    from lfsam.video.io.result import is_video_result

    if isinstance(path, (list, tuple)):
        if len(path) != 1:
            return None
        path = path[0]
    if not (is_result_file(path) or is_video_result(path) or is_video(path)):
        try:
            detect_format(path)
        except LfsamError:
            return None
    return _notifying_reader


def _notifying_reader(path: str | list[str]) -> list[LayerData]:
    if isinstance(path, (list, tuple)):
        path = path[0]
    try:
        return read_path(path)
    except LfsamError as exc:
        from napari.utils.notifications import show_error

        show_error(str(exc))
        return []


def write_result(path: str, data: Any, attributes: dict[str, Any]) -> list[str]:
    """npe2 writer: a labels layer as an lfsam result ``.npz``.

    The widget's "committed objects" layer carries its session in its metadata: then the
    session's result is written (prompts included, so it reopens editable). Any other labels
    layer ``(S, T, U, V)`` is written as a result holding just its labels.

    Returns
    -------
    list of str
        The written path.
    """
    from lfsam.fileutil import check_output_path
    from lfsam.result import SegmentationResult, save_result

    metadata = attributes.get("metadata") or {}
    session = metadata.get(SESSION_KEY)
    try:
        if session is not None:
            return [str(session.save(path))]
        if getattr(data, "ndim", 0) == 5:
            raise LfsamError(
                "this labels layer is a light-field video's; save it from the lfsam dock "
                "(Track, then Save result) to write the video result folder"
            )
        labels = np.asarray(data)
        if labels.ndim != 4:
            raise LfsamError(
                f"an lfsam result needs labels of shape (S, T, U, V), this layer has "
                f"{labels.shape}; save a labels layer of a light field"
            )
        check_output_path(path)
        previous = metadata.get(RESULT_KEY)
        meta = dict(previous.meta) if previous is not None else {}
        meta.setdefault("source", "napari labels layer")
        result = SegmentationResult(labels=labels.astype(np.int32), meta=meta)
        return [str(save_result(result, path))]
    except LfsamError as exc:
        from napari.utils.notifications import show_error

        show_error(str(exc))
        return []
