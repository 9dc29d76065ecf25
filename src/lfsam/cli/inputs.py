"""The kinds of input each command takes, checked before anything is read.

Commands take four kinds of input: a light field, a light-field video, a segmentation result
(``.npz``) and a video's result folder. :func:`lfsam.video.io.detect.input_kind` tells them apart
from names and headers. Given one in the wrong role (a video where a result belongs, a result
where a light field belongs, ...), a command fails with one line that names what it was given
and what it takes, instead of a reader's complaint about an array's shape
(docs/design.md section 2, "Outputs and inputs on the command line"):

- :func:`expect_input` checks a command's input against the kinds the command takes;
- :func:`expect_partner` checks the light field given with a result (``metrics --gt``,
  ``export --lightfield``, ``show --lightfield``): a light field for a result, a light-field
  video for a video's result folder;
- :func:`expect_dataset` checks the data set of ``lfsam evaluate``: a folder of scenes, not
  one light field, video or result.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Collection
from pathlib import Path

import numpy as np

from lfsam.errors import LfsamError
from lfsam.video.io.detect import input_kind, video_kind
from lfsam.video.io.frames_folder import VIDEO_MARKER
from lfsam.video.io.result import RESULT_MARKER

__all__ = ["GIVEN", "TAKES", "expect_dataset", "expect_input", "expect_partner"]

#: What a path of each kind is, in the error line: "clip.npz is a light-field video".
GIVEN = {
    "lightfield": "a light field",
    "video": "a light-field video",
    "result": "a segmentation result",
    "video-result": "a light-field video's result folder",
}

#: What a command takes, by kind, in the error line: "lfsam metrics takes a result .npz".
TAKES = {
    "result": "a result .npz",
    "video-result": "a video result folder",
    "lightfield": "a light field (a folder of views or an .npz/.npy/.h5/.mat file)",
    "video": "a light-field video (a folder of frames, of view_SS_TT.mp4 files, or an "
    "[F, S, T, U, V, 3] array)",
}

#: The light field that goes with each kind of result.
PARTNER = {"result": "lightfield", "video-result": "video"}


def _recorded_input(path: str | os.PathLike, kind: str) -> str | None:
    """The input a result records (``meta["input"]``), if it can be read cheaply."""
    try:
        if kind == "result":
            with np.load(path, allow_pickle=False) as npz:
                meta = json.loads(str(npz["meta"])) if "meta" in npz.files else {}
        else:
            manifest = json.loads((Path(path) / RESULT_MARKER).read_text(encoding="utf-8"))
            meta = manifest.get("meta", {})
    except Exception:  # damaged or foreign files: no hint, the check still names the kind
        return None
    value = meta.get("input") if isinstance(meta, dict) else None
    return value if isinstance(value, str) and value else None


def _hint(path: str | os.PathLike, given: str, accepted: Collection[str]) -> str:
    """What to do instead, for an input of kind ``given`` where ``accepted`` belong."""
    if given in ("lightfield", "video") and not {"lightfield", "video"} & set(accepted):
        out = "RESULT.npz" if given == "lightfield" else "RESULT_FOLDER"
        return f"segment it first: lfsam segment {path} --auto --out {out}"
    if given in ("result", "video-result"):
        source = _recorded_input(path, given)
        return f"it was computed on {source}" if source else "give what it was computed on"
    if given == "video":
        return "give a single light field, e.g. one of its frames"
    return "give a light-field video"


def expect_input(
    path: str | os.PathLike | None,
    command: str,
    accepted: Collection[str],
    *,
    option: str | None = None,
    hint: str | None = None,
) -> str | None:
    """Check that ``path`` is of a kind ``command`` takes; return its kind.

    Parameters
    ----------
    path : path-like or None
        The input (None: not given, nothing to check).
    command : str
        The subcommand, e.g. ``"metrics"``.
    accepted : collection of str
        Kinds of :data:`lfsam.video.io.detect.INPUT_KINDS` the command takes here.
    option : str, optional
        The option that names the input (``"--gt"``); None for the positional input.
    hint : str, optional
        What to do instead; default a hint by the kind given.

    Returns
    -------
    str or None
        The kind; None for a missing path or one of no known kind (its reader then says what
        is wrong with it).

    Raises
    ------
    LfsamError
        One line: "VIDEO.npz is a light-field video; lfsam metrics takes a result .npz or a
        video result folder; segment it first: ...".
    """
    if path is None:
        return None
    kind = input_kind(path)
    if kind is None or kind in accepted:
        return kind
    takes = [TAKES[k] for k in ("result", "video-result", "lightfield", "video") if k in accepted]
    wanted = takes[0] if len(takes) == 1 else ", ".join(takes[:-1]) + " or " + takes[-1]
    where = f"lfsam {command}" + (f" {option}" if option else "")
    raise LfsamError(
        f"{path} is {GIVEN[kind]}; {where} takes {wanted}; "
        f"{hint or _hint(path, kind, accepted)}"
    )


def expect_partner(
    path: str | os.PathLike | None,
    result: str | os.PathLike,
    result_kind: str | None,
    command: str,
    option: str,
) -> str | None:
    """Check that ``path`` is the kind of light field the result ``result`` (of kind
    ``result_kind``, from :func:`expect_input`) goes with: a light field for a result, a
    light-field video for a video's result folder.

    Raises
    ------
    LfsamError
        As :func:`expect_input`; the hint names the input the result records.

    A result that is missing (``result_kind`` None) has no partner to check: its reader says
    what is wrong with it, rather than a line about the partner.
    """
    if result_kind is None and not Path(result).exists():
        return None
    result_kind = result_kind if result_kind in PARTNER else "result"
    partner = PARTNER[result_kind]
    source = _recorded_input(result, result_kind)
    hint = (f"give the {GIVEN[partner][2:]} {result} was computed on"
            + (f" (recorded: {source})" if source else ""))
    return expect_input(path, command, (partner,), option=option, hint=hint)


def expect_dataset(path: str | os.PathLike | None) -> None:
    """Check that ``path`` is a folder of scenes (``lfsam evaluate DATASET_DIR``), not a single
    light field, a light-field video of its own (a folder with ``lfsam_video.json`` or
    ``view_SS_TT.mp4`` files), a result or a video's result folder.

    A folder of sub-folders and light-field files is both a data set and a video's folder of
    frames (:func:`lfsam.video.io.detect.video_kind`); without the video marker it is a data set.

    Raises
    ------
    LfsamError
        One line naming what ``path`` is.
    """
    if path is None:
        return
    kind = input_kind(path)
    if kind is None or (kind == "video" and video_kind(path) == "frames"
                        and not (Path(path) / VIDEO_MARKER).is_file()):
        return
    raise LfsamError(
        f"{path} is {GIVEN[kind]}; lfsam evaluate takes a folder of scenes (one light field or "
        "light-field video per sub-folder or file, with ground truth); put it in a folder of "
        "its own and give that folder"
        + ("" if kind in ("lightfield", "video") else ", or score it with lfsam metrics")
    )


@contextlib.contextmanager
def video_with_result(result_path: str | os.PathLike, video_path: str | os.PathLike):
    """Open a video's result folder and its light-field video together, checked to match:
    yields ``(VideoResult, LightFieldVideo)``.

    Raises
    ------
    LfsamError
        One line when the result's labels and the video differ in shape.
    """
    from lfsam.video import read_video
    from lfsam.video.io.result import load_video_result

    result = load_video_result(result_path)
    with read_video(video_path) as video:
        if tuple(video.shape) != tuple(result.shape):
            raise LfsamError(f"{result_path} has labels {result.shape}, {video_path} is a "
                             f"video of {tuple(video.shape)}")
        yield result, video
