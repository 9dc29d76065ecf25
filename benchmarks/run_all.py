"""Run every benchmark (``make bench``), each in its own process, printing its numbers."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
# Cheapest first; each script prints its own table.
SCRIPTS = [
    "bench_metrics.py",
    "bench_disparity.py",
    "bench_objects3d.py",
    "bench_decoder.py",
    "bench_pipeline.py",
    "bench_speed.py",
    "bench_interactive.py",
    "bench_references.py",
    "bench_render.py",
]


def main() -> int:
    failed = []
    for name in SCRIPTS:
        script = HERE / name
        if not script.exists():
            print(f"== {name}: missing", flush=True)
            failed.append(name)
            continue
        print(f"\n== {name}", flush=True)
        start = time.perf_counter()
        code = subprocess.call([sys.executable, str(script), *sys.argv[1:2]])
        print(f"== {name}: exit {code}, {time.perf_counter() - start:.0f} s", flush=True)
        if code:
            failed.append(name)
    if failed:
        print(f"\nfailed: {', '.join(failed)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
