"""Rendering around objects (issue 66): accuracy against the synthetic twin, and speed.

Accuracy, on `lfsam synth` scenes of held-out seeds, oracle masks (the scene's labels) and the
center view's disparity estimated from the views (`lfsam disparity`'s default):

- see-through: PSNR against the scene without the object over the center-view pixels hidden by
  it, seen by at least a quarter of the views, whose hidden surface lies within 0.25 px of the
  focus; and plain refocusing at the same focus (target: >= 30 dB and >= 8 dB above);
- remove: PSNR in every view over the object's pixels that another view sees by the scene's
  truth (:func:`lfsam.synth.seen_behind`: the twin's surface there lands, in some other view,
  off the object and on the same surface; the lowest view is reported; target >= 30 dB), and
  over the pixels
  the removal says it filled (its own flags); how many truly seen pixels it flagged unseen
  (inpainted) and how many it filled that no view sees; and the removed light field's own
  estimated center disparity within 0.1 px of the twin's there (target >= 90 %), against the
  twin's true disparity and against the twin's own estimate (view consistency, whatever the
  estimator's own error);
- refocus on a fronto-parallel object: PSNR against the center view over the object (its mask
  less 3 pixels; target >= 35 dB) and over the background (blurred: low).

Speed: refocus, see-through and removal of 9x9 views of 512x512 (target 2 s, 2 s, 15 s), with
the ground-truth center disparity given (estimating it is `lfsam disparity`'s cost).

    python benchmarks/bench_render.py                       # seeds 901-903, 5x5 of 128x160
    python benchmarks/bench_render.py --seeds 7 --size 64x96 --speed-size 64x64   # smoke
    python benchmarks/bench_render.py --seeds 1101,1102 --speed-size 0x0          # no speed part
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from lfsam.disparity import estimate_disparity
from lfsam.render import object_focus, objects_in_front, refocus, remove_objects, see_through
from lfsam.render.background_disparity import dilate, rim_disparity
from lfsam.synth import generate_scene, generate_scene_without, seen_behind


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = np.mean((np.asarray(a, float) - np.asarray(b, float)) ** 2)
    return float(10 * np.log10(255.0**2 / max(mse, 1e-12)))


def pair(text: str) -> tuple[int, int]:
    a, b = text.lower().split("x")
    return int(a), int(b)


def accuracy(seed: int, grid, size, objects: int) -> dict:
    settings = dict(grid=grid, size=size, seed=seed, num_objects=objects)
    lf = generate_scene(**settings)
    sc, tc = lf.center
    ids, counts = np.unique(lf.labels[sc, tc], return_counts=True)
    obj = int(ids[1:][np.argmax(counts[1:])])  # the object most seen in the center view
    twin = generate_scene_without([obj], **settings)
    start = time.perf_counter()
    disparity = estimate_disparity(lf, device="cpu").disparity
    estimate_s = time.perf_counter() - start
    masks = lf.labels == obj
    focus = rim_disparity(masks[sc, tc], disparity)
    front = objects_in_front(lf.labels, [obj], disparity, focus)  # as `lfsam render` does
    image, coverage = see_through(lf.views, masks, disparity=disparity, occluders=front)
    hidden = masks[sc, tc] & (coverage >= 0.25) & (np.abs(twin.disparity[sc, tc] - focus) < 0.25)
    truth = twin.views[sc, tc][hidden]
    row = {"seed": seed, "object": obj, "estimate_s": estimate_s, "st_pixels": int(hidden.sum()),
           "st_psnr": psnr(image[hidden], truth),
           "plain_psnr": psnr(refocus(lf.views, focus)[hidden], truth)}
    views, unseen = remove_objects(lf.views, masks, disparity)
    seen = seen_behind(lf, twin, [obj])
    per_view, per_truth = [], []
    for s in range(grid[0]):
        for t in range(grid[1]):
            filled = masks[s, t] & ~unseen[s, t]
            if filled.sum():
                per_view.append(psnr(views[s, t][filled], twin.views[s, t][filled]))
            if seen[s, t].sum():
                per_truth.append(psnr(views[s, t][seen[s, t]], twin.views[s, t][seen[s, t]]))
    from lfsam.lightfield import LightField

    own = estimate_disparity(LightField(views), device="cpu").disparity
    twin_own = estimate_disparity(twin, device="cpu").disparity
    filled = masks[sc, tc] & ~unseen[sc, tc]
    close = np.abs(own - twin.disparity[sc, tc])[filled] <= 0.1
    consistent = np.abs(own - twin_own)[filled] <= 0.1
    row.update(remove_min_psnr=min(per_view) if per_view else float("nan"),
               remove_median_psnr=float(np.median(per_view)) if per_view else float("nan"),
               truth_min_psnr=min(per_truth) if per_truth else float("nan"),
               truth_median_psnr=float(np.median(per_truth)) if per_truth else float("nan"),
               seen_flagged=int((seen & unseen).sum()), seen_pixels=int(seen.sum()),
               unseen_filled=int((~seen & masks & ~unseen).sum()),
               unseen=int(unseen.sum()), object_pixels=int(masks.sum()),
               disparity_within=float(close.mean()) if close.size else float("nan"),
               disparity_consistent=float(consistent.mean()) if consistent.size else float("nan"))
    flat = [o["label"] for o in lf.meta["generator"]["objects"][1:] if o["slope"] == [0.0, 0.0]]
    if flat:
        mask = lf.labels[sc, tc] == flat[0]
        inner = ~dilate(torch.from_numpy(~mask), 3).numpy()
        sharp = refocus(lf.views, object_focus(mask, disparity))
        rest = lf.labels[sc, tc] == 1
        row.update(refocus_object=psnr(sharp[inner], lf.views[sc, tc][inner]),
                   refocus_rest=psnr(sharp[rest], lf.views[sc, tc][rest]))
    return row


def speed(grid, size, seed: int, repeats: int) -> dict:
    lf = generate_scene(grid=grid, size=size, seed=seed, num_objects=4, supersample=1)
    sc, tc = lf.center
    ids, counts = np.unique(lf.labels[sc, tc], return_counts=True)
    obj = int(ids[1:][np.argmax(counts[1:])])
    masks = lf.labels == obj
    disparity = lf.disparity[sc, tc]
    times = {}
    for name, call in (
        ("refocus", lambda: refocus(lf.views, 0.3)),
        ("see-through", lambda: see_through(lf.views, masks, disparity=disparity)),
        ("remove", lambda: remove_objects(lf.views, masks, disparity)),
    ):
        best = float("inf")
        for _ in range(repeats):
            start = time.perf_counter()
            call()
            best = min(best, time.perf_counter() - start)
        times[name] = best
    times["object_share"] = float(masks.mean())
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default="901,902,903")
    parser.add_argument("--grid", type=pair, default=(5, 5))
    parser.add_argument("--size", type=pair, default=(128, 160))
    parser.add_argument("--objects", type=int, default=3)
    parser.add_argument("--speed-grid", type=pair, default=(9, 9))
    parser.add_argument("--speed-size", type=pair, default=(512, 512))
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    torch.set_num_threads(max(1, torch.get_num_threads()))
    print(f"accuracy: {args.grid[0]}x{args.grid[1]} views of {args.size[0]}x{args.size[1]}, "
          "oracle masks, estimated center disparity")
    print("| seed | object | see-through dB | plain refocus dB | pixels | remove min / median dB "
          "(truly seen) | truly seen px flagged / all | filled but unseen px | remove min / "
          "median dB (own flags) | unseen / object px | disparity within 0.1 px of the twin's "
          "truth / own estimate | refocus object dB | refocus rest dB |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for seed in (int(s) for s in args.seeds.split(",")):
        r = accuracy(seed, args.grid, args.size, args.objects)
        print(f"| {r['seed']} | {r['object']} | {r['st_psnr']:.1f} | {r['plain_psnr']:.1f} | "
              f"{r['st_pixels']} | {r['truth_min_psnr']:.1f} / {r['truth_median_psnr']:.1f} | "
              f"{r['seen_flagged']} / {r['seen_pixels']} | {r['unseen_filled']} | "
              f"{r['remove_min_psnr']:.1f} / {r['remove_median_psnr']:.1f} | "
              f"{r['unseen']} / {r['object_pixels']} | {r['disparity_within']:.1%} / "
              f"{r['disparity_consistent']:.1%} | "
              f"{r.get('refocus_object', float('nan')):.1f} | "
              f"{r.get('refocus_rest', float('nan')):.1f} |", flush=True)
    if args.speed_size[0] == 0:
        return
    t = speed(args.speed_grid, args.speed_size, 0, args.repeats)
    print(f"speed: {args.speed_grid[0]}x{args.speed_grid[1]} views of {args.speed_size[0]}x"
          f"{args.speed_size[1]}, {torch.get_num_threads()} threads, best of {args.repeats}; "
          f"object {t['object_share']:.1%} of the pixels")
    print(f"| refocus s | see-through s | remove s |\n|---|---|---|\n"
          f"| {t['refocus']:.2f} | {t['see-through']:.2f} | {t['remove']:.2f} |")


if __name__ == "__main__":
    main()
