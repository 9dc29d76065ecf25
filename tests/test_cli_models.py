"""``lfsam models`` and the shared segmenter options of the CLI."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import pytest

from lfsam.cli.main import main
from lfsam.cli.models import add_model_arguments, parse_option, segmenter_from_args
from lfsam.errors import LfsamError
from lfsam.segmenters.registry import MODELS
from lfsam.segmenters.sam2.backend import Sam2Segmenter


@pytest.fixture
def offline_hub(tmp_path, monkeypatch) -> Path:
    home = tmp_path / "hf"
    home.mkdir()
    monkeypatch.setenv("HF_HOME", str(home))
    monkeypatch.setenv("HF_HUB_CACHE", str(home / "hub"))
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    return home


def _fake_cached(home: Path, repo: str, filename: str) -> Path:
    root = home / "hub" / f"models--facebook--{repo}"
    (root / "refs").mkdir(parents=True)
    (root / "refs" / "main").write_text("c0ffee")
    (root / "snapshots" / "c0ffee").mkdir(parents=True)
    path = root / "snapshots" / "c0ffee" / filename
    path.write_bytes(b"x")
    return path


def test_models_lists_every_name_and_cache_state(offline_hub, capsys):
    cached = _fake_cached(offline_hub, "sam2.1-hiera-tiny", "sam2.1_hiera_tiny.pt")
    assert main(["models"]) == 0
    out = capsys.readouterr().out
    for name in [*MODELS, "oracle"]:
        assert name in out
    line = {ln.split()[0]: ln for ln in out.splitlines() if ln.strip()}
    assert "cached" in line["sam2.1-hiera-tiny"] and "not cached" not in line["sam2.1-hiera-tiny"]
    assert "not cached" in line["sam2.1-hiera-small"]
    assert "random only" in line["sam2-tiny-test"]
    assert "46.1 M" in line["sam2.1-hiera-small"]
    assert "Device: cpu" in out or "Device: cuda" in out or "Device: mps" in out

    assert main(["models", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    rows = {row["name"]: row for row in info["models"]}
    assert rows["sam2.1-hiera-tiny"]["cached"] == str(cached)
    assert rows["sam2.1-hiera-small"]["cached"] is None and rows["sam2.1-hiera-small"]["default"]
    assert rows["sam2.1-hiera-large"]["params"] == MODELS["sam2.1-hiera-large"].params
    assert info["cache"] == str(offline_hub / "hub")


def test_download_offline_is_one_line_error_without_traceback(offline_hub, capsys):
    start = time.perf_counter()
    assert main(["models", "--download", "sam2.1-hiera-small"]) == 2
    assert time.perf_counter() - start < 2.0
    err = capsys.readouterr().err
    assert err.startswith("lfsam: error: no cached weights for sam2.1-hiera-small")
    assert err.count("\n") == 1 and "Traceback" not in err
    assert not any(p.is_file() for p in offline_hub.rglob("*"))


def test_download_uses_the_cache(offline_hub, capsys):
    cached = _fake_cached(offline_hub, "sam2-hiera-small", "sam2_hiera_small.pt")
    assert main(["models", "--download", "sam2-hiera-small"]) == 0
    assert str(cached) in capsys.readouterr().out


def _parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_model_arguments(parser)
    return parser.parse_args(argv)


def test_segmenter_options_build_the_asked_model():
    args = _parse(["--model", "sam2-tiny-test", "--device", "cpu", "--amg", "points_per_side=4"])
    seg = segmenter_from_args(args)
    assert isinstance(seg, Sam2Segmenter)
    assert seg.amg_options["points_per_side"] == 4
    assert seg.amg_options["pred_iou_thresh"] == 0.88  # the paper's value stays


def test_segmenter_options_offline_error(offline_hub):
    args = _parse([])  # the paper's model by default
    assert args.model == "sam2.1-hiera-small"
    start = time.perf_counter()
    with pytest.raises(LfsamError, match=r"no cached weights for sam2\.1-hiera-small"):
        segmenter_from_args(args)
    assert time.perf_counter() - start < 2.0


def test_parse_option():
    assert parse_option("points_per_side=32") == ("points_per_side", 32)
    assert parse_option("pred_iou_thresh=0.5") == ("pred_iou_thresh", 0.5)
    assert parse_option("use_m2m=True") == ("use_m2m", True)
    with pytest.raises(argparse.ArgumentTypeError):
        parse_option("points_per_side")


def test_help_has_an_example(capsys):
    with pytest.raises(SystemExit):
        main(["models", "--help"])
    assert "lfsam models --download" in capsys.readouterr().out


@pytest.mark.parametrize("name", ["sam2.1-hiera-small", "edgetam"])
def test_download_checks_the_cache_takes_files_before_any_download(offline_hub, monkeypatch,
                                                                   capsys, name):
    """A cache that cannot be written is named in one line before the hub is asked (the
    offline hub would give another message)."""
    blocker = offline_hub / "a-file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("HF_HUB_CACHE", str(blocker / "hub"))
    assert main(["models", "--download", name]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Hugging Face cache" in err and "HF_HUB_CACHE" in err
    assert "no cached weights" not in err

