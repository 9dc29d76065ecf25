"""Frames landing in a followed folder, for the live-stream tests (tests/test_video_follow.py,
tests/test_viewer_follow.py, tests/test_viewer_edges.py; docs/design.md section 10)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path


def frame_folders(source: Path) -> list[Path]:
    """The frame folders of a written video (``frame_0000/`` ...), in order."""
    return sorted(p for p in Path(source).iterdir() if p.is_dir())


def land_frame(frame: Path, folder: Path) -> None:
    """Land a frame the way a camera writer should: written under a hidden name, renamed in."""
    hidden = Path(folder) / f".{frame.name}.part"
    shutil.copytree(frame, hidden)
    os.rename(hidden, Path(folder) / frame.name)
