"""Make docs/render_antinous.png: before / see-through / removed on the HCI scene antinous.

    python docs/make_render_figure.py [--data ../shared/data/hci_antinous]
                                      [--out docs/render_antinous.png]

The object is the bust. No SAM 2 checkpoint can be had here, so its masks come from the scene's
ground truth: the center view's ground-truth disparity, split at the gap between the bust and
the wall (Otsu's threshold; the connected region that holds the bust's chest, less the floor),
carried into every view by lfsam's own forward warp of that disparity
(:func:`lfsam.disparity.warp_center_disparity`, z-buffered) and split there the same way.
Everything else is what ``lfsam render`` does: the center disparity is estimated from the views
(``lfsam disparity``'s default), the see-through is focused on what lies behind the bust (black
where no view sees it), and the removed light field fills each view from the views that see
behind the bust, the rest inpainted (and flagged; the flags are drawn as a hatch on the third
panel).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from scipy import ndimage

from lfsam.disparity import estimate_disparity, warp_center_disparity
from lfsam.io import read_lightfield
from lfsam.render import remove_objects, see_through
from lfsam.viz import save_image


def otsu(values: np.ndarray, bins: int = 256) -> float:
    """The threshold that best splits ``values`` into two classes (Otsu 1979)."""
    hist, edges = np.histogram(values, bins=bins)
    centers = (edges[:-1] + edges[1:]) / 2
    weight = np.cumsum(hist)
    mean = np.cumsum(hist * centers)
    total, grand = weight[-1], mean[-1]
    between = (grand * weight - total * mean) ** 2 / np.maximum(weight * (total - weight), 1)
    return float(centers[np.argmax(between[:-1])])


def bust_masks(disparity: np.ndarray, grid: tuple[int, int]) -> np.ndarray:
    """The nearer region of the center disparity in every view: in each, the connected region
    nearer than the threshold that holds the bust's chest, less the floor in front of the
    pedestal (the rows where the region spans more than four fifths of the view)."""
    threshold = otsu(disparity[np.isfinite(disparity)])
    s_count, t_count = grid
    sc, tc = s_count // 2, t_count // 2
    height, width = disparity.shape
    chest = (int(0.55 * height), width // 2)
    masks = np.zeros((s_count, t_count, height, width), dtype=bool)
    for s in range(s_count):
        for t in range(t_count):
            view = warp_center_disparity(disparity, (s - sc, t - tc), device="cpu")[0]
            near, _ = ndimage.label(view > threshold)
            mask = near == near[chest]
            floor = np.nonzero(mask.sum(1) > 0.8 * width)[0]
            if floor.size:
                mask[floor.min():] = False
            masks[s, t] = mask
    return masks


def hatch(image: np.ndarray, flags: np.ndarray) -> np.ndarray:
    """Diagonal stripes over the flagged (inpainted) pixels."""
    rows, cols = np.mgrid[0:flags.shape[0], 0:flags.shape[1]]
    stripes = flags & ((rows + cols) % 12 < 2)
    out = image.copy()
    out[stripes] = (255, 64, 64)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", default=str(Path(__file__).resolve().parents[2] / "shared" /
                                              "data" / "hci_antinous"))
    parser.add_argument("--out", default=str(Path(__file__).with_name("render_antinous.png")))
    args = parser.parse_args()
    lf = read_lightfield(args.data)
    sc, tc = lf.center
    truth = lf.disparity if lf.disparity.ndim == 2 else lf.disparity[sc, tc]
    masks = bust_masks(truth, lf.grid_shape)
    start = time.perf_counter()
    disparity = estimate_disparity(lf).disparity
    print(f"disparity estimated in {time.perf_counter() - start:.1f} s")
    start = time.perf_counter()
    behind, coverage = see_through(lf.views, masks, disparity=disparity)
    print(f"see-through in {time.perf_counter() - start:.1f} s; "
          f"{(coverage[masks[sc, tc]] > 0).mean():.1%} of the bust's pixels seen behind")
    start = time.perf_counter()
    removed, unseen = remove_objects(lf.views, masks, disparity, progress=True)
    print(f"removal in {time.perf_counter() - start:.1f} s; "
          f"{unseen[sc, tc].sum() / max(masks[sc, tc].sum(), 1):.1%} of the center view's bust "
          "inpainted (seen by no view)")
    before = lf.views[sc, tc].copy()
    edge = masks[sc, tc] & ~ndimage.binary_erosion(masks[sc, tc], iterations=2)
    before[edge] = (255, 200, 0)
    panels = [before, np.clip(np.round(behind), 0, 255).astype(np.uint8),
              hatch(removed[sc, tc], unseen[sc, tc])]
    gap = np.full((before.shape[0], 8, 3), 255, dtype=np.uint8)
    figure = np.concatenate([panels[0], gap, panels[1], gap, panels[2]], axis=1)
    figure = figure[::2, ::2]  # half size for the README
    save_image(args.out, figure)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
