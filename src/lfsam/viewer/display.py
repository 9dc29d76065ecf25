"""Is there a display to open the viewer on? Checked before Qt starts (issue 46).

Without one, Qt's xcb plugin aborts the whole process (exit 134, seven lines about plugins and
nothing about what to do). :func:`check_display` looks first, without Qt and in well under a
second: on Linux and the BSDs a window needs ``WAYLAND_DISPLAY`` naming a Wayland socket that
exists, or ``DISPLAY`` naming an X server that accepts a connection (its Unix socket
``/tmp/.X11-unix/X<n>``, or TCP port 6000 + n on another host). A platform chosen with
``QT_QPA_PLATFORM`` other than ``xcb`` / ``wayland`` (``offscreen``, ``vnc``, ``eglfs``, ...)
is the user's choice and is not second-guessed; macOS and Windows always have a display.
"""

from __future__ import annotations

import os
import socket
import sys
from pathlib import Path

from lfsam.errors import LfsamError

__all__ = ["check_display", "display_problem"]

#: Seconds to wait for an X server's TCP port.
CONNECT_TIMEOUT = 1.0


def _x_server_answers(display: str) -> bool:
    """Whether the X server named by ``display`` (``[host]:n[.screen]``) accepts a connection."""
    host, _, rest = display.rpartition(":")
    number = rest.split(".", 1)[0]
    if not number.isdigit():
        return False
    host = host.removeprefix("unix/")
    try:
        if host in ("", "unix"):
            with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
                sock.settimeout(CONNECT_TIMEOUT)
                path = f"/tmp/.X11-unix/X{number}"
                if Path(path).exists():
                    sock.connect(path)
                    return True
                sock.connect(f"\0{path}")  # Linux's abstract socket (no file)
                return True
        with socket.create_connection((host, 6000 + int(number)), timeout=CONNECT_TIMEOUT):
            return True
    except OSError:
        return False


def _wayland_answers(name: str, env: dict[str, str]) -> bool:
    path = Path(name) if os.path.isabs(name) else Path(
        env.get("XDG_RUNTIME_DIR", f"/run/user/{os.getuid()}")) / name
    return path.exists()


def display_problem(environ: dict[str, str] | None = None,
                    platform: str | None = None) -> str | None:
    """Why no window can open here (a short phrase), or None when one can.

    Parameters
    ----------
    environ : dict, optional
        The environment to judge (default ``os.environ``).
    platform : str, optional
        ``sys.platform`` (default: this one).
    """
    env = dict(os.environ) if environ is None else environ
    platform = sys.platform if platform is None else platform
    if platform.startswith(("darwin", "win", "cygwin")):
        return None
    qpa = env.get("QT_QPA_PLATFORM", "").split(":", 1)[0].split(";", 1)[0].strip()
    if qpa and qpa not in ("xcb", "wayland", "wayland-egl"):
        return None
    wayland, x11 = env.get("WAYLAND_DISPLAY", ""), env.get("DISPLAY", "")
    if qpa != "xcb" and wayland and _wayland_answers(wayland, env):
        return None
    if qpa.startswith("wayland"):
        return f"the Wayland display {wayland or '(WAYLAND_DISPLAY unset)'} does not answer"
    if x11 and _x_server_answers(x11):
        return None
    if x11:
        return f"no X server answers on DISPLAY={x11}"
    return "DISPLAY is not set"


def check_display(command: str = "lfsam view ...") -> None:
    """Check that a window can open before Qt starts.

    Parameters
    ----------
    command : str
        The command to suggest under ``xvfb-run -a``.

    Raises
    ------
    LfsamError
        One line naming ``DISPLAY`` and ``xvfb-run -a <command>``.
    """
    problem = display_problem()
    if problem is not None:
        raise LfsamError(
            f"no display to open the viewer on ({problem}); on a machine without a screen "
            f"(SSH, a server) run it on a virtual one: xvfb-run -a {command}, or log in with "
            "ssh -X so DISPLAY is set")
