"""The viewer's "Objects in 3D" dock: the segmented objects as coloured point clouds.

Beside the lfsam dock (:class:`lfsam.viewer.widget.LightFieldWidget`), "Show in 3D" runs
:func:`lfsam.objects3d.objects_in_3d` on the dock's light field and the masks it shows (every
mask layer, the current object over the committed ones over the automatic ones), with the
session's disparity source and the light field's camera or one picked with "Camera…" (a
``--camera`` JSON file, :func:`lfsam.camera.load_camera`). The work runs in a thread of its own,
never in the GUI thread; its answer reaches the GUI thread through a queued Qt signal, as in
:mod:`lfsam.viewer.follow_dock`. The points are drawn in an embedded vispy canvas (a turntable
camera that starts near the center view's camera, turned a little to show depth; drag to turn,
scroll to zoom) and the measures are listed below it (:func:`lfsam.objects3d.format_table`).

Points are in the center view's camera frame (x right, y down, z forward, metres); the canvas
shows camera point ``(x, y, z)`` at vispy's ``(x, z, -y)``, so its up (``+z``) is the image's up.

References
----------
docs/design.md section 11 (objects in 3D: depth from disparity, point clouds, measures).
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
import traceback
from typing import Any

import numpy as np
from qtpy.QtCore import Signal
from qtpy.QtGui import QFontDatabase
from qtpy.QtWidgets import (
    QApplication,
    QCheckBox,
    QHBoxLayout,
    QLabel,
    QPlainTextEdit,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from lfsam.camera import CAMERA_EXAMPLE, Camera, camera_of, load_camera, missing_camera_message
from lfsam.errors import LfsamError
from lfsam.objects3d import Objects3D, format_table, objects_in_3d
from lfsam.result import SegmentationResult
from lfsam.viewer import controls as C
from lfsam.viewer import layers as L
from lfsam.viewer.native_libraries import preload_native_libraries
from lfsam.viz.colors import label_colors

__all__ = ["ObjectsDock"]

#: Marker size on screen, pixels.
POINT_SIZE = 3.0
#: The canvas starts turned this far (azimuth, elevation; degrees) from the center view's camera.
START_TURN = (-20.0, 10.0)
NO_WIDGET = ("open the lfsam widget first (Plugins > lfsam light fields > Segment light field), "
             "then Show in 3D")


class ObjectsDock(QWidget):
    """Show the objects of the lfsam dock's light field as 3D point clouds (module docstring).

    Parameters
    ----------
    napari_viewer : napari.Viewer
    widget : LightFieldWidget, optional
        The lfsam dock; default: the one docked in ``napari_viewer`` (looked for again at each
        "Show in 3D").

    Attributes
    ----------
    found : Objects3D or None
        The objects shown (None before the first, or after a failed, "Show in 3D").
    points_shown : int
        Points in the canvas.
    camera : Camera or None
        The camera picked with "Camera…" (None: the light field's own).
    status : QLabel
    show_button, camera_button : QPushButton
    by_object : QCheckBox
        Colour each object's points with its own colour instead of the pixels' colours.
    canvas : vispy.scene.SceneCanvas
    table : QPlainTextEdit
        The measures (:func:`lfsam.objects3d.format_table`).
    """

    _delivered = Signal(object)

    def __init__(self, napari_viewer: Any, widget: Any = None) -> None:
        super().__init__()
        preload_native_libraries()  # torch before OpenGL draws (native_libraries docstring)
        self.viewer, self.widget = napari_viewer, widget
        self.found: Objects3D | None = None
        self.points_shown = 0
        self.camera: Camera | None = None
        self._thread: threading.Thread | None = None
        self._running, self._rows = False, 1

        self.show_button = QPushButton("Show in 3D")
        self.show_button.setToolTip("the objects of the lfsam dock as point clouds in metres")
        self.camera_button = QPushButton("Camera…")
        self.camera_button.setToolTip(f"a camera JSON file: {CAMERA_EXAMPLE}")
        self.by_object = QCheckBox("colour by object")
        self.status = QLabel()
        self.status.setWordWrap(True)
        self.table = QPlainTextEdit()
        self.table.setReadOnly(True)
        self.table.setLineWrapMode(QPlainTextEdit.LineWrapMode.NoWrap)
        self.table.setFont(QFontDatabase.systemFont(QFontDatabase.SystemFont.FixedFont))
        self.table.setMaximumHeight(160)
        self._make_canvas()

        row = QHBoxLayout()
        for item in (self.show_button, self.camera_button, self.by_object):
            row.addWidget(item)
        layout = QVBoxLayout()
        layout.addLayout(row)
        layout.addWidget(self.status)
        layout.addWidget(self.canvas.native, 1)
        layout.addWidget(self.table)
        self.setLayout(layout)

        self.show_button.clicked.connect(lambda _=False: self.compute())
        self.camera_button.clicked.connect(lambda _=False: self._ask_camera())
        self.by_object.toggled.connect(lambda _on: self._draw())
        self._delivered.connect(self._on_done)  # queued: emitted in the work's thread
        self._set_status("Show in 3D: the segmented objects as point clouds"
                         if self._find_widget() is not None else NO_WIDGET)

    def _make_canvas(self) -> None:
        import qtpy
        from vispy import app, scene

        app.use_app(qtpy.API_NAME)  # napari's backend (napari._vispy does the same)
        self.canvas = scene.SceneCanvas(keys=None, size=(320, 240), bgcolor="black",
                                        show=False, parent=self)
        self.canvas.native.setMinimumHeight(200)
        self.view = self.canvas.central_widget.add_view()
        self.view.camera = scene.TurntableCamera(elevation=0.0, azimuth=0.0, fov=45.0,
                                                 distance=1.0, center=(0.0, 1.0, 0.0))
        self.markers = scene.visuals.Markers(parent=self.view.scene)
        self.markers.visible = False

    # --- the lfsam dock and what it shows -------------------------------------------------------
    def _find_widget(self) -> Any:
        """The lfsam dock: the one given, else the first docked in the viewer (or None)."""
        if self.widget is None:
            from lfsam.viewer.widget import LightFieldWidget

            docked = getattr(getattr(self.viewer, "window", None), "dock_widgets", None) or {}
            self.widget = next((w for w in list(docked.values())
                                if isinstance(w, LightFieldWidget)), None)
        return self.widget

    def _inputs(self) -> tuple[SegmentationResult, Any, Any, Camera]:
        """The labels, light field, disparity source and camera to use (GUI thread).

        Raises
        ------
        LfsamError
            No lfsam dock, no light field, no object, or no camera (one line each).
        """
        widget = self._find_widget()
        if widget is None:
            raise LfsamError(NO_WIDGET)
        session = widget.session
        if session is None or L.COMMITTED not in widget.layers:
            raise LfsamError("no light field: open one in the lfsam dock first")
        labels = widget.masks.composite()
        if not labels.any():
            raise LfsamError("no object yet: click one or Segment everything in the lfsam dock")
        lightfield = session.lightfield
        camera = self.camera or camera_of(lightfield.meta)
        if camera is None:
            raise LfsamError(missing_camera_message(str(lightfield.meta.get(
                "source", "the light field"))) + " (here: the Camera… button)")
        return SegmentationResult(labels=labels), lightfield, session.disparity, camera

    # --- the work -------------------------------------------------------------------------------
    @property
    def running(self) -> bool:
        """Whether "Show in 3D" is being computed."""
        return self._running

    def compute(self, block: bool = False, timeout: float = 120.0) -> None:
        """"Show in 3D": compute the objects in a thread of their own and show them when done;
        ``block``: wait for them (``timeout`` seconds at most) while Qt processes its events
        (tests, scripts). A missing dock, light field, object or camera is said in the status."""
        if self._running:
            self._set_status("still computing the objects in 3D…")
            return
        try:
            result, lightfield, disparity, camera = self._inputs()
        except LfsamError as exc:
            self._fail(str(exc))
            return
        self._running, self._rows = True, lightfield.view_shape[0]
        self.show_button.setEnabled(False)
        what = "estimating the disparity and " if str(disparity) == "estimate" else ""
        self._set_status(f"{what}computing the objects in 3D…")
        self._thread = threading.Thread(
            target=self._run, args=(result, lightfield, disparity, camera),
            name="lfsam-objects3d", daemon=True)
        self._thread.start()
        end = time.monotonic() + timeout
        while block and self._running and time.monotonic() < end:
            QApplication.processEvents()
            time.sleep(0.005)

    def _run(self, result: SegmentationResult, lightfield: Any, disparity: Any,
             camera: Camera) -> None:
        """The work's thread: :func:`objects_in_3d`; its answer or one line goes to the GUI."""
        try:
            answer: Any = objects_in_3d(result, lightfield, disparity=disparity, camera=camera)
        except LfsamError as exc:
            answer = str(exc)
        except BaseException as exc:  # a bug: its traceback on stderr, one line in the dock
            traceback.print_exc()
            answer = f"error: {exc!r}"
        with contextlib.suppress(RuntimeError):  # the dock is gone (the viewer closed)
            self._delivered.emit(answer)

    def _on_done(self, answer: Any) -> None:
        self._running, self._thread = False, None
        self.show_button.setEnabled(True)
        if isinstance(answer, str):
            self._fail(answer)
            return
        self.found = answer
        self._draw(reset=True)
        self.table.setPlainText(format_table(answer))
        cam = answer.camera
        self._set_status(
            f"{len(answer.measures)} object(s), {self.points_shown} points (disparity "
            f"{answer.disparity_source}, f = {cam.focal_px:.1f} px, b = {cam.baseline_m:.4g} m);"
            " drag to turn, scroll to zoom")

    def _fail(self, message: str) -> None:
        self.found = None
        self._draw()
        self.table.setPlainText("")
        self._set_status(message)

    # --- camera file ----------------------------------------------------------------------------
    def set_camera(self, camera: Camera | str | os.PathLike | None) -> None:
        """Use ``camera`` (a Camera or a ``--camera`` JSON path; None: the light field's own)
        from the next "Show in 3D" on; a bad file is said in the status."""
        try:
            self.camera = camera if camera is None or isinstance(camera, Camera) \
                else load_camera(camera)
        except LfsamError as exc:
            self._set_status(str(exc))
            return
        self._set_status("camera: the light field's own" if self.camera is None else
                         f"camera: f = {self.camera.focal_px:.1f} px, b = "
                         f"{self.camera.baseline_m:.4g} m; Show in 3D to use it")

    def _ask_camera(self) -> None:
        path = C.ask_open_file(self, "Camera of the light field (JSON)", "*.json")
        if path:
            self.set_camera(path)

    # --- drawing --------------------------------------------------------------------------------
    def _draw(self, reset: bool = False) -> None:
        """Put the points of :attr:`found` into the canvas (coloured by pixel or by object);
        ``reset``: the camera back at the center view's."""
        clouds = [] if self.found is None else [c for c in self.found.clouds.values()
                                                 if len(c.xyz)]
        self.points_shown = int(sum(len(c.xyz) for c in clouds))
        if not self.points_shown:
            self.markers.visible = False
            self.canvas.update()
            return
        xyz = np.concatenate([c.xyz for c in clouds])
        if self.by_object.isChecked():
            rgb = np.concatenate([np.repeat(label_colors([c.object_id]), len(c.xyz), axis=0)
                                  for c in clouds])
        else:
            rgb = np.concatenate([c.rgb for c in clouds])
        colors = np.concatenate([rgb / 255.0, np.ones((len(rgb), 1))], axis=1)
        shown = np.stack([xyz[:, 0], xyz[:, 2], -xyz[:, 1]], axis=1).astype(np.float32)
        self.markers.set_data(shown, face_color=colors.astype(np.float32), size=POINT_SIZE,
                              edge_width=0)
        self.markers.visible = True
        if reset:
            self._reset_camera(xyz)
        self.canvas.update()

    def _reset_camera(self, xyz: np.ndarray) -> None:
        """Turned :data:`START_TURN` degrees (azimuth, elevation) from the center view's camera
        about the points' median depth, from 1.5 times the camera's distance, with the light field's
        field of view: the scene as the center view sees it, turned enough to show depth."""
        depth = float(np.median(xyz[:, 2]))
        cam = self.view.camera
        (cam.azimuth, cam.elevation), cam.roll = START_TURN, 0.0
        cam.center, cam.distance = (0.0, depth, 0.0), 1.5 * depth
        if self.found is not None:
            half = self._rows / 2 / self.found.camera.focal_px
            cam.fov = float(np.clip(np.degrees(2 * np.arctan(half)), 10.0, 120.0))

    def _set_status(self, text: str) -> None:
        self.status.setText(text)

    def closeEvent(self, event: Any) -> None:
        """Let a running computation finish in the background; close the canvas."""
        self.canvas.close()
        super().closeEvent(event)
