"""The speed guard (issue 65): the default commands a user runs, timed whole in fresh processes.

Each case is one ``lfsam`` command as a user types it (defaults, nothing tuned), run ``--repeat``
times (default 3) in a fresh Python process, alone; the median wall time is printed beside the
figure recorded in ``docs/performance.md`` (the table between the ``guard:begin`` and
``guard:end`` markers of its section "Speed guard") and flagged ``SLOWER`` when it is more
than ``--tolerance`` (default 15 %) above it. ``--record`` writes the medians measured into that
table (for a change that is meant to change the speed; say so in its note).

Inputs are made once, untimed, in ``--work`` (a synthetic scene, video and rigid-box video of
``lfsam synth``; HCI antinous from ``../shared/data``, skipped with a line when absent):

========================  ==================================================================
case                      command
========================  ==================================================================
disparity-antinous        ``lfsam disparity hci_antinous --out d.npy`` (9x9 views, 512x512)
segment-edgetam           ``lfsam segment scene --point 160,120 --model edgetam
                          --random-weights`` (5x5 views of 240x320, disparity estimated)
segment-hiera-tiny        the same with ``--model sam2.1-hiera-tiny``
live-edgetam              ``lfsam segment clip --point 48,35 --model edgetam --random-weights
                          --refine-views 1`` on an 8-frame 5x5 video of 96x128 (seconds per
                          frame: the tracking's seconds of its summary over its frames)
poses-estimated           ``lfsam poses result --lightfield boxes`` (10 frames of 7x7 views of
                          240x320, 3 boxes, estimated disparity: the defaults)
demo                      ``lfsam demo`` (what ``make demo`` runs)
========================  ==================================================================

Run (alone: two PyTorch processes fight over the cores)::

    python benchmarks/guard.py [--only CASE,CASE] [--repeat 3] [--record]
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PERFORMANCE = ROOT / "docs" / "performance.md"
SHARED = ROOT.parent / "shared" / "data"
LFSAM = [sys.executable, "-m", "lfsam.cli.main"]
BEGIN, END = "<!-- guard:begin -->", "<!-- guard:end -->"


@dataclass(frozen=True)
class Case:
    """One guarded command: its name, its arguments (``{work}`` is the work folder) and what is
    timed: the whole command (``unit="s"``), or with ``unit="s/frame"`` the tracking's own
    seconds that the command prints in its JSON summary (``"seconds"``, start-up and model
    building left out) over its ``"frames"``."""

    name: str
    args: tuple[str, ...]
    unit: str = "s"


CASES = (
    Case("disparity-antinous",
         ("disparity", str(SHARED / "hci_antinous"), "--out", "{work}/out/antinous.npy")),
    Case("segment-edgetam",
         ("segment", "{work}/scene", "--point", "160,120", "--model", "edgetam",
          "--random-weights", "--out", "{work}/out/edgetam.npz")),
    Case("segment-hiera-tiny",
         ("segment", "{work}/scene", "--point", "160,120", "--model", "sam2.1-hiera-tiny",
          "--random-weights", "--out", "{work}/out/tiny.npz")),
    Case("live-edgetam",
         ("segment", "{work}/clip", "--point", "48,35", "--model", "edgetam",
          "--random-weights", "--refine-views", "1", "--out", "{work}/out/clip"),
         unit="s/frame"),
    Case("poses-estimated",
         ("poses", "{work}/boxes_result", "--lightfield", "{work}/boxes", "--json",
          "{work}/out/poses.json")),
    Case("demo", ("demo", "--out", "{work}/out/demo")),
)
#: What each case needs made first (untimed): (the path it makes, the lfsam command).
PREPARE = {
    "segment-edgetam": [("{work}/scene", ("synth", "{work}/scene", "--grid", "5x5", "--size",
                                          "240x320", "--seed", "0"))],
    "live-edgetam": [("{work}/clip", ("synth", "{work}/clip", "--frames", "8", "--grid", "5x5",
                                      "--size", "96x128", "--objects", "3", "--seed", "0"))],
    "poses-estimated": [
        ("{work}/boxes", ("synth", "{work}/boxes", "--rigid", "--seed", "4")),
        ("{work}/boxes_result", ("segment", "{work}/boxes", "--auto", "--model", "oracle",
                                 "--disparity", "gt", "--out", "{work}/boxes_result")),
    ],
}
PREPARE["segment-hiera-tiny"] = PREPARE["segment-edgetam"]


def recorded() -> dict[str, float]:
    """The figures of the table between the markers in docs/performance.md."""
    text = PERFORMANCE.read_text(encoding="utf-8")
    if BEGIN not in text:
        return {}
    block = text.split(BEGIN, 1)[1].split(END, 1)[0]
    out = {}
    for line in block.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 3 and re.fullmatch(r"[\d.]+", cells[2]):
            out[cells[0].strip("`")] = float(cells[2])
    return out


def record(medians: dict[str, tuple[float, str]], command: str) -> None:
    """Write the medians into the table between the markers (the others kept)."""
    figures = {name: (value, "") for name, value in recorded().items()}
    units = {c.name: c.unit for c in CASES}
    figures.update(medians)
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    rows = ["| case | unit | seconds |", "|---|---|---|"]
    rows += [f"| `{name}` | {units.get(name, 's')} | {figures[name][0]:.2f} |"
             for name in (c.name for c in CASES) if name in figures]
    block = "\n".join([BEGIN, f"Recorded {stamp} by `{command}`.", "", *rows, END])
    text = PERFORMANCE.read_text(encoding="utf-8")
    if BEGIN in text:
        head, rest = text.split(BEGIN, 1)
        text = head + block + rest.split(END, 1)[1]
    else:
        text = text.rstrip("\n") + "\n\n## Speed guard (issue 65)\n\n" + block + "\n"
    PERFORMANCE.write_text(text, encoding="utf-8")


def _fill(args, work: Path) -> list[str]:
    return [a.replace("{work}", str(work)) for a in args]


def _call(args: list[str], unit: str = "s") -> float:
    """Run ``lfsam ARGS`` in a fresh process: its wall time, or (``unit="s/frame"``) its
    summary's seconds per frame."""
    env = {**os.environ, "TQDM_DISABLE": "1"}
    start = time.perf_counter()
    done = subprocess.run([*LFSAM, *args], env=env, capture_output=True, text=True, check=False)
    seconds = time.perf_counter() - start
    if done.returncode:
        tail = (done.stderr or "").strip().splitlines()[-3:]
        raise RuntimeError(f"`lfsam {' '.join(args)}` exited {done.returncode}: {tail}")
    if unit == "s/frame":
        summary = json.loads(done.stdout.strip().splitlines()[-1])
        return float(summary["seconds"]) / int(summary["frames"])
    return seconds


def prepare(case: Case, work: Path) -> str | None:
    """Make the case's inputs once; a reason when it cannot run here."""
    if case.name == "disparity-antinous" and not (SHARED / "hci_antinous").is_dir():
        return f"{SHARED / 'hci_antinous'} not found"
    for target, args in PREPARE.get(case.name, []):
        if not Path(target.replace("{work}", str(work))).exists():
            _call(_fill(args, work))
    return None


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", help="comma-separated cases (default: all): "
                        + ", ".join(c.name for c in CASES))
    parser.add_argument("--repeat", type=int, default=3, help="runs per case (median)")
    parser.add_argument("--tolerance", type=float, default=0.15,
                        help="flag a case this much slower than recorded")
    parser.add_argument("--work", default="/tmp/lfsam_guard", help="inputs and outputs")
    parser.add_argument("--record", action="store_true",
                        help="write the medians into docs/performance.md's guard table")
    args = parser.parse_args()
    chosen = CASES
    if args.only:
        names = set(args.only.split(","))
        unknown = names - {c.name for c in CASES}
        if unknown:
            parser.error(f"unknown cases {sorted(unknown)}; choose from "
                         f"{[c.name for c in CASES]}")
        chosen = tuple(c for c in CASES if c.name in names)
    work = Path(args.work)
    (work / "out").mkdir(parents=True, exist_ok=True)
    before = recorded()
    medians: dict[str, tuple[float, str]] = {}
    print(f"load average before: {os.getloadavg()[0]:.2f}; {args.repeat} fresh processes a case")
    print(f"{'case':<20} {'unit':<8} {'runs':<26} {'median':>8} {'recorded':>9} {'ratio':>6}")
    slower = []
    for case in chosen:
        reason = prepare(case, work)
        if reason:
            print(f"{case.name:<20} skipped: {reason}")
            continue
        runs = []
        for _ in range(args.repeat):
            shutil.rmtree(work / "out", ignore_errors=True)
            (work / "out").mkdir(parents=True)
            runs.append(_call(_fill(case.args, work), case.unit))
        median = statistics.median(runs)
        medians[case.name] = (median, case.unit)
        old = before.get(case.name)
        ratio = "" if old is None else f"{median / old:5.2f}x"
        flag = ""
        if old is not None and median > old * (1 + args.tolerance):
            flag = "  SLOWER"
            slower.append(case.name)
        cells = ", ".join(f"{r:.2f}" for r in runs)
        print(f"{case.name:<20} {case.unit:<8} {cells:<26} {median:8.2f} "
              f"{'-' if old is None else f'{old:.2f}':>9} {ratio:>6}{flag}", flush=True)
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    if args.record and medians:
        record(medians, "python benchmarks/guard.py" + (f" --only {args.only}" if args.only
                                                        else ""))
        print(f"recorded in {PERFORMANCE.relative_to(ROOT)}")
    if slower:
        print(f"slower than recorded by more than {args.tolerance:.0%}: {', '.join(slower)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
