"""``lfsam view`` without a display (issue 46): one line naming DISPLAY and ``xvfb-run -a``,
exit 2, before Qt starts (whose xcb plugin would abort the process with exit 134)."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time

import pytest

from lfsam.viewer.display import display_problem

LINUX = "linux"


def _lfsam_view(args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "lfsam.cli.main", "view", *args],
                          capture_output=True, text=True, timeout=60, env=env)


@pytest.mark.parametrize("follow", [False, True])
def test_lfsam_view_without_a_display_exits_2_in_one_line(follow, tmp_path):
    env = {k: v for k, v in os.environ.items()
           if k not in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM")}
    args = [str(tmp_path), "--follow", "--model", "oracle"] if follow else []
    start = time.monotonic()
    proc = _lfsam_view(args, env)
    seconds = time.monotonic() - start
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1, proc.stderr
    assert "DISPLAY" in lines[0] and "xvfb-run -a lfsam view" in lines[0]
    assert seconds < 20


def test_display_problem_reads_the_environment(tmp_path):
    assert display_problem({}, LINUX) == "DISPLAY is not set"
    assert display_problem({}, "darwin") is None
    assert display_problem({"QT_QPA_PLATFORM": "offscreen"}, LINUX) is None
    assert "DISPLAY=:987" in display_problem({"DISPLAY": ":987"}, LINUX)
    assert "nonsense" in display_problem({"DISPLAY": "nonsense"}, LINUX)
    # a Wayland socket in XDG_RUNTIME_DIR is a display; a name with nothing behind it is not
    (tmp_path / "wayland-7").touch()
    env = {"WAYLAND_DISPLAY": "wayland-7", "XDG_RUNTIME_DIR": str(tmp_path)}
    assert display_problem(env, LINUX) is None
    assert display_problem({**env, "WAYLAND_DISPLAY": "wayland-8"}, LINUX) is not None
    assert display_problem({**env, "QT_QPA_PLATFORM": "wayland", "WAYLAND_DISPLAY": "w-9"},
                           LINUX).startswith("the Wayland display")


def test_an_x_server_that_accepts_a_connection_is_a_display():
    """DISPLAY=host:n is TCP port 6000 + n: a listening port there counts, a closed one not."""
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen(1)
        port = server.getsockname()[1]
        assert port > 6000
        display = f"127.0.0.1:{port - 6000}.0"
        assert display_problem({"DISPLAY": display}, LINUX) is None
    assert display_problem({"DISPLAY": display}, LINUX) == f"no X server answers on " \
        f"DISPLAY={display}"
