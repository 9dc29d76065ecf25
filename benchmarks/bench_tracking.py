"""Tracks that come back (issue 47; docs/design.md section 10): objects through clutter.

Synthetic videos with the hard cases (:func:`lfsam.video.io.synth.generate_video` with
``hard=True``: objects at up to 6 pixels per frame, depth order changing, one small object
passing fully behind a near occluder for about five frames, one leaving the frame and coming
back), 5x5 views of 96x128, tracked with the oracle and ground-truth disparity from one click
per object at frame 0 (every object showing at least 100 pixels in the center view there, at
its deepest pixel). Each seed is tracked twice in the same process, with the search of issue 47
(``search=True``, the default) and without it (``search=False``: the tracking before issue 47),
and with each ``--jitter`` setting of the oracle (``boundary_jitter``). Printed per run, over
all seeds:

* ``visible``: the (object, frame, view) triples where the object shows at least
  ``--min-pixels`` (100) pixels; ``lost``: the share of them with IoU below 0.5; ``mean_iou``
  over them (target: lost <= 1 %, mean IoU >= 0.97; with jitter 1 lost <= 2 %);
* ``switches``: identity switches (:func:`lfsam.metrics.temporal.identity_switches` over the
  clicked objects; target 0); ``switches (shown)``: the same counted only over the frames
  where the object shows at least ``--min-pixels`` in some view (a hidden object whose few
  visible pixels lie under a neighbour's mask one pixel too wide counts in ``switches``,
  matched to that neighbour, not here);
* ``returns``: episodes where an object comes back after showing fewer than ``--min-pixels``
  in every view for at least one frame; ``latency``: frames from the first frame it shows
  ``--min-pixels`` again in some view to the first frame it is found (IoU >= 0.5 in such a
  view; ``never`` counts those not found by the end; ``after gaps``: each return's frames
  hidden before it; ``late or never (gap <= 5)``: the returns after gaps of up to
  :data:`TARGET_GAP` frames found late or never, the target's count: 0);
* the cost (target: the search costs at most 20 % more per frame than the tracking before
  it), measured in this process, each frame's least time over ``--repeat`` runs, four ways:
  ``ms/frame`` and ``ratio``: the whole :meth:`OnlineTracker.track` call against ``before``
  (this includes the light-field pipeline segmenting the objects that ``before`` dropped,
  work a track that keeps its objects has to do); ``carrying``: the carrying / search alone
  (``OnlineTracker.carry_seconds``) and its ratio; ``search extra``: the search's extra
  carrying time as a share of ``before``'s whole frame; ``same-objects ratio``: the whole
  frame over only the frames where both placed the same object ids (the pipeline's work
  alike, so the difference is the search's). ``--easy`` tracks videos without the hard cases,
  where ``before`` loses few objects, so the whole-frame ratio there is the search's cost;
* ``--stages``: the pipeline's stages (ms a frame per tracking mode: encode, initial,
  propagate, occlude, refine, fuse...), where the whole frame's extra goes (``make
  gpu-track`` prints them);
* ``--ops``: the torch operators dispatched a frame per tracking mode, counted in one more
  (untimed) run of each video: every operator is at least one kernel launch on CUDA, where
  the host's launches, not the arithmetic, are the cost of small views, so the count is the
  GPU's cost measured on any machine; ``waits``: those that make the host wait for a GPU (a
  value read back, ``nonzero``, ``unique``, ``masked_select``, as ``bench_gpu.py --profile``
  counts them);
* ``clicked`` (a third mode, no tracking): every object clicked afresh in every frame at the
  deepest pixel of the view where it shows most, each frame segmented alone by the same
  pipeline and oracle. Its lost share is the floor that the oracle's imperfections set: with
  ``--jitter 1`` the oracle erodes a third of its answers by one pixel (a 3x3 square), and an
  object a few pixels wide keeps under half of itself (IoU below 0.5) however it was found.

``--consensus`` runs every mode (search, before, clicked) with the multi-view consensus of
issue 36 (docs/design.md section 3.9: each refined view's mask voted with its neighbours'):
``on`` with it, ``off`` without (default), ``both`` each video with and without it, one after
the other in the same process, so that its cost per frame is a ratio measured in one run
(printed as ``consensus cost``; with ``--repeat`` the two settings alternate run by run).
Its cost with a real architecture: ``--model`` (e.g. ``edgetam-tiny-test``, or ``edgetam
--random-weights`` for EdgeTAM's full-size encoder; random weights: the timings count, the
scores mean nothing, and the search then widens every frame for objects never found).

The default seeds (101-103) are held out: the tracker was developed on seeds 1-40.

Usage::

    OMP_NUM_THREADS=1 python benchmarks/bench_tracking.py [--seeds 101,102,103]
        [--frames 12] [--objects 5] [--jitter 0,1] [--modes search,before,clicked] [--easy]
        [--repeat 2] [--consensus off|on|both] [--model oracle] [--device auto] [--stages]
        [--ops] [--ablate RULE[,RULE...]|all] [--json OUT]

``--ablate`` adds one mode a rule, ``search-RULE``: the search with that rule switched off
(:class:`lfsam.video.tracking.config.TrackerConfig`, docs/design.md section 10, "The tracker's
rules"), so that each row against ``search`` shows what the rule buys on these videos (lost
share, switches, cost).

At the full size, on a GPU (``make gpu-check`` runs it): ``--size 480x640 --min-pixels 2500
--frames 8 --seeds 1301 --jitter 0 --modes search,before --repeat 2 --device cuda --stages``; the
carrying columns then split the search's own time (on the CPU) from the pipeline's.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
from scipy import ndimage
from torch.utils._python_dispatch import TorchDispatchMode

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from lfsam.api import ModelOptions, RunOptions, SegmentOptions
from lfsam.metrics.temporal import frame_matches, identity_switches
from lfsam.pipeline import PipelineConfig
from lfsam.prompts import ObjectPrompts, PointPrompt
from lfsam.segmenters import load_segmenter
from lfsam.video.io.synth import generate_video
from lfsam.video.tracking.config import TrackerConfig, switches
from lfsam.video.tracking.online import OnlineTracker

MODES = {"search": True, "before": False, "clicked": None}
#: Issue 47's target covers objects hidden for up to this many frames: found again in the
#: first frame they show ``--min-pixels`` (``late or never (gap <= 5)`` counts the others).
TARGET_GAP = 5
#: ``--consensus``: the consensus settings each video is run with.
CONSENSUS = {"off": (False,), "on": (True,), "both": (False, True)}


#: Where the segmenter and the pipeline run (``--device``; ``auto``: CUDA where present).
DEVICE = "auto"


def options_for(jitter: int, seed: int, consensus: bool = False,
                model: str = "oracle") -> SegmentOptions:
    """The run's options: ``model`` (the oracle with ``jitter``) on :data:`DEVICE`, the
    multi-view consensus (docs/design.md section 3.9) on or off."""
    oracle = {"boundary_jitter": jitter} if jitter and model == "oracle" else None
    return SegmentOptions(pipeline=PipelineConfig(consensus=consensus),
                          run=RunOptions(progress=False),
                          model=ModelOptions(name=model, oracle=oracle, seed=seed,
                                             device=DEVICE))


def clicks(lf, min_pixels: int) -> tuple[list[ObjectPrompts], dict[int, int]]:
    """One click (deepest pixel) per object showing ``min_pixels`` in the center view; the
    prompts and the map object id -> ground-truth label."""
    labels = lf.labels[lf.center]
    prompts, truth = [], {}
    for label in np.unique(labels[labels > 1]):  # label 1 is the background
        mask = labels == label
        if mask.sum() < min_pixels:
            continue
        obj_id = len(prompts) + 1
        prompts.append(ObjectPrompts(obj_id, (deepest_click(mask),)))
        truth[obj_id] = int(label)
    return prompts, truth


def deepest_click(mask: np.ndarray) -> PointPrompt:
    """A click at the pixel of ``mask`` farthest from its border (``(U, V)`` bool)."""
    depth = ndimage.distance_transform_edt(np.pad(mask, 1))[1:-1, 1:-1]
    row, col = np.unravel_index(int(np.argmax(depth)), depth.shape)
    return PointPrompt(float(col), float(row))


def clicked_every_frame(frames, truth: dict[int, int], jitter: int, seed: int,
                        consensus: bool = False, segmenter=None):
    """The reference without tracking: every object clicked afresh in every frame (one click
    at the deepest pixel of the view where it shows most, if it shows anywhere), each frame
    segmented alone by the same pipeline and oracle. What it loses is the floor the oracle's
    imperfections set (with ``--jitter``: a one-pixel erosion of an object a few pixels wide
    keeps under half of it), not tracking. Labels and seconds as :func:`track`."""
    options = options_for(jitter, seed, consensus)
    labels, seconds = [], []
    for lf in frames:
        prompts = []
        for obj_id, label in truth.items():
            area = (lf.labels == label).sum(axis=(2, 3))
            if area.max() == 0:
                continue
            view = tuple(int(i) for i in np.unravel_index(int(np.argmax(area)), area.shape))
            click = deepest_click(lf.labels[view] == label)
            prompts.append(ObjectPrompts(obj_id, (PointPrompt(click.x, click.y, True, view),)))
        start = time.perf_counter()
        if prompts:
            tracker = OnlineTracker(segmenter or "oracle", disparity="gt", options=options,
                                    memory=False)
            tracker.add_prompts(prompts)
            labels.append(tracker.track(lf).labels)
        else:
            labels.append(np.zeros(lf.labels.shape, np.int64))
        seconds.append(time.perf_counter() - start)
    return labels, seconds, [0.0] * len(frames)


def track(frames, prompts, search: bool, jitter: int, seed: int, consensus: bool = False,
          segmenter=None, stages: list | None = None):
    """Labels of every frame, the seconds of each ``track`` call and of its carrying (one
    run; ``main`` keeps each frame's least time over ``--repeat`` runs: the labels are the
    same every run). ``segmenter``: a ready model tracked with constrained prompts (default:
    the oracle). ``stages``: each frame's pipeline stage seconds (the frame result's
    ``timings``) are appended to it."""
    options = options_for(jitter, seed, consensus)
    tracker = OnlineTracker(segmenter or "oracle", disparity="gt", options=options,
                            search=search, memory=False)
    tracker.add_prompts(prompts)
    labels, seconds, carrying = [], [], []
    for lf in frames:
        start, carried = time.perf_counter(), tracker.carry_seconds
        result = tracker.track(lf)
        seconds.append(time.perf_counter() - start)
        carrying.append(tracker.carry_seconds - carried)
        labels.append(result.labels)
        if stages is not None:
            stages.append(dict(result.timings))
    return labels, seconds, carrying


class OperatorCount(TorchDispatchMode):
    """Counts the torch operators dispatched while active (``--ops``): ``operators`` in all,
    ``waits`` of them make the host wait for a GPU (:data:`WAITS`)."""

    #: Operators that read a value back or size their output by the data.
    WAITS = frozenset({"aten::_local_scalar_dense", "aten::nonzero", "aten::_unique2",
                       "aten::unique_consecutive", "aten::masked_select"})

    def __init__(self) -> None:
        super().__init__()
        self.operators = 0
        self.waits = 0

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        self.operators += 1
        self.waits += func._schema.name in self.WAITS
        return func(*args, **(kwargs or {}))


def count_operators(frames, prompts, search: bool, jitter: int, seed: int,
                    consensus: bool = False, segmenter=None) -> tuple[int, int]:
    """Operators and waits a frame of one tracked video (:class:`OperatorCount`)."""
    with OperatorCount() as counter:
        track(frames, prompts, search, jitter, seed, consensus, segmenter)
    return counter.operators // len(frames), counter.waits // len(frames)


def score(frames, labels, truth: dict[int, int], min_pixels: int) -> dict:
    """Lost share, mean IoU, identity switches and return latencies of one tracked video."""
    ious, matches, shown_matches = [], [], []
    returns, latencies, gaps = 0, [], []
    state = {obj_id: {"gone": False, "since": None, "gap": 0} for obj_id in truth}
    for lf, pred in zip(frames, labels, strict=True):
        found = frame_matches(pred, lf.labels)
        matches.append({g: found.get(g) for g in truth.values() if g in found})
        shown_matches.append({})
        for obj_id, label in truth.items():
            gt = lf.labels == label
            ours = pred == obj_id
            area = gt.sum(axis=(2, 3))
            inter = (gt & ours).sum(axis=(2, 3))
            union = (gt | ours).sum(axis=(2, 3))
            shown = area >= min_pixels
            iou = inter[shown] / np.maximum(union[shown], 1)
            ious.extend(iou.tolist())
            st = state[obj_id]
            if shown.any() and label in found:
                shown_matches[-1][label] = found[label]
            if not shown.any():
                st["gone"] = True
                st["gap"] += 1
                continue
            if st["gone"] and st["since"] is None:
                st["since"], st["waited"], st["return_gap"] = 0, 0, st["gap"]
                returns += 1
            if st["since"] is not None:
                if (iou >= 0.5).any():
                    latencies.append(st["waited"])
                    gaps.append(st["return_gap"])
                    st["since"] = None
                else:
                    st["waited"] += 1
            st["gone"], st["gap"] = False, 0
    never_gaps = [st["return_gap"] for st in state.values() if st["since"] is not None]
    never = len(never_gaps)
    switches = identity_switches(matches)
    shown_switches = identity_switches(shown_matches)
    ious_arr = np.asarray(ious)
    return {"visible": len(ious), "lost": int((ious_arr < 0.5).sum()),
            "iou_sum": float(ious_arr.sum()), "switches": int(sum(switches.values())),
            "shown_switches": int(sum(shown_switches.values())),
            "returns": returns, "latencies": latencies, "gaps": gaps, "never": never,
            "never_gaps": never_gaps,
            "late_in_target": sum(1 for lat, gap in zip(latencies, gaps, strict=True)
                                  if lat > 0 and gap <= TARGET_GAP)
            + sum(1 for gap in never_gaps if gap <= TARGET_GAP)}


def _ids(labels: np.ndarray) -> frozenset[int]:
    return frozenset(int(i) for i in np.unique(labels) if i > 0)


def timing(totals: dict, key: tuple) -> dict:
    """The cost figures of one run against ``before`` with the same jitter and consensus (see
    the module docstring): whole frame, carrying, the search's own extra as a share of the
    earlier frame, and the whole frame over the frames where both placed the same objects;
    with the consensus, its cost: the whole frame against the same mode without it."""
    mode, jitter, consensus = key
    total, base = totals[key], totals.get(("before", jitter, consensus))
    ms = 1000 * float(np.mean(total["seconds"]))
    carry_ms = 1000 * float(np.mean(total["carrying"]))
    out = {"ms_per_frame": ms, "carrying_ms_per_frame": carry_ms}
    plain = totals.get((mode, jitter, False))
    if consensus and plain is not None:
        out["consensus_ratio"] = ms / (1000 * float(np.mean(plain["seconds"])))
    if base is None or mode == "clicked":  # no tracking: its cost is not the search's
        return out
    base_ms = 1000 * float(np.mean(base["seconds"]))
    base_carry = 1000 * float(np.mean(base["carrying"]))
    same = [(a, b) for a, b, ia, ib in zip(total["seconds"], base["seconds"], total["ids"],
                                           base["ids"], strict=True) if ia == ib]
    out.update({
        "ratio": ms / base_ms, "carrying_ratio": carry_ms / base_carry,
        "search_extra_share": (carry_ms - base_carry) / base_ms,
        "same_objects_frames": len(same), "frames": len(total["seconds"]),
        "same_objects_ratio": (sum(a for a, _ in same) / sum(b for _, b in same)
                               if same else float("nan"))})
    return out


def rules_of(mode: str) -> TrackerConfig:
    """The tracker's rules of a mode: ``search-RULE`` (``--ablate``) the search with that rule
    switched off, any other mode today's rules."""
    rule = mode.removeprefix("search-")
    return TrackerConfig().without(rule) if rule != mode else TrackerConfig()


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        epilog="examples: OMP_NUM_THREADS=1 python benchmarks/bench_tracking.py --seeds 1,2 "
               "--jitter 0\n  python benchmarks/bench_tracking.py --easy --repeat 2 "
               "--modes search,before --jitter 0   # the search's cost where nothing is lost"
               "\n  python benchmarks/bench_tracking.py --consensus on --modes search,clicked "
               "--jitter 1   # with the multi-view consensus (and its floor)"
               "\n  python benchmarks/bench_tracking.py --seeds 1001 --consensus both "
               "--modes search --repeat 2 --model edgetam-tiny-test   # the consensus's "
               "cost per frame with a real architecture",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default="101,102,103")
    parser.add_argument("--frames", type=int, default=12)
    parser.add_argument("--objects", type=int, default=5)
    parser.add_argument("--grid", default="5x5")
    parser.add_argument("--size", default="96x128")
    parser.add_argument("--jitter", default="0,1")
    parser.add_argument("--modes", default="search,before,clicked",
                        help="search: the tracking of issue 47; before: the tracking before "
                             "it; clicked: no tracking, every object clicked afresh in every "
                             "frame (the floor the oracle's imperfections set)")
    parser.add_argument("--consensus", choices=list(CONSENSUS), default="off",
                        help="every mode with the multi-view consensus (docs/design.md "
                             "section 3.9), without it, or both, one after the other per "
                             "video (its cost per frame: 'consensus cost', a ratio in one run)")
    parser.add_argument("--model", default="oracle",
                        help="the segmenter (default the oracle); another model, e.g. "
                             "edgetam-tiny-test or sam2-tiny-test (random weights), is loaded "
                             "once and tracked with constrained prompts: its timings count, "
                             "its scores mean nothing; --jitter must then be 0")
    parser.add_argument("--random-weights", action="store_true",
                        help="with --model: the named architecture with random weights (e.g. "
                             "--model edgetam: EdgeTAM's full-size encoder, no checkpoint)")
    parser.add_argument("--min-pixels", type=int, default=100,
                        help="an object shows in a view from this many pixels (clicks, scores; "
                             "scale it with the view: 2500 at 480x640)")
    parser.add_argument("--device", default="auto",
                        help="where the segmenter and the pipeline run: auto (CUDA where "
                             "present), cpu, cuda; the search's matching runs on the CPU")
    parser.add_argument("--easy", action="store_true",
                        help="videos without the hard cases (hard=False), where the earlier "
                             "tracking loses few objects: the search's cost on the same work")
    parser.add_argument("--repeat", type=int, default=1,
                        help="track each video this many times (with --consensus both the two "
                             "settings alternate); each frame's least time counts")
    parser.add_argument("--stages", action="store_true",
                        help="also print each tracking mode's pipeline stages (ms a frame, the "
                             "mean over every run): where the whole frame's extra goes")
    parser.add_argument("--ops", action="store_true",
                        help="also count the torch operators dispatched a frame per tracking "
                             "mode, in one more untimed run of each video (each is at least "
                             "one kernel launch on CUDA): the GPU's cost on any machine")
    parser.add_argument("--ablate", default="", metavar="RULE[,RULE...]|all",
                        help="also track with the search with each of these rules switched off "
                             "(lfsam.video.tracking.config.TrackerConfig's switches; all: every "
                             "one), a mode 'search-RULE' each: what each rule buys (lost, "
                             "switches, cost against the full search)")
    parser.add_argument("--json", default=None, help="also write the numbers here")
    args = parser.parse_args()
    global DEVICE
    DEVICE = args.device
    grid = tuple(int(x) for x in args.grid.lower().split("x"))
    size = tuple(int(x) for x in args.size.lower().split("x"))
    seeds = [int(s) for s in args.seeds.split(",")]
    jitters = [int(j) for j in args.jitter.split(",")]
    modes = args.modes.split(",")
    ablated = list(switches()) if args.ablate == "all" else [r for r in args.ablate.split(",") if r]
    try:
        TrackerConfig().without(*ablated)
    except ValueError as exc:
        parser.error(str(exc))
    modes += [f"search-{rule}" for rule in ablated]
    if args.model != "oracle" and any(jitters):
        parser.error("--jitter is the oracle's: give --jitter 0 with --model")
    totals: dict[tuple[str, int, bool], dict] = {}
    stage_runs: dict[tuple[str, int, bool], list[dict]] = defaultdict(list)
    op_runs: dict[tuple[str, int, bool], list[tuple[int, int]]] = defaultdict(list)
    segmenter = None
    for seed in seeds:
        frames = list(generate_video(grid=grid, size=size, frames=args.frames, seed=seed,
                                     num_objects=args.objects, hard=not args.easy))
        prompts, truth = clicks(frames[0], args.min_pixels)
        if args.model != "oracle" and segmenter is None:  # loaded once, outside the timing
            segmenter = load_segmenter(args.model, random_weights=args.random_weights,
                                       device=args.device, keep_decoder_state=False)
        for jitter in jitters:
            for mode in modes:
                runs: dict[bool, tuple] = {}
                for _ in range(args.repeat):  # the consensus settings alternate, run by run
                    for consensus in CONSENSUS[args.consensus]:
                        if mode == "clicked":
                            got = clicked_every_frame(frames, truth, jitter, seed, consensus,
                                                      segmenter)
                        else:
                            with rules_of(mode).applied():
                                got = track(frames, prompts, MODES.get(mode, True), jitter,
                                            seed, consensus, segmenter,
                                            stage_runs[(mode, jitter, consensus)])
                        if args.ops and mode != "clicked" and len(runs) < len(
                                CONSENSUS[args.consensus]):  # once a video and setting
                            with rules_of(mode).applied():
                                op_runs[(mode, jitter, consensus)].append(count_operators(
                                    frames, prompts, MODES.get(mode, True), jitter, seed,
                                    consensus, segmenter))
                        old = runs.get(consensus)
                        runs[consensus] = got if old is None else (
                            old[0], list(np.minimum(old[1], got[1])),
                            list(np.minimum(old[2], got[2])))
                for consensus, (labels, seconds, carrying) in runs.items():
                    row = score(frames, labels, truth, args.min_pixels)
                    row["seconds"] = seconds
                    row["carrying"] = carrying
                    row["ids"] = [_ids(x) for x in labels]
                    total = totals.setdefault((mode, jitter, consensus), {
                        "visible": 0, "lost": 0, "iou_sum": 0.0, "switches": 0,
                        "shown_switches": 0, "returns": 0,
                        "latencies": [], "gaps": [], "never": 0, "never_gaps": [],
                        "late_in_target": 0, "seconds": [], "carrying": [], "ids": []})
                    for key, value in row.items():
                        total[key] = total[key] + value
                    name = mode + ("+cons" if consensus else "")
                    never_after = f" after gaps {row['never_gaps']}" if row["never"] else ""
                    print(f"seed {seed} jitter {jitter} {name:>12}: {row['lost']}/"
                          f"{row['visible']} lost, mean IoU "
                          f"{row['iou_sum'] / max(row['visible'], 1):.4f}, "
                          f"{row['switches']} switches ({row['shown_switches']} shown), "
                          f"returns {row['returns']} latencies "
                          f"{row['latencies']} after gaps {row['gaps']} never "
                          f"{row['never']}{never_after}, "
                          f"{1000 * np.mean(seconds):.0f} ms/frame "
                          f"({1000 * np.mean(carrying):.0f} carrying)", flush=True)
    print()
    print(f"{len(seeds)} videos (seeds {args.seeds}{', easy' if args.easy else ''}), "
          f"{args.frames} frames of {grid[0]}x{grid[1]} views of {size[0]}x{size[1]}, "
          f"{args.objects} objects, {args.model}, gt disparity, least of {args.repeat} "
          f"timing(s)")
    header = ("mode", "jitter", "consensus", "visible", "lost %", "mean IoU", "switches",
              "switches (shown)", "returns",
              "latency mean", "latency max", "never", f"late or never (gap <= {TARGET_GAP})",
              "ms/frame", "ratio", "carrying ms/frame",
              "carrying ratio", "search extra % of before frame",
              "same-objects frames", "same-objects ratio", "consensus cost")
    print(" | ".join(header))
    out = []
    for (mode, jitter, consensus), total in totals.items():
        lat = total["latencies"]
        row = {"mode": mode, "jitter": jitter, "consensus": consensus,
               "visible": total["visible"],
               "lost_pct": 100 * total["lost"] / max(total["visible"], 1),
               "mean_iou": total["iou_sum"] / max(total["visible"], 1),
               "switches": total["switches"], "shown_switches": total["shown_switches"],
               "returns": total["returns"],
               "latency_mean": float(np.mean(lat)) if lat else None,
               "latency_max": max(lat) if lat else None, "never": total["never"],
               "late_in_target": total["late_in_target"],
               **timing(totals, (mode, jitter, consensus))}
        out.append(row)
        nan = float("nan")
        print(f"{mode} | {jitter} | {'on' if consensus else 'off'} | {row['visible']} | "
              f"{row['lost_pct']:.2f} | "
              f"{row['mean_iou']:.4f} | {row['switches']} | {row['shown_switches']} | "
              f"{row['returns']} | "
              f"{row['latency_mean'] if lat else '-'} | {row['latency_max'] if lat else '-'} | "
              f"{row['never']} | {row['late_in_target']} | {row['ms_per_frame']:.0f} | "
              f"{row.get('ratio', nan):.2f} | "
              f"{row['carrying_ms_per_frame']:.0f} | {row.get('carrying_ratio', nan):.2f} | "
              f"{100 * row.get('search_extra_share', nan):.1f} | "
              f"{row.get('same_objects_frames', '-')}/{row.get('frames', '-')} | "
              f"{row.get('same_objects_ratio', nan):.2f} | "
              f"{row.get('consensus_ratio', nan):.2f}")
    if args.stages:
        print_stages(stage_runs, out)
    if args.ops:
        print_operators(op_runs, out)
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1), encoding="utf-8")


def print_stages(stage_runs: dict[tuple[str, int, bool], list[dict]], out: list[dict]) -> None:
    """The pipeline's stage seconds per tracking mode, ms a frame (the mean over every run and
    frame; ``total``: the pipeline's own, the search's answers included in ``initial`` and
    ``refine``, its matching not): added to ``out``'s rows as ``stages_ms``."""
    names = sorted({name for runs in stage_runs.values() for frame in runs for name in frame})
    if not names:
        return
    print()
    print("stage ms/frame (mean over runs) | " + " | ".join(names))
    for row in out:
        runs = stage_runs.get((row["mode"], row["jitter"], row["consensus"]), [])
        if not runs:
            continue
        means = {name: 1000 * float(np.mean([frame.get(name, 0.0) for frame in runs]))
                 for name in names}
        row["stages_ms"] = means
        print(_mode_label(row) + " | " + " | ".join(f"{means[name]:.0f}" for name in names))


def _mode_label(row: dict) -> str:
    """``search jitter 1 +cons``: a tracking mode's name in the extra tables."""
    return f"{row['mode']} jitter {row['jitter']}{' +cons' if row['consensus'] else ''}"


def print_operators(op_runs: dict[tuple[str, int, bool], list[tuple[int, int]]],
                    out: list[dict]) -> None:
    """Operators and waits a frame per tracking mode (the mean over the videos), and the
    operators' ratio to ``before`` with the same jitter and consensus: added to ``out``'s rows
    as ``operators_per_frame``, ``waits_per_frame``."""
    if not op_runs:
        return
    means = {key: np.mean(np.asarray(runs, dtype=np.float64), axis=0)
             for key, runs in op_runs.items()}
    print()
    print("operators a frame (one untimed run) | operators | waits | ratio")
    for row in out:
        key = (row["mode"], row["jitter"], row["consensus"])
        if key not in means:
            continue
        operators, waits = means[key]
        base = means.get(("before", row["jitter"], row["consensus"]))
        ratio = operators / base[0] if base is not None and base[0] else float("nan")
        row["operators_per_frame"], row["waits_per_frame"] = float(operators), float(waits)
        print(f"{_mode_label(row)} | {operators:.0f} | {waits:.0f} | {ratio:.2f}")


if __name__ == "__main__":
    main()
