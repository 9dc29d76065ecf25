"""The viewer's "Objects in 3D" dock: the segmented objects as coloured point clouds.

Beside the lfsam dock (:class:`lfsam.viewer.widget.LightFieldWidget`), "Show in 3D" runs
:func:`lfsam.objects3d.objects_in_3d` on the dock's light field and the masks it shows (every
mask layer, the current object over the committed ones over the automatic ones), with the
session's disparity source and the light field's camera or one picked with "Camera…" (a
``--camera`` JSON file, :func:`lfsam.camera.load_camera`). The work runs in a thread of its own,
never in the GUI thread; its answer reaches the GUI thread through a queued Qt signal, as in
:mod:`lfsam.viewer.side_dock`. The points are drawn in an embedded vispy canvas (a turntable
camera that starts near the center view's camera, turned a little to show depth; drag to turn,
scroll to zoom) and the measures are listed below it (:func:`lfsam.objects3d.format_table`).

"Poses" runs :class:`lfsam.poses.VideoPoses` (what :func:`lfsam.poses.poses_of_video` runs) on
the masks the lfsam dock shows, in the same thread of its own: over every frame of a light-field
video (the masks of a track, or any shown frame by frame), or on the single light field (each
object's first pose), with the session's disparity source (``estimate``: the center and corner
views' points, 5 estimates per frame with the estimator's light settings, as ``lfsam poses``)
and the same camera. Each object's pose axes at the frame
on the ``frame`` slider (red, green, blue: its x, y, z) and its path (the pose's origins over the
frames it was found in) are drawn with the points; moving the slider moves the axes
(:mod:`lfsam.viewer.pose_visuals`).

Points are in the center view's camera frame (x right, y down, z forward, metres); the canvas
shows camera point ``(x, y, z)`` at vispy's ``(x, z, -y)``, so its up (``+z``) is the image's up.

References
----------
docs/design.md section 11 (objects in 3D: depth from disparity, point clouds, measures) and
section 12 (6D poses).
"""

from __future__ import annotations

import contextlib
import os
from functools import partial
from typing import Any

import numpy as np
from qtpy.QtCore import Signal
from qtpy.QtGui import QFontDatabase
from qtpy.QtWidgets import (
    QCheckBox,
    QHBoxLayout,
    QLabel,
    QPlainTextEdit,
    QVBoxLayout,
)

from lfsam.camera import CAMERA_EXAMPLE, Camera, camera_of, load_camera, missing_camera_message
from lfsam.errors import LfsamError
from lfsam.objects3d import Objects3D, format_table, objects_in_3d
from lfsam.poses import ObjectPoses, VideoPoses
from lfsam.result import SegmentationResult
from lfsam.viewer import controls as C
from lfsam.viewer import pose_visuals as PV
from lfsam.viewer.side_dock import SideDock, no_widget_message, push_button
from lfsam.viz.colors import label_colors

__all__ = ["ObjectsDock"]

#: Marker size on screen, pixels.
POINT_SIZE = 3.0
#: The canvas starts turned this far (azimuth, elevation; degrees) from the center view's camera.
START_TURN = (-20.0, 10.0)
NO_WIDGET = no_widget_message("Show in 3D")


class ObjectsDock(SideDock):
    """Show the objects of the lfsam dock's light field as 3D point clouds (module docstring).

    Made from the viewer and, optionally, the lfsam dock whose masks it shows, as
    :class:`lfsam.viewer.side_dock.SideDock` is.

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
    poses : list of ObjectPoses or None
        The objects' poses of the last "Poses" (None before, or after a failed one).
    pose_lengths : dict of int to ndarray
        Each object's axis lengths, metres (:func:`lfsam.viewer.pose_visuals.axis_lengths`).
    pose_frame : int
        The frame whose poses the axes show.
    axes_vertices : ndarray, shape (6 K, 3)
        The axes drawn, in the camera frame (:func:`lfsam.viewer.pose_visuals.frame_axes`).
    poses_button : QPushButton
    """

    no_widget = NO_WIDGET
    thread_name = "lfsam-objects3d"
    _delivered = Signal(object)
    _posed = Signal(object)
    _progress = Signal(str)

    def __init__(self, napari_viewer: Any, widget: Any = None) -> None:
        super().__init__(napari_viewer, widget)
        self.found: Objects3D | None = None
        self.points_shown = 0
        self.camera: Camera | None = None
        self._rows = 1
        self.poses: list[ObjectPoses] | None = None
        self.pose_lengths: dict[int, np.ndarray] = {}
        self.pose_frame = 0
        self.axes_vertices = np.zeros((0, 3))

        self.show_button = push_button(
            "Show in 3D", "the objects of the lfsam dock as point clouds in metres")
        self.poses_button = push_button(
            "Poses", "each object's 6D pose over the video's frames: its axes at the frame shown "
            "and its path")
        self.camera_button = push_button("Camera…", f"a camera JSON file: {CAMERA_EXAMPLE}")
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
        for item in (self.show_button, self.poses_button, self.camera_button, self.by_object):
            row.addWidget(item)
        layout = QVBoxLayout()
        layout.addLayout(row)
        layout.addWidget(self.status)
        layout.addWidget(self.canvas.native, 1)
        layout.addWidget(self.table)
        self.setLayout(layout)

        self.show_button.clicked.connect(lambda _=False: self.compute())
        self.poses_button.clicked.connect(lambda _=False: self.compute_poses())
        self.camera_button.clicked.connect(lambda _=False: self._ask_camera())
        self.by_object.toggled.connect(lambda _on: self._draw())
        self._delivered.connect(self._on_done)  # queued: emitted in the work's thread
        self._posed.connect(self._on_poses)
        self._progress.connect(self._set_status)
        dims = getattr(napari_viewer, "dims", None)
        if dims is not None:
            dims.events.current_step.connect(self._on_step)
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
        self.paths = scene.visuals.Line(parent=self.view.scene, width=2.0, antialias=False)
        self.axes = scene.visuals.Line(parent=self.view.scene, width=3.0, antialias=False)
        self.paths.visible = self.axes.visible = False

    # --- the lfsam dock and what it shows -------------------------------------------------------
    def _source(self) -> tuple[Any, Any, Camera]:
        """The lfsam dock, its session and the camera to use (GUI thread).

        Raises
        ------
        LfsamError
            No lfsam dock, no light field or no camera (one line each).
        """
        widget, session = self._session()
        lightfield = session.lightfield
        camera = self.camera or camera_of(lightfield.meta)
        if camera is None:
            raise LfsamError(missing_camera_message(str(lightfield.meta.get(
                "source", "the light field"))) + " (here: the Camera… button)")
        return widget, session, camera

    def _inputs(self) -> tuple[SegmentationResult, Any, Any, Camera]:
        """The labels, light field, disparity source and camera to use (GUI thread).

        Raises
        ------
        LfsamError
            No lfsam dock, no light field, no object, or no camera (one line each).
        """
        widget, session, camera = self._source()
        labels = widget.masks.composite()
        if not labels.any():
            raise LfsamError("no object yet: click one or Segment everything in the lfsam dock")
        return SegmentationResult(labels=labels), session.lightfield, session.disparity, camera

    def _pose_inputs(self) -> tuple[int, Any, Any, Any, Camera, str]:
        """What "Poses" registers (GUI thread): the number of frames, the labels and the light
        field of frame k (functions, read in the work's thread: a video's frames are read one
        at a time), the disparity source, the camera and the views whose points count.

        Raises
        ------
        LfsamError
            As :meth:`_source`, or while the lfsam dock is busy (its track writes the masks).
        """
        widget, session, camera = self._source()
        if widget.busy:
            raise LfsamError("the lfsam dock is busy (tracking or segmenting): Poses when it is "
                             "done")
        disparity = session.disparity
        views = "corners" if isinstance(disparity, str) and disparity == "estimate" else "all"
        if getattr(widget, "is_video", False):
            return (session.video.num_frames, widget.masks.composite_at, session.video.frame,
                    disparity, camera, views)
        labels, lightfield = widget.masks.composite(), session.lightfield
        return 1, lambda _k: labels, lambda _k: lightfield, disparity, camera, views

    # --- the work (:class:`SideDock`; :attr:`running`: "Show in 3D" or "Poses") -----------------
    def compute(self, block: bool = False, timeout: float = 120.0) -> None:
        """"Show in 3D": compute the objects in a thread of their own and show them when done;
        ``block``: wait for them (``timeout`` seconds at most) while Qt processes its events
        (tests, scripts). A missing dock, light field, object or camera is said in the status."""
        if self._still_running():
            return
        try:
            result, lightfield, disparity, camera = self._inputs()
        except LfsamError as exc:
            self._fail(str(exc))
            return
        self._rows = lightfield.view_shape[0]
        what = "estimating the disparity and " if str(disparity) == "estimate" else ""
        work = partial(objects_in_3d, result, lightfield, disparity=disparity, camera=camera)
        self._start(work, self._delivered, f"{what}computing the objects in 3D…", block, timeout)

    def compute_poses(self, block: bool = False, timeout: float = 120.0) -> None:
        """"Poses": every object's pose over the video's frames (or the single light field's),
        in a thread of its own (module docstring); then its axes at the frame shown and its path
        are drawn. ``block`` and ``timeout`` as :meth:`compute`; problems are said in the
        status."""
        if self._still_running():
            return
        try:
            count, labels_at, lightfield_at, disparity, camera, views = self._pose_inputs()
        except LfsamError as exc:
            self._set_status(str(exc))
            return
        self._rows = self.widget.session.lightfield.view_shape[0]
        what = "estimating the disparity and " if str(disparity) == "estimate" else ""
        work = partial(self._poses_work, count, labels_at, lightfield_at, disparity, camera,
                       views)
        self._start(work, self._posed, f"{what}registering the objects' poses over {count} "
                    "frame(s)…", block, timeout)

    def _enable(self, on: bool) -> None:
        self.show_button.setEnabled(on)
        self.poses_button.setEnabled(on)

    def _poses_work(self, count: int, labels_at: Any, lightfield_at: Any, disparity: Any,
                    camera: Camera, views: str) -> tuple:
        """The work's thread: :class:`VideoPoses` over the frames; the objects' poses, their
        axis lengths, the camera and the number of frames."""
        session = VideoPoses(disparity=disparity, camera=camera, views=views)
        for index in range(count):
            session.add(SegmentationResult(labels=labels_at(index)), lightfield_at(index))
            with contextlib.suppress(RuntimeError):
                self._progress.emit(f"poses: frame {index + 1} of {count} registered…")
        session.finish()
        if not session.objects:
            raise LfsamError("no object to pose: click one, Segment everything or Track in the "
                             "lfsam dock first")
        lengths = {obj.object_id: PV.axis_lengths(session.tracker.model_points(obj.object_id),
                                                  obj.first_pose)
                   for obj in session.objects}
        return session.objects, lengths, session.camera, count

    def _on_done(self, answer: Any) -> None:
        self._finish()
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

    def _on_poses(self, answer: Any) -> None:
        self._finish()
        if isinstance(answer, str):
            self.poses, self.pose_lengths = None, {}
            self._draw_poses()
            self._set_status(answer)
            return
        self.poses, self.pose_lengths, camera, count = answer
        self._draw_poses(camera if self.found is None else None)
        lost = sum(f.status == "lost" for obj in self.poses for f in obj.frames)
        uncertain = sum(f.status == "uncertain" for obj in self.poses for f in obj.frames)
        self._set_status(
            f"poses of {len(self.poses)} object(s) over {count} frame(s)"
            + (f" ({lost} lost object-frame(s))" if lost else "")
            + (f" ({uncertain} uncertain object-frame(s))" if uncertain else "")
            + f"; axes at frame {self.pose_frame} (x red, y green, z blue) and paths: move the "
            "frame slider to move them")

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
        self.markers.set_data(PV.to_canvas(xyz), face_color=colors.astype(np.float32),
                              size=POINT_SIZE, edge_width=0)
        self.markers.visible = True
        if reset:
            self._reset_camera(xyz, self.found.camera)
        self.canvas.update()

    def _draw_poses(self, reset: Camera | None = None) -> None:
        """Draw the paths of :attr:`poses` (each object's colour) and their axes at the frame
        shown; ``reset``: the canvas' camera about the paths, with this light-field camera's
        field of view."""
        objects = self.poses or []
        paths = [PV.path_points([f.frame for f in obj.frames], [f.pose for f in obj.frames])
                 for obj in objects]
        vertices, connect, owner = PV.path_segments(paths)
        if len(connect):
            ids = np.array([obj.object_id for obj in objects])[owner]
            colors = np.concatenate([label_colors(ids) / 255.0, np.ones((len(ids), 1))], axis=1)
            self.paths.set_data(pos=PV.to_canvas(vertices), color=colors.astype(np.float32),
                                connect=connect)
        self.paths.visible = bool(len(connect))
        if reset is not None and len(vertices):
            self._reset_camera(vertices, reset)
        self.set_frame(self._shown_frame())

    def set_frame(self, frame: int) -> None:
        """Draw each object's axes at ``frame`` (the ``frame`` slider calls it; objects lost
        there or not yet seen show none)."""
        self.pose_frame = int(frame)
        tracks = [([f.frame for f in obj.frames], [f.pose for f in obj.frames],
                   self.pose_lengths[obj.object_id]) for obj in self.poses or []]
        vertices, colors, _ = PV.frame_axes(tracks, self.pose_frame)
        self.axes_vertices = vertices
        if len(vertices):
            self.axes.set_data(pos=PV.to_canvas(vertices), color=colors.astype(np.float32),
                               connect="segments")
        self.axes.visible = bool(len(vertices))
        self.canvas.update()

    def _shown_frame(self) -> int:
        """The frame on the lfsam dock's ``frame`` slider (0 for a single light field)."""
        widget = self.widget
        return widget.shown_frame() if getattr(widget, "is_video", False) else 0

    def _on_step(self, _event: Any = None) -> None:
        if self.poses is not None:
            with contextlib.suppress(RuntimeError):  # the dock's Qt object is gone
                frame = self._shown_frame()
                if frame != self.pose_frame:
                    self.set_frame(frame)

    def _reset_camera(self, xyz: np.ndarray, camera: Camera) -> None:
        """Turned :data:`START_TURN` degrees (azimuth, elevation) from the center view's camera
        about the points' median depth, from 1.5 times the camera's distance, with the light field's
        field of view: the scene as the center view sees it, turned enough to show depth."""
        depth = float(np.median(xyz[:, 2]))
        cam = self.view.camera
        (cam.azimuth, cam.elevation), cam.roll = START_TURN, 0.0
        cam.center, cam.distance = (0.0, depth, 0.0), 1.5 * depth
        half = self._rows / 2 / camera.focal_px
        cam.fov = float(np.clip(np.degrees(2 * np.arctan(half)), 10.0, 120.0))

    def closeEvent(self, event: Any) -> None:
        """Let a running computation finish in the background; close the canvas."""
        dims = getattr(self.viewer, "dims", None)
        if dims is not None:
            with contextlib.suppress(TypeError, ValueError, RuntimeError):
                dims.events.current_step.disconnect(self._on_step)
        self.canvas.close()
        super().closeEvent(event)
