"""How ``lfsam view`` lays out its window: the image canvas the largest part (issue 46).

napari opens a window of its own default size with docks at their preferred widths; with the
lfsam dock and the "lfsam 3D" dock on the right and napari's layer docks on the left, a
1600 x 1000 screen left the image canvas about 240 pixels of a 1090-pixel window, and the 3D
tab, added last, in front. :func:`lay_out` fixes that once the window is shown: the window
takes the screen's available area, the lfsam dock is in front of the docks tabbed with it, and
every dock of the right and left areas is as narrow as its contents allow (its
``minimumSizeHint``), so the canvas gets the rest.
"""

from __future__ import annotations

import contextlib
from typing import Any

from qtpy.QtCore import Qt, QTimer
from qtpy.QtWidgets import QApplication, QDockWidget, QMainWindow

__all__ = ["canvas_share", "lay_out"]


def _window(viewer: Any) -> QMainWindow:
    return viewer.window._qt_window


def lay_out(viewer: Any, front: QDockWidget) -> None:
    """Size the window to the screen, put ``front`` in front of its tabs, narrow the docks.

    Parameters
    ----------
    viewer : napari.Viewer
        Shown or not (the sizes apply when it shows).
    front : QDockWidget
        The dock that goes in front of the docks tabbed with it (the lfsam dock).
    """
    window = _window(viewer)
    screen = window.screen() or QApplication.primaryScreen()
    if screen is not None:
        window.setGeometry(screen.availableGeometry())
    docks = [d for d in window.findChildren(QDockWidget)
             if d.isVisible() and not d.isFloating() and d.widget() is not None
             and window.dockWidgetArea(d) in (Qt.DockWidgetArea.LeftDockWidgetArea,
                                              Qt.DockWidgetArea.RightDockWidgetArea)]
    widths = [max(d.widget().minimumSizeHint().width(), d.minimumSizeHint().width())
              for d in docks]
    if docks:
        window.resizeDocks(docks, widths, Qt.Orientation.Horizontal)
    front.raise_()
    # napari tabifies and sizes docks from its event loop: once more when it has run
    QTimer.singleShot(0, lambda: _again(window, docks, widths, front))


def _again(window: QMainWindow, docks: list[QDockWidget], widths: list[int],
           front: QDockWidget) -> None:
    with contextlib.suppress(RuntimeError):  # the window closed meanwhile
        window.resizeDocks(docks, widths, Qt.Orientation.Horizontal)
        front.raise_()


def canvas_share(viewer: Any) -> float:
    """The image canvas's width as a share of the window's."""
    canvas = viewer.window._qt_viewer.canvas.native
    return canvas.width() / max(_window(viewer).width(), 1)
