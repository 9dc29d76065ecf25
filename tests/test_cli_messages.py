"""One-line messages of the `lfsam` command: a cache folder that cannot be made is an error
before any work, and warnings are one plain line each (``lfsam: warning: MESSAGE``)."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

import lfsam
import lfsam.cli.segment as segment_command
from lfsam.cli.main import main, plain_warnings
from lfsam.errors import LfsamError
from lfsam.fileutil import check_cache_dir
from lfsam.io import write_lightfield
from lfsam.synth import generate_scene

ORACLE_WARNING = (
    "lfsam: warning: oracle embeddings are not cached on disk (nothing to save: it does not "
    "run an image encoder)"
)


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    path = tmp_path_factory.mktemp("scene") / "scene"
    write_lightfield(generate_scene(grid=(3, 3), size=(24, 32), seed=2, num_objects=2), path)
    return path


def _segment(scene, out, cache, *extra):
    return ["segment", str(scene), "--auto", "--model", "oracle", "--disparity", "gt",
            "--out", str(out), "--cache", str(cache), *extra]


# --- --cache ----------------------------------------------------------------------------------
def test_check_cache_dir_creates_missing_folders(tmp_path):
    folder = tmp_path / "a" / "b"
    assert check_cache_dir(folder) == folder and folder.is_dir()
    assert check_cache_dir(str(folder)) == folder  # an existing folder is fine


@pytest.mark.parametrize("where", ["file", "under_file"])
def test_check_cache_dir_refuses_in_one_line(tmp_path, where):
    blocker = tmp_path / "blocker"
    blocker.write_text("not a folder")
    folder = blocker if where == "file" else blocker / "cache"
    with pytest.raises(LfsamError) as info:
        check_cache_dir(folder)
    message = str(info.value)
    assert "\n" not in message and repr(str(folder)) in message and "--cache" in message


@pytest.mark.parametrize(
    "cache", ["blocker/cache", "blocker"] + (["/proc/nope"] if Path("/proc").is_dir() else [])
)
def test_segment_with_an_unusable_cache_fails_before_reading(
    scene, tmp_path, monkeypatch, capsys, cache
):
    (tmp_path / "blocker").write_text("not a folder")
    cache = cache if cache.startswith("/") else str(tmp_path / cache)

    def no_reading(*args, **kwargs):
        raise AssertionError("the light field was read before --cache was checked")

    monkeypatch.setattr(segment_command, "read_lightfield", no_reading)
    out = tmp_path / "r.npz"
    assert main(_segment(scene, out, cache, "--quiet")) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("lfsam: error:"), err
    assert repr(cache) in err[0] and "Traceback" not in err[0]
    assert not out.exists()


def test_segment_creates_a_missing_cache_folder(scene, tmp_path, capsys):
    cache = tmp_path / "new" / "cache"
    assert main(_segment(scene, tmp_path / "r.npz", cache, "--quiet")) == 0
    assert cache.is_dir() and (tmp_path / "r.npz").is_file()


# --- warnings ---------------------------------------------------------------------------------
def test_plain_warnings_prints_one_line_and_restores(capsys):
    before = warnings.showwarning
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        with plain_warnings():
            warnings.warn("a first line\n  and a second", UserWarning, stacklevel=1)
            warnings.warn("another", RuntimeWarning, stacklevel=1)
        assert warnings.showwarning is before
    err = capsys.readouterr().err.splitlines()
    assert err == ["lfsam: warning: a first line and a second", "lfsam: warning: another"]


def test_main_restores_showwarning(scene, tmp_path, capsys):
    before = warnings.showwarning
    main(["info", str(scene)])
    assert warnings.showwarning is before


def test_a_warning_of_a_command_is_one_plain_line(scene, tmp_path):
    """In a fresh process as a user runs it: --cache with the oracle (no encoder to cache) warns
    once, as one line without Python's file:line, category and source line."""
    src = str(Path(lfsam.__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([src, os.environ.get("PYTHONPATH", "")])}
    env.pop("PYTHONWARNINGS", None)
    out = tmp_path / "r.npz"
    proc = subprocess.run(
        [sys.executable, "-m", "lfsam.cli.main", *_segment(scene, out, tmp_path / "c", "--quiet")],
        capture_output=True, text=True, timeout=300, env=env,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.splitlines() == [ORACLE_WARNING]
    assert out.is_file()
