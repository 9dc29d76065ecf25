"""A napari viewer and plugin for light fields: browse the views, click to segment, correct, save.

Issue 15; docs/design.md section 8. The light field is one image layer with the view row and
column ``(s, t)`` as slider dimensions; the widget (:mod:`lfsam.viewer.widget`) drives
:class:`lfsam.predictor.LightFieldPredictor` in a worker thread. The plugin's manifest
(``napari.yaml``) contributes a reader for every light-field format lfsam reads and for lfsam
result files (:mod:`lfsam.viewer.plugin_io`), the dock widget, and a writer for results.

napari is an optional dependency (the ``viewer`` extra): importing this package does not import
it; :func:`require_napari` says how to install it.
"""

from __future__ import annotations

from lfsam.errors import LfsamError

__all__ = ["INSTALL_COMMAND", "require_napari"]

#: The command that installs the viewer's dependencies.
INSTALL_COMMAND = "pip install 'lfsam[viewer]'"


def require_napari() -> None:
    """Check that napari and a Qt binding can be imported.

    Raises
    ------
    LfsamError
        One line naming the command that installs them.
    """
    try:
        import napari  # noqa: F401
        import qtpy.QtWidgets  # noqa: F401
    except Exception as exc:  # ImportError, or qtpy's error when no Qt binding is installed
        missing = getattr(exc, "name", None) or "a Qt binding"
        raise LfsamError(
            f"the viewer needs napari and a Qt binding ({missing} is not installed); "
            f"install them with: {INSTALL_COMMAND}"
        ) from None
