"""The CUDA batch path (issue 18): these run only on a CUDA GPU (`make gpu-check`).

Checks that the GPU path computes what the CPU path computes: batched bf16 encoding against one
view at a time and against float32 on the CPU (cosine similarity of the embeddings, since bf16
autocast changes the last bits), the whole pipeline with the oracle on CUDA against the CPU, and
the GPU benchmark script end to end at a tiny size.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from lfsam.api import ModelOptions, RunOptions, SegmentOptions, segment
from lfsam.segmenters import load_segmenter
from lfsam.synth import generate_scene

pytestmark = pytest.mark.cuda

BENCH_GPU = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_gpu.py"


def _cosine(a: torch.Tensor, b: torch.Tensor) -> float:
    a, b = a.float().flatten().cpu(), b.float().flatten().cpu()
    return float(torch.dot(a, b) / (a.norm() * b.norm()))


def _levels(embedding) -> list[torch.Tensor]:
    return [embedding.data.image_embed, *embedding.data.high_res_feats]


def test_batched_cuda_encoding_matches_single_views_and_cpu():
    lf = generate_scene(grid=(2, 2), size=(48, 64), seed=0, num_objects=3)
    views = lf.views.reshape(-1, 48, 64, 3)
    gpu = load_segmenter("sam2-tiny-test", random_weights=True, device="cuda")
    cpu = load_segmenter("sam2-tiny-test", random_weights=True, device="cpu")
    gpu.encode_batch_size = 4
    batched = gpu.encode(views)
    gpu.encode_batch_size = 1
    single = gpu.encode(views)
    reference = cpu.encode(views)
    for b, s, r in zip(batched, single, reference, strict=True):
        for level_b, level_s, level_r in zip(_levels(b), _levels(s), _levels(r), strict=True):
            assert level_b.device.type == "cuda"
            assert level_b.shape == level_r.shape
            assert _cosine(level_b, level_s) > 0.999
            assert _cosine(level_b, level_r) > 0.99


def test_oracle_pipeline_on_cuda_matches_cpu():
    lf = generate_scene(grid=(3, 3), size=(48, 64), seed=1, num_objects=4)
    cpu, gpu = (
        segment(lf, disparity="gt", options=SegmentOptions(
            model=ModelOptions(name="oracle", device=device), run=RunOptions(progress=False)))
        for device in ("cpu", "cuda")
    )
    assert gpu.num_masks == cpu.num_masks > 0
    agree = float(np.mean(np.asarray(gpu.labels) == np.asarray(cpu.labels)))
    assert agree > 0.999, f"CUDA and CPU labels agree on only {agree:.4%} of the pixels"


def test_bench_gpu_runs_on_cuda():
    run = subprocess.run(
        [sys.executable, str(BENCH_GPU), "--model", "sam2-tiny-test", "--grid", "3x3",
         "--size", "48x64", "--prompts", "4", "--baseline-objects", "2", "--repeats", "1",
         "--cases", "none"],
        capture_output=True, text=True, timeout=600,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    assert "on cuda" in run.stdout
    assert "GiB" in run.stdout.split("peak GPU memory, LFSAM")[1].splitlines()[0]


def test_bench_gpu_realtime_cases_run_on_cuda(tmp_path):
    """Issue 44's cases (one click, the live stream with --latest) at the smoke size on CUDA,
    with the profile's counts and the JSON."""
    import json

    out = tmp_path / "gpu.json"
    run = subprocess.run(
        [sys.executable, str(BENCH_GPU), "--smoke", "--profile", "--json", str(out)],
        capture_output=True, text=True, timeout=600,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    numbers = json.loads(out.read_text())
    assert numbers["device"].startswith("cuda")
    assert numbers["paper"]["profile"]["kernel_launches"] > 0
    assert numbers["click_sparse"]["profile"]["kernel_launches"] > 0
    assert numbers["stream"]["frames_processed"] >= 1
