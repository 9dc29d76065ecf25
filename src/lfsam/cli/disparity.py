"""``lfsam disparity``: estimate the disparity of one view (default the center) of a light field."""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from lfsam.cli.common import HelpFormatter, add_device_argument, parse_pair
from lfsam.cli.inputs import expect_input
from lfsam.errors import LfsamError
from lfsam.fileutil import atomic_output, check_writable
from lfsam.io import read_lightfield

# The names of lfsam.disparity.methods.METHODS, default first (kept here so that building the
# parser does not import torch; a test checks that they agree).
METHOD_NAMES = ("occlusion-aware", "structure-tensor")

DESCRIPTION = """\
Estimate the disparity of one view (the center view unless --view is given). Absent views of a
partial grid are left out.

Methods (--method):
  occlusion-aware   (default) a cost volume over disparity hypotheses: every view is matched
                    against the chosen view at each hypothesis, and each pixel keeps the best of
                    the four half-grids of views (left, right, top, bottom), so a pixel next to
                    an occluder is judged by the views that see it; the costs are smoothed by a
                    guided filter that stops at the view's edges, and the best hypothesis is
                    refined to sub-pixel precision; away from edges a robust local surface fit
                    averages the noise of weakly textured, slanted or curved surfaces. On HCI
                    antinous about 4.5 % of the pixels are off by more than 0.07 px (structure
                    tensor: 22 %).
  structure-tensor  the paper's estimator: the structure tensor on epipolar-plane images
                    (Wanner & Goldluecke), sheared to candidate disparities so large baselines
                    work too, finished by an edge-aware smoothing (--no-edge-refinement skips it).

The result is a (U, V) float32 .npy in lfsam's convention: a pixel (u, v) of view (s_r, t_r) with
disparity d is seen in view (s, t) at (u - d (s - s_r), v - d (t - t_r)); larger is closer. Give
a center map to `lfsam segment --disparity FILE.npy`. The disparity range is found from the views
unless given. --confidence writes a (U, V) map in [0, 1] of how much to trust each value: low at
occlusion edges, in textureless regions and on shiny surfaces (occlusion-aware: the margin of the
best cost over the second-best, times the agreement with the outermost views; structure tensor:
its coherence).
"""

EPILOG = """\
examples:
  lfsam disparity ../shared/data/hci_antinous --out antinous_disp.npy --preview antinous_disp.png
  lfsam disparity scene --out disp.npy --range=-3,3      # negative numbers need the = form
  lfsam disparity scene --view 0,8 --out disp_0_8.npy    # view row 0, column 8 (0-based)
  lfsam disparity scene --out disp.npy --confidence conf.npy   # with a confidence map
  lfsam disparity scene --out st.npy --method structure-tensor  # the paper's estimator
  lfsam disparity scene --out d.npy --learned-refinement  # with the learned edge step
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``disparity`` subcommand."""
    parser = subparsers.add_parser(
        "disparity",
        help="estimate a view's disparity (occlusion-aware cost volume or structure tensor)",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=HelpFormatter,
    )
    parser.add_argument("path", help="light field (folder of views, .npz, ...)")
    parser.add_argument("--out", required=True, metavar="DISP.npy", help="output .npy")
    parser.add_argument(
        "--range", dest="disparity_range", metavar="LO,HI",
        type=lambda s: parse_pair(s, sep=",", kind=float),
        help="disparity range in pixels per view step (default: found from the views)",
    )
    parser.add_argument(
        "--method", choices=METHOD_NAMES, default=METHOD_NAMES[0],
        help="the estimator (see above)",
    )
    parser.add_argument(
        "--confidence", metavar="CONF.npy",
        help="also write the per-pixel confidence in [0, 1] (float32 .npy)",
    )
    parser.add_argument(
        "--edge-refinement", dest="edge_refinement", action="store_true", default=None,
        help="finish with the confidence-weighted joint bilateral smoothing (default: on for "
        "structure-tensor, off for occlusion-aware, where it blurs more than it repairs)",
    )
    parser.add_argument(
        "--no-edge-refinement", dest="edge_refinement", action="store_false",
        help="skip that smoothing",
    )
    parser.add_argument(
        "--learned-refinement", dest="learned_refinement", action="store_true",
        help="occlusion-aware: finish with the small network, trained on lfsam's synthetic "
        "scenes only, that moves pixels along depth edges to a neighbour's disparity (off by "
        "default: better on HCI antinous and cotton, worse on some synthetic scenes, and it "
        "can move a small near object's pixels to the background)",
    )
    parser.add_argument(
        "--view", metavar="S,T", type=lambda s: parse_pair(s, sep=",", kind=int),
        help="the view to estimate: 0-based view row S and column T (default: the center view)",
    )
    parser.add_argument("--preview", metavar="PNG", help="also write a colour-mapped picture")
    parser.add_argument("--format", dest="input_format", help="input format (default: detect)")
    add_device_argument(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``lfsam disparity``."""
    from lfsam.disparity import estimate_disparity  # loads on use, keeping `lfsam --help` light

    if not str(args.out).endswith(".npy"):
        raise LfsamError(f"--out must end in .npy, got {args.out!r}")
    if args.confidence is not None and not str(args.confidence).endswith(".npy"):
        raise LfsamError(f"--confidence must end in .npy, got {args.confidence!r}")
    for option, path in (("--out", args.out), ("--confidence", args.confidence),
                         ("--preview", args.preview)):
        if path:  # every output, before the light field is read
            check_writable(path, folder=False, option=option)
    if args.learned_refinement and args.method != "occlusion-aware":
        raise LfsamError(
            f"--learned-refinement refines the occlusion-aware estimate only, not "
            f"--method {args.method}; drop one of the two"
        )
    expect_input(args.path, "disparity", ("lightfield",))
    lightfield = read_lightfield(args.path, format=args.input_format)
    start = time.perf_counter()
    options = {} if args.edge_refinement is None else {"edge_refinement": args.edge_refinement}
    if args.method == "occlusion-aware":
        options["learned_refinement"] = args.learned_refinement
    estimate = estimate_disparity(
        lightfield, args.disparity_range, method=args.method, device=args.device,
        view=args.view, **options,
    )
    seconds = time.perf_counter() - start
    with atomic_output(args.out) as tmp:
        np.save(tmp, estimate.disparity.astype(np.float32))
    if args.confidence is not None:
        with atomic_output(args.confidence) as tmp:
            np.save(tmp, estimate.confidence.astype(np.float32))
    if args.preview:
        from matplotlib import colormaps

        from lfsam.viz import save_image

        low, high = estimate.disparity_range
        scaled = (estimate.disparity - low) / max(high - low, 1e-6)
        rgb = colormaps["viridis"](np.clip(scaled, 0, 1))[..., :3]
        save_image(args.preview, (rgb * 255).round().astype(np.uint8))
    print(json.dumps({
        "out": args.out,
        "method": args.method,
        "view": estimate.meta["view"],
        "range": [round(float(x), 3) for x in estimate.disparity_range],
        "seconds": round(seconds, 3),
        "mean_confidence": round(float(estimate.confidence.mean()), 3),
        "edge_refinement": bool(estimate.meta["edge_refinement"]),
        "learned_refinement": bool(estimate.meta.get("learned_refinement", False)),
        **({"confidence": args.confidence} if args.confidence is not None else {}),
    }))
    return 0
