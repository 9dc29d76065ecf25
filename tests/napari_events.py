"""Helpers of the viewer tests: lfsam's napari plugin registered as an installed package's entry
point registers it, the mouse events napari's callbacks read, and the start of the scripts the
fresh-process tests run (docs/design.md section 8)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def register_plugin() -> None:
    """Our npe2 manifest, as its entry point registers it in an installed package."""
    import npe2

    manager = npe2.PluginManager.instance()
    manager.discover()
    if "lfsam" not in manager._manifests:
        from importlib.resources import files

        manager.register(npe2.PluginManifest.from_file(files("lfsam.viewer") / "napari.yaml"))


@dataclass
class MouseEvent:
    """The fields napari's mouse callbacks read from a vispy mouse event; ``dims_displayed``
    are the image axes shown (the last two of the layer)."""

    type: str
    position: tuple
    modifiers: list = field(default_factory=list)
    is_dragging: bool = False
    pos: np.ndarray = field(default_factory=lambda: np.zeros(2))
    view_direction: list | None = None
    up_direction: list | None = None
    dims_displayed: list = field(default_factory=lambda: [2, 3])


#: The start of a fresh-process viewer script: ``wait(condition, what)`` lets Qt process events
#: (draws included) until ``condition()`` holds, or exits naming ``what``.
WAIT_PRELUDE = """
import json, sys, time
from qtpy.QtWidgets import QApplication

def wait(condition, what, timeout=200):
    end = time.monotonic() + timeout
    while not condition():
        QApplication.processEvents()
        time.sleep(0.01)
        if time.monotonic() > end:
            sys.exit(f"timed out waiting for {what}")
"""
