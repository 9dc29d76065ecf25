"""The benchmark scripts run end to end (tiny settings): `make bench` must not rot unnoticed.

The numbers they print at tiny sizes mean nothing; each case checks only that the script exits
cleanly and prints its headline line. The real runs are `make bench` (README, "Development").

Each script runs in the test's own process, as ``python SCRIPT ARGS`` would run it (``runpy``
with ``__main__``, its arguments in ``sys.argv``, its folder on ``sys.path``): a fresh process
paid 4-10 s of imports the test worker has already made (issue 65, `make test` in ten minutes).
The torch thread count a script sets is put back after it.
"""

from __future__ import annotations

import runpy
import sys
from pathlib import Path

import pytest
import torch

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"

CASES = {
    "bench_gpu.py": (
        ["--device", "cpu", "--model", "sam2-tiny-test", "--grid", "3x3", "--size", "32x48",
         "--prompts", "2", "--baseline-objects", "1", "--no-estimate", "--cases", "none"],
        "ratio baseline / LFSAM",
    ),
    "bench_speed.py": (
        ["--grid", "3x3", "--size", "32x48", "--prompts", "2", "--models", "sam2-tiny-test",
         "--starts", "center,first"],
        "summary (T in ms per mask per view)",
    ),
    "bench_pipeline.py": (
        ["--parts", "speed", "--model", "sam2-tiny-test", "--grid", "3x3", "--size", "32x48",
         "--prompts", "2"],
        "total / encoder alone",
    ),
    "bench_decoder.py": (
        ["--model", "sam2-tiny-test", "--size", "32x48", "--prompts", "4", "--repeats", "1",
         "--chunks", "1,2"],
        "max |low-res logits - Meta batched|",
    ),
    "bench_disparity.py": (
        ["--size", "48x64", "--timing-size", "48x64", "--no-real", "--glass-grid", "5x5",
         "--glass-size", "64x96"], "occlusion-aware on 9x9"
    ),
    "bench_metrics.py": (["--grid", "3x3", "--size", "64x96", "--masks", "5"], "bench_metrics:"),
    "bench_interactive.py": (
        ["--model", "sam2-tiny-test", "--grid", "3x3", "--size", "48x64", "--objects", "3",
         "--repeats", "1"],
        "edit / single-object run",
    ),
    "bench_text.py": (
        ["--model", "sam3-tiny-test", "--size", "32x48", "--repeats", "1"],
        "seconds_per_reference_view",
    ),
    "bench_sparse.py": (
        ["--seeds", "1", "--hidden", "0", "--size", "32x48", "--settings", "all,sparse",
         "--disparities", "gt",
         "--model", "sam2-tiny-test", "--prompts", "3"],
        "sparse speed-up over all",
    ),
    "bench_video.py": (
        ["--parts", "speed,memory,stream,latest,write", "--grid", "3x3", "--size", "24x32",
         "--frames", "2", "--models", "oracle", "--settings", "all", "--memory-frames", "2,3",
         "--memory-model", "oracle", "--stream-runs", "sam2-tiny-test:memory",
         "--stream-size", "32x40", "--stream-frames", "2", "--rate", "20",
         "--latest-frames", "6", "--latest-grid", "3x3", "--latest-size", "24x32",
         "--write-size", "24x32", "--write-repeats", "1", "--write-frames", "4",
         "--write-rate", "20"],
        "target: with --latest the 95th-percentile latency under 2 frame times",
    ),
    "bench_tracking.py": (
        ["--seeds", "1", "--frames", "3", "--grid", "3x3", "--size", "48x64", "--objects", "3",
         "--jitter", "0", "--min-pixels", "20", "--consensus", "both", "--stages", "--ops"],
        ("stage ms/frame (mean over runs) | ",
         "operators a frame (one untimed run) | operators | waits | ratio\nsearch jitter 0 | "),
    ),
    "bench_consensus.py": (
        ["--seeds", "1", "--hidden", "0", "--size", "32x48", "--grid", "3x3",
         "--answers", "exact", "--cost-model", "sam2-tiny-test"],
        "target: ratio <= 1.15",
    ),
    "bench_objects3d.py": (
        ["--scenes", "1", "--size", "48x64", "--parts", "synthetic"],
        "| median depth relative error |",
    ),
    "bench_render.py": (
        ["--seeds", "7", "--size", "64x96", "--speed-size", "64x64", "--repeats", "1"],
        ("| seed | object | see-through dB |", "| refocus s | see-through s | remove s |"),
    ),
    "bench_references.py": (
        ["--model", "sam2-tiny-test", "--answers", "oracle", "--points-per-side", "16",
         "--grid", "3x3", "--size", "48x64", "--modes", "corners", "--rounds", "1",
         "--quality-size", "64x96", "--quality-seeds", "0", "--hidden", "1"],
        "| corners |",
    ),
}


def run_script(script: str, args: list[str], capsys, monkeypatch) -> str:
    """Run ``benchmarks/SCRIPT ARGS`` here as its own ``__main__``; its standard output, after
    asserting that it ended without an error (no exception, exit status 0)."""
    path = BENCHMARKS / script
    monkeypatch.setattr(sys, "argv", [str(path), *args])
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    threads = torch.get_num_threads()
    capsys.readouterr()
    try:
        runpy.run_path(str(path), run_name="__main__")
    except SystemExit as exc:
        assert exc.code in (None, 0), capsys.readouterr().err[-2000:]
    finally:
        torch.set_num_threads(threads)
    return capsys.readouterr().out


@pytest.mark.parametrize("script", sorted(CASES))
def test_benchmark_script_runs(script, capsys, monkeypatch):
    args, expected = CASES[script]
    out = run_script(script, args, capsys, monkeypatch)
    for line in (expected,) if isinstance(expected, str) else expected:
        assert line in out


def test_bench_gpu_smoke_runs_every_case_and_writes_json(tmp_path, capsys, monkeypatch):
    """bench_gpu.py --smoke (issue 44): the paper's setting, one click (sparse and all views)
    and the live stream with --latest (ground-truth and estimated disparity) at a tiny size
    with the tiny models, on the CPU, every number written as JSON."""
    import json

    out = tmp_path / "gpu.json"
    stdout = run_script("bench_gpu.py", ["--device", "cpu", "--smoke", "--profile",
                                         "--no-baseline", "--json", str(out)], capsys, monkeypatch)
    numbers = json.loads(out.read_text())
    assert numbers["paper"]["total_s"] > 0 and "kernel_launches" in numbers["paper"]["profile"]
    for click in ("click_sparse", "click_all"):
        assert numbers[click]["seconds"] > 0 and numbers[click]["views_encoded"] >= 1
    for stream in ("stream", "stream_estimate"):
        got = numbers[stream]
        assert got["frames_processed"] >= 1 and got["tracking"] == "edgetam-memory"
        assert got["frames_processed"] + got["skipped"] == got["frames_arrived"]
        assert got["latency_p95_s"] > 0
        assert got["write_median_s"] > 0 and got["disk_latency_p95_s"] > 0  # written behind
    assert numbers["targets"]["stream_per_second"] == 30
    assert "| live stream, estimate disparity, --latest |" in stdout
