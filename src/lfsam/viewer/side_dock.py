"""What the docks beside the lfsam dock share: finding it, its light field, and work off the GUI
thread.

The "Objects in 3D" dock (:class:`lfsam.viewer.objects3d_dock.ObjectsDock`, docs/design.md
section 11) and the "Render" dock (:class:`lfsam.viewer.render_dock.RenderDock`, docs/design.md
section 13) both work on what the lfsam dock (:class:`lfsam.viewer.widget.LightFieldWidget`)
shows. :class:`SideDock` finds that dock in the viewer, checks it holds a light field, and runs
each computation in a daemon thread of its own: the answer (or one line saying what went wrong)
reaches the GUI thread through a queued Qt signal, and problems are one line in the dock's
status, never a dialog.

References
----------
docs/design.md section 11 (objects in 3D) and section 13 (rendering around objects).
"""

from __future__ import annotations

import contextlib
import threading
import time
import traceback
from typing import Any

from qtpy.QtWidgets import QApplication, QLabel, QPushButton, QWidget

from lfsam.errors import LfsamError
from lfsam.viewer import layers as L
from lfsam.viewer.native_libraries import preload_native_libraries

__all__ = ["NO_LIGHT_FIELD", "SideDock", "no_widget_message", "push_button"]

#: Said when the lfsam dock holds no light field.
NO_LIGHT_FIELD = "no light field: open one in the lfsam dock first"


def no_widget_message(action: str) -> str:
    """The status line of a dock with no lfsam dock in its viewer.

    Parameters
    ----------
    action : str
        What the dock does once the lfsam dock is open (``"render"``, ``"Show in 3D"``).

    Returns
    -------
    str
        One line: how to open the lfsam dock, then ``action``.

    References
    ----------
    docs/design.md sections 11 and 13.
    """
    return ("open the lfsam widget first (Plugins > lfsam light fields > Segment light field), "
            f"then {action}")


def push_button(text: str, tip: str) -> QPushButton:
    """A dock's push button.

    Parameters
    ----------
    text : str
        Its label.
    tip : str
        Its tooltip: what it does.

    Returns
    -------
    QPushButton

    References
    ----------
    docs/design.md sections 11 and 13.
    """
    made = QPushButton(text)
    made.setToolTip(tip)
    return made


class SideDock(QWidget):
    """A dock beside the lfsam dock whose work runs in a thread of its own.

    Subclasses set :attr:`no_widget` and :attr:`thread_name`, make their status label
    :attr:`status`, and say which buttons work disables (:meth:`_enable`).

    Parameters
    ----------
    napari_viewer : napari.Viewer
    widget : LightFieldWidget, optional
        The lfsam dock; default: the one docked in ``napari_viewer`` (looked for again at each
        action until found).

    Attributes
    ----------
    viewer : napari.Viewer
    widget : LightFieldWidget or None
    status : QLabel
        The dock's one-line status (made by the subclass).

    References
    ----------
    docs/design.md section 11 (objects in 3D) and section 13 (rendering around objects).
    """

    #: The status line without an lfsam dock (:func:`no_widget_message`).
    no_widget = no_widget_message("use this dock")
    #: The name of the work's threads.
    thread_name = "lfsam-dock"
    status: QLabel

    def __init__(self, napari_viewer: Any, widget: Any = None) -> None:
        super().__init__()
        preload_native_libraries()  # torch before OpenGL draws (native_libraries docstring)
        self.viewer, self.widget = napari_viewer, widget
        self._thread: threading.Thread | None = None
        self._running = False

    # --- the lfsam dock -------------------------------------------------------------------------
    def _find_widget(self) -> Any:
        """The lfsam dock: the one given, else the first docked in the viewer (or None)."""
        if self.widget is None:
            from lfsam.viewer.widget import LightFieldWidget

            docked = getattr(getattr(self.viewer, "window", None), "dock_widgets", None) or {}
            self.widget = next((w for w in list(docked.values())
                                if isinstance(w, LightFieldWidget)), None)
        return self.widget

    def _session(self) -> tuple[Any, Any]:
        """The lfsam dock and its session, which holds a light field (GUI thread).

        Returns
        -------
        widget : LightFieldWidget
        session : Session

        Raises
        ------
        LfsamError
            No lfsam dock (:attr:`no_widget`) or no light field (:data:`NO_LIGHT_FIELD`).
        """
        widget = self._find_widget()
        if widget is None:
            raise LfsamError(self.no_widget)
        session = widget.session
        if session is None or L.COMMITTED not in widget.layers:
            raise LfsamError(NO_LIGHT_FIELD)
        return widget, session

    # --- the work, in its own thread ------------------------------------------------------------
    @property
    def running(self) -> bool:
        """Whether the dock's work is under way."""
        return self._running

    def _still_running(self) -> bool:
        """Whether work is under way (then the status asks to wait for it)."""
        if self._running:
            self._set_status("still computing; wait for it to finish")
        return self._running

    def _start(self, work: Any, signal: Any, status: str, block: bool, timeout: float) -> None:
        """Run ``work()`` in a daemon thread; its answer goes to the GUI thread by ``signal``.

        Parameters
        ----------
        work : callable
            Called without arguments in the work's thread.
        signal : Signal
            A signal of the dock, connected (queued) to what takes the answer; that calls
            :meth:`_finish`.
        status : str
            The status line meanwhile.
        block : bool
            Wait until the answer came (``timeout`` seconds at most) while Qt processes its
            events (tests, scripts).
        timeout : float
        """
        self._running = True
        self._enable(False)
        self._set_status(status)
        self._thread = threading.Thread(target=self._run, args=(work, signal),
                                        name=self.thread_name, daemon=True)
        self._thread.start()
        end = time.monotonic() + timeout
        while block and self._running and time.monotonic() < end:
            QApplication.processEvents()
            time.sleep(0.005)

    def _run(self, work: Any, signal: Any) -> None:
        """The work's thread: ``work()``; its answer or one line goes to the GUI by ``signal``.

        An :class:`LfsamError` gives its message, an :class:`OSError` "could not write: ...",
        anything else (a bug) its traceback on stderr and "error: ..." in the dock.
        """
        try:
            answer: Any = work()
        except LfsamError as exc:
            answer = str(exc)
        except OSError as exc:
            answer = f"could not write: {exc}"
        except BaseException as exc:  # a bug: its traceback on stderr, one line in the dock
            traceback.print_exc()
            answer = f"error: {exc!r}"
        with contextlib.suppress(RuntimeError):  # the dock is gone (the viewer closed)
            signal.emit(answer)

    def _finish(self) -> None:
        """The work is done (GUI thread): the buttons work again."""
        self._running, self._thread = False, None
        self._enable(True)

    def _enable(self, on: bool) -> None:
        """Enable (``on``) or disable the buttons that start work; each dock says which."""
        raise NotImplementedError

    def _set_status(self, text: str) -> None:
        self.status.setText(text)
