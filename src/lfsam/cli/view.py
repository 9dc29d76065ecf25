"""``lfsam view``: open a light field in napari and segment it by clicking."""

from __future__ import annotations

import argparse
import signal
import sys
from typing import Any

from lfsam.cli.common import (
    HelpFormatter,
    add_consensus_argument,
    add_disparity_argument,
    add_refine_views_argument,
    positive_float,
)
from lfsam.cli.models import add_model_arguments, model_options_from_args
from lfsam.cli.text import add_text_arguments, check_text_weights
from lfsam.errors import LfsamError
from lfsam.fileutil import check_cache_dir, check_writable
from lfsam.io import read_lightfield
from lfsam.result import load_result
from lfsam.video import is_video, read_video

DESCRIPTION = """\
Open a light field in napari: the views are one image layer with the view row s and column t on
two sliders; click an object in any view and see its mask in every view.

The dock widget drives lfsam's interactive predictor (docs/design.md section 8) in a worker
thread, so the window never freezes: the clicked view's mask appears first, then every view's.
Keys: S segment, C commit the object, T toggle positive/negative clicks (Ctrl-click adds the
other kind), Shift-C clear, Ctrl-Z / Ctrl-Shift-Z undo/redo prompt edits. Draw a rectangle in
"box prompts" for a box. "Segment everything" runs the automatic mode; "Find" takes a phrase
and adds every instance in the view shown as an object (SAM 3; --text PHRASE does it at start).
The Views / EPI buttons switch between the views and the epipolar-plane images through the
current pixel row or column. The "Consensus" box (--consensus) votes each view's masks with its
nearest views' masks, carried by disparity, so one view's wrong answer is outvoted; toggling it
refines the objects again.
Save writes a normal lfsam result (prompts included, so it reopens editable with --result).

A light-field video (a folder of frames, an [F, S, T, U, V, 3] array, per-view videos) opens
with a frame slider before the view sliders, read lazily; a click is tagged with the frame shown
and segments that frame at once. "Track" (Ctrl-T) tracks every object through all frames in the
worker, each frame showing as it finishes; Save then writes the video result folder, which
--result FOLDER reopens (read lazily; its objects editable with their per-frame prompts).

A live stream (--follow, or "Follow a frames folder…" in the dock): PATH is a folder a
light-field camera is writing frames into (renamed in when complete; it may be empty). Each frame
is segmented as it lands, in the background, and shown with its masks and its latency; a click
on the shown frame starts a new object, segmented from the next frame on. "Stop following", a
file named END in PATH or --follow-timeout ends the stream; --out (default PATH_live) then holds
every frame done, shown as a video when the stream ends. --auto (the dock's "Follow:
everything in the first frame" box) finds every object of the first frame and tracks it;
--text PHRASE finds the phrase's instances in the first frame and tracks them. A frame that
cannot be read or has another size is skipped with one line; a fault of the setup (the oracle
on frames without ground truth, a model that cannot load) stops the stream at once.

Needs a display: without one (DISPLAY unset, an SSH session, a server) it stops in one line
before Qt starts; run it under a virtual display with xvfb-run -a lfsam view ...

Needs the viewer extra: pip install 'lfsam[viewer]'.
"""

EPILOG = """\
examples:
  lfsam view scene --model oracle --disparity gt         # a synthetic scene with ground truth
  lfsam view ../shared/data/hci_antinous --cache ~/.cache/lfsam-embeddings
  lfsam view ../shared/data/lytro_2067 --model sam2.1-hiera-large --checkpoint sam2.1_hiera_large.pt
  lfsam view scene --model sam2-tiny-test --random-weights --device cpu   # try the viewer quickly
  lfsam view scene --result result.npz --model oracle    # reopen a result and correct it
  lfsam view scene --model oracle --disparity gt --text disc   # every disc, found at start
  lfsam view clip --model oracle --disparity gt          # a video (lfsam synth clip --frames 6)
  lfsam view incoming --follow --out live --model oracle --disparity gt   # a live stream
  lfsam view incoming --follow --auto --model oracle     # every object of the first frame
  lfsam view incoming --follow --text tile --model oracle   # "tile", found in the first frame
  xvfb-run -a lfsam view scene --model oracle            # no screen (SSH, a server): Xvfb
  lfsam view                                             # empty viewer; File > Open a light field
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``view`` subcommand."""
    parser = subparsers.add_parser(
        "view",
        help="open a light field in napari and segment it interactively",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=HelpFormatter,
    )
    parser.add_argument(
        "path", nargs="?", help="light field: a folder of views, .npz/.npy/.h5/.mat, ...; a "
        "video; with --follow, the frames folder a camera is writing"
    )
    parser.add_argument("--result", metavar="RESULT",
                        help="reopen this result's objects to edit (a result .npz, or a video's "
                        "result folder)")
    add_model_arguments(parser)
    add_text_arguments(parser)
    add_disparity_argument(parser)
    add_refine_views_argument(parser)
    add_consensus_argument(parser)
    parser.add_argument("--cache", metavar="DIR", help="embedding cache folder")
    parser.add_argument("--format", dest="input_format", help="input format (default: detect)")
    follow = parser.add_argument_group("a live stream (a frames folder that is still growing)")
    follow.add_argument(
        "--follow", action="store_true",
        help="PATH is a frames folder a light-field camera is still writing (it may be empty): "
        "segment and show each frame as it lands; clicks start objects from the next frame on",
    )
    follow.add_argument("--out", metavar="FOLDER",
                        help="with --follow: the live result folder, new or empty (default "
                        "PATH_live next to PATH)")
    follow.add_argument("--follow-timeout", type=positive_float, default=None, metavar="S",
                        help="with --follow: end after S seconds without a new frame (default: "
                        "a file named END or Stop ends it)")
    follow.add_argument("--latest", action="store_true",
                        help="with --follow: never fall behind: segment only the newest frame "
                        "that has landed, skipping older ones not yet started (the dock's "
                        "'Newest frame only')")
    follow.add_argument("--auto", action="store_true",
                        help="with --follow: find every object of the first frame "
                        "automatically and track it (clicks add more; the dock's \"Follow: "
                        "everything in the first frame\" box)")
    parser.set_defaults(func=run)


def check_follow(args: argparse.Namespace) -> None:
    """Check ``--follow`` and its options before anything opens (one line each; the viewer's
    Follow, docs/design.md section 10).

    Raises
    ------
    LfsamError
        ``--out``, ``--follow-timeout`` or ``--auto`` without ``--follow``; with it, no
        folder, a missing one, ``--result``, ``--text`` with ``--auto``, a disparity file, or
        an ``--out`` that is not a new or empty folder.
    """
    from lfsam.video.io.live_result import check_live_folder
    from lfsam.video.stream.follow import check_follow_folder

    if not getattr(args, "follow", False):
        if (getattr(args, "out", None) is not None or getattr(args, "follow_timeout", None)
                or getattr(args, "latest", False) or getattr(args, "auto", False)):
            raise LfsamError("--out, --follow-timeout, --latest and --auto go with --follow: "
                             "lfsam view FOLDER --follow --out RESULT")
        return
    if not args.path:
        raise LfsamError("--follow watches a frames folder: lfsam view FOLDER --follow")
    if args.result:
        raise LfsamError("--follow writes a new result into --out; to reopen a followed result "
                         "afterwards: lfsam view FOLDER --result RESULT")
    if getattr(args, "text", None) and args.auto:
        raise LfsamError("--follow takes --text or --auto, not both: --auto finds every "
                         "object already")
    if args.disparity not in ("estimate", "gt"):
        raise LfsamError("--follow takes --disparity estimate or gt (one per frame), not a file")
    folder = check_follow_folder(args.path)
    if args.out is None:  # PATH_live (or PATH_live_2, ...) is made next to PATH
        check_writable(folder.resolve().parent, folder=True, option="--out", inside=True)
    else:
        check_writable(args.out, folder=True, option="--out", inside=True)
        check_live_folder(args.out)


def open_viewer(args: argparse.Namespace, show: bool = True) -> tuple[Any, Any]:
    """The napari viewer and the docked widget for ``args`` (without starting the event loop).

    Raises
    ------
    LfsamError
        Without napari (naming the install command), without a display (naming ``DISPLAY``
        and ``xvfb-run -a``), or for an unreadable light field or result; nothing is opened
        then.
    """
    from lfsam.viewer import require_napari
    from lfsam.viewer.display import check_display
    from lfsam.viewer.native_libraries import preload_native_libraries

    check_follow(args)
    require_napari()
    check_display()  # before Qt, whose xcb plugin would abort the process (issue 46)
    if args.cache:
        check_cache_dir(args.cache)
    check_text_weights(args)
    preload_native_libraries()  # before napari draws with OpenGL (native_libraries docstring)
    video = None
    following = bool(getattr(args, "follow", False))
    if args.path and not following and args.input_format is None and is_video(args.path):
        video = read_video(args.path)
    lightfield = (
        read_lightfield(args.path, format=args.input_format)
        if args.path and video is None and not following else None
    )
    if args.result and lightfield is None and video is None:
        raise LfsamError("--result needs its light field: give the light field's path too")
    if video is not None:
        from lfsam import load_result as load_any_result
        from lfsam.video.io.result import is_video_result

        if args.result and not is_video_result(args.result):
            raise LfsamError("--result of a light-field video is its result folder (written "
                             "by `lfsam segment VIDEO --out FOLDER` or the viewer's Save)")
        result = load_any_result(args.result) if args.result else None
    else:
        result = load_result(args.result) if args.result else None

    import napari

    from lfsam.viewer.layout import lay_out
    from lfsam.viewer.objects3d_dock import ObjectsDock
    from lfsam.viewer.render_dock import RenderDock
    from lfsam.viewer.widget import LightFieldWidget

    model = model_options_from_args(args)
    viewer = napari.Viewer(title="lfsam", show=show)
    widget = LightFieldWidget(
        viewer,
        lightfield=lightfield,
        video=video,
        model=model.name,
        disparity=args.disparity,
        cache_dir=args.cache,
        segmenter_options=model.segmenter_keywords(),
        refine_views=getattr(args, "refine_views", "all"),
        consensus=bool(getattr(args, "consensus", False)),
        text_options={
            "text_model": model.text_model,
            "text_checkpoint": model.text_checkpoint,
            "text_threshold": model.text_threshold,
        },
    )
    dock = viewer.window.add_dock_widget(widget, name="lfsam", area="right")
    viewer.window.add_dock_widget(ObjectsDock(viewer, widget), name="lfsam 3D", area="right",
                                  tabify=True)  # a tab beside the lfsam dock (section 11)
    viewer.window.add_dock_widget(RenderDock(viewer, widget), name="lfsam render",
                                  area="right", tabify=True)  # refocus, see through (section 13)
    lay_out(viewer, dock)  # the canvas the largest part, the lfsam dock in front (issue 46)
    if result is not None and video is not None:
        widget.show_tracked(result)
    elif result is not None:
        widget.open_result(result)
    if following:  # --text: the phrases are found in the first frame, then tracked
        widget.controls.follow_auto_box.setChecked(bool(args.auto))
        widget.follow.start(args.path, args.out, timeout=args.follow_timeout, auto=args.auto,
                            latest=args.latest, texts=getattr(args, "text", None) or ())
        return viewer, widget
    for text in getattr(args, "text", None) or []:
        widget.find(text.phrase, view=text.view)
    return viewer, widget


def run(args: argparse.Namespace) -> int:
    """Run ``lfsam view``: returns when the window is closed (or on Ctrl-C / SIGTERM, which
    close it as its close button does). The dock's status lines are echoed on stderr."""
    viewer, widget = open_viewer(args)
    import napari
    from qtpy.QtCore import QTimer

    widget.status_changed.connect(lambda text: print(f"lfsam view: {text}", file=sys.stderr,
                                                     flush=True))

    def close(_signum: int, _frame: Any) -> None:
        viewer.close()

    previous = {sig: signal.signal(sig, close) for sig in (signal.SIGINT, signal.SIGTERM)}
    # Python runs signal handlers only between bytecodes: wake it while Qt's loop waits
    waker = QTimer()
    waker.timeout.connect(lambda: None)
    waker.start(200)
    try:
        napari.run()
    finally:
        widget.follow.stop(wait=30)  # the frame being segmented is finished and kept
        waker.stop()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return 0
