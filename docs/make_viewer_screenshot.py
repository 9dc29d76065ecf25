"""Take docs/viewer.png: the napari viewer with a segmented synthetic light field.

Run under a virtual X display from the repo root (napari needs OpenGL, which Qt's offscreen
platform lacks)::

    xvfb-run -a -s "-screen 0 1600x1000x24" .venv/bin/python docs/make_viewer_screenshot.py

The window is laid out as ``lfsam view`` lays it out (:func:`lfsam.viewer.layout.lay_out`).

It opens a synthetic 5x5 light field, runs "segment everything" with the oracle and ground-truth
disparity, clicks one object in a corner view the way a user does (through the points layer's
mouse callbacks), waits for the worker, moves the sliders to that view and saves the window.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from napari.utils._proxies import ReadOnlyWrapper
from napari.utils.interactions import mouse_press_callbacks, mouse_release_callbacks
from qtpy.QtWidgets import QApplication
from scipy import ndimage

from lfsam.synth import generate_scene
from lfsam.viewer import layers as L


class _Click:
    def __init__(self, kind: str, position: tuple) -> None:
        self.type, self.position, self.modifiers = kind, position, []
        self.is_dragging, self.pos = False, np.zeros(2)
        self.view_direction = self.up_direction = None
        self.dims_displayed = [2, 3]


def _wait(widget, timeout: float = 300.0) -> None:
    end = time.time() + timeout
    while not widget.work.idle and time.time() < end:
        QApplication.processEvents()
        time.sleep(0.02)
    for _ in range(20):
        QApplication.processEvents()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(Path(__file__).with_name("viewer.png")))
    args = parser.parse_args()

    import napari

    from lfsam.viewer.layout import lay_out
    from lfsam.viewer.objects3d_dock import ObjectsDock
    from lfsam.viewer.widget import LightFieldWidget

    lf = generate_scene(
        grid=(5, 5), size=(240, 320), seed=3, num_objects=5, label_background=False
    )
    viewer = napari.Viewer(title="lfsam view", show=True)
    widget = LightFieldWidget(viewer, lightfield=lf, model="oracle", disparity="gt")
    dock = viewer.window.add_dock_widget(widget, name="lfsam", area="right")
    viewer.window.add_dock_widget(ObjectsDock(viewer, widget), name="lfsam 3D", area="right",
                                  tabify=True)
    lay_out(viewer, dock)  # as `lfsam view` opens it: the screen's size, the canvas largest
    _wait(widget)
    widget.segment_everything()
    _wait(widget)
    # click the largest non-background object of a corner view, as the current object
    view = (0, 4)
    labels = lf.labels[view]
    ids, areas = np.unique(labels[labels > 0], return_counts=True)
    target = ids[areas.argmax()]
    dist = ndimage.distance_transform_edt(labels == target)
    pixel = np.unravel_index(dist.argmax(), dist.shape)
    viewer.dims.current_step = (*view, *viewer.dims.current_step[2:])
    points = widget.layers[L.POINTS]
    for kind, dispatch in (("mouse_press", mouse_press_callbacks),
                           ("mouse_release", mouse_release_callbacks)):
        event = _Click(kind, (*view, *(float(p) for p in pixel)))
        dispatch(points, ReadOnlyWrapper(event, exceptions=("handled",)))
    _wait(widget)
    viewer.layers.selection.active = points
    viewer.reset_view()
    _wait(widget)
    from napari._qt.dialogs.qt_notification import NapariQtNotification

    for toast in viewer.window._qt_window.findChildren(NapariQtNotification):
        toast.close()  # e.g. napari's notice about the Qt binding
    _wait(widget)
    viewer.screenshot(args.out, canvas_only=False, flash=False)
    print(f"wrote {args.out}")
    viewer.close()


if __name__ == "__main__":
    main()
