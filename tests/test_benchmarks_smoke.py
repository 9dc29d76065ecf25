"""The benchmark scripts run end to end (tiny settings): `make bench` must not rot unnoticed.

The numbers they print at tiny sizes mean nothing; each case checks only that the script exits
cleanly and prints its headline line. The real runs are `make bench` (README, "Development").
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"

CASES = {
    "bench_gpu.py": (
        ["--device", "cpu", "--model", "sam2-tiny-test", "--grid", "3x3", "--size", "32x48",
         "--prompts", "2", "--baseline-objects", "1", "--no-estimate"],
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
        ["--size", "48x64", "--timing-size", "48x64", "--no-real"], "occlusion-aware on 9x9"
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
        ["--parts", "speed,memory,stream", "--grid", "3x3", "--size", "24x32", "--frames", "2",
         "--models", "oracle", "--settings", "all", "--memory-frames", "2,3",
         "--memory-model", "oracle", "--stream-runs", "sam2-tiny-test:memory",
         "--stream-size", "32x40", "--stream-frames", "2", "--rate", "20"],
        "targets: edgetam >= 1 frame/s",
    ),
    "bench_consensus.py": (
        ["--seeds", "1", "--hidden", "0", "--size", "32x48", "--answers", "exact",
         "--cost-model", "sam2-tiny-test"],
        "target: ratio <= 1.15",
    ),
    "bench_objects3d.py": (
        ["--scenes", "1", "--size", "48x64", "--parts", "synthetic"],
        "| median depth relative error |",
    ),
    "bench_references.py": (
        ["--model", "sam2-tiny-test", "--answers", "oracle", "--points-per-side", "16",
         "--grid", "3x3", "--size", "48x64", "--modes", "corners", "--rounds", "1",
         "--quality-size", "64x96", "--quality-seeds", "0", "--hidden", "1"],
        "| corners |",
    ),
}


@pytest.mark.parametrize("script", sorted(CASES))
def test_benchmark_script_runs(script):
    args, expected = CASES[script]
    run = subprocess.run(
        [sys.executable, str(BENCHMARKS / script), *args],
        capture_output=True, text=True, timeout=300,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    assert expected in run.stdout
