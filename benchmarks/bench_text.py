"""SAM 3's concept detector on a CPU (issue 26; docs/design.md section 9).

Builds ``sam3`` at full size with random weights (untrained: for timing only; the architecture
and the work per view are those of ``facebook/sam3``) and times :meth:`detect` on one view of
``--size`` (default 480x640, a view of the paper's UrbanLF-Syn): the first call (cold) and, when
``--repeats`` > 1, the fastest of the further calls. Prints the parameter count, build seconds,
seconds per reference view, the peak resident memory, and the detector's share of a 9x9 run
whose other work took ``--run-seconds`` (default 230.06 s: docs/performance.md, "CPU: where the
time goes", SAM 2.1 Hiera-S over 9x9 views of 240x320). Text prompts run the detector once per
phrase and reference view, so that share is per phrase.

Usage::

    PYTHONPATH=src python benchmarks/bench_text.py [--size 480x640] [--repeats 2]
        [--model sam3] [--run-seconds 230.06]
"""

from __future__ import annotations

import argparse
import json
import resource
import time

import numpy as np
import torch


def main() -> None:
    from lfsam.segmenters.text import load_text_detector

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="480x640")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--model", default="sam3")
    parser.add_argument("--run-seconds", type=float, default=230.06)
    args = parser.parse_args()
    rows, cols = (int(x) for x in args.size.split("x"))
    image = np.random.default_rng(0).integers(0, 256, (rows, cols, 3), dtype=np.uint8)
    start = time.perf_counter()
    detector = load_text_detector(args.model, random_weights=True, device="cpu")
    build = time.perf_counter() - start
    params = sum(p.numel() for p in detector.model.parameters())
    times = []
    for _ in range(max(1, args.repeats)):
        start = time.perf_counter()
        found = detector.detect(image, "red cup", threshold=0.0)
        times.append(time.perf_counter() - start)
    per_view = min(times[1:]) if len(times) > 1 else times[0]
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps({
        "model": args.model,
        "params": params,
        "threads": torch.get_num_threads(),
        "build_s": round(build, 2),
        "view": [rows, cols],
        "detect_s": [round(t, 2) for t in times],
        "seconds_per_reference_view": round(per_view, 2),
        "instances_at_threshold_0": len(found),
        "peak_rss_mb": round(peak_mb),
        "share_of_9x9_run": round(per_view / (per_view + args.run_seconds), 3),
    }))


if __name__ == "__main__":
    main()
