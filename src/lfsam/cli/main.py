"""Entry point of the ``lfsam`` command.

Each subcommand lives in its own module of :mod:`lfsam.cli` exposing ``register(subparsers)``,
which adds its parser and sets ``func`` to a callable taking the parsed arguments and returning an
exit status. User errors (:class:`lfsam.errors.LfsamError`) are printed as one line without a
traceback and exit with status 2. Warnings are printed as one plain line each,
``lfsam: warning: MESSAGE`` (:func:`plain_warnings`), not in Python's format with a source line.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import sys
import warnings
from collections.abc import Iterator, Sequence
from typing import Any, TextIO

from lfsam.devices import resolve_device
from lfsam.errors import LfsamError
from lfsam.version import __version__

# Subcommand modules, in the order `lfsam --help` lists them.
SUBCOMMANDS = [
    "info",
    "convert",
    "synth",
    "disparity",
    "models",
    "segment",
    "metrics",
    "export",
    "objects",
    "poses",
    "evaluate",
    "show",
    "render",
    "demo",
    "view",
]

DESCRIPTION = """\
Segment light fields with Segment Anything 2, consistently across views.

lfsam segments the center view with SAM 2, moves each mask into every other view with the scene's
disparity, removes occluded parts with SAM 2's own features, and re-prompts SAM 2 in each view
with a point and a box (Goncharov & Dansereau, WACV 2025 workshops).
"""

EPILOG = """\
examples:
  lfsam synth scene --grid 9x9 --size 240x320 --seed 0     # a synthetic scene with ground truth
  lfsam info ../shared/data/hci_antinous                   # what a light field holds
  lfsam segment scene --auto --model oracle --disparity gt --out result.npz
  lfsam metrics result.npz --gt scene                      # the paper's metrics
  lfsam show result.npz --lightfield scene --out figure.png
  lfsam render scene --result result.npz --see-through 3 --out behind.png

Run `lfsam COMMAND --help` for each command's options and an example.
"""


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser with every available subcommand."""
    parser = argparse.ArgumentParser(
        prog="lfsam",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"lfsam {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in SUBCOMMANDS:
        try:
            module = importlib.import_module(f"lfsam.cli.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"lfsam.cli.{name}":
                continue  # subcommand not built yet
            raise
        module.register(subparsers)
    return parser


def _show_plain(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: TextIO | None = None,
    line: str | None = None,
) -> None:
    """``warnings.showwarning`` replacement: ``lfsam: warning: MESSAGE`` on one line of stderr
    (a message of several lines is joined), without the category, file and source line."""
    target = sys.stderr if file is None else file
    if target is None:  # no stderr (pythonw): nowhere to show it, as Python's own
        return
    text = " ".join(part.strip() for part in str(message).splitlines() if part.strip())
    with contextlib.suppress(OSError):
        target.write(f"lfsam: warning: {text}\n")


@contextlib.contextmanager
def plain_warnings() -> Iterator[None]:
    """Print warnings as one plain line each (``lfsam: warning: MESSAGE``) while the block runs.

    Only the display changes: which warnings are shown (the filters, once per place by default)
    stays Python's. The previous ``warnings.showwarning`` is restored on exit.
    """
    previous: Any = warnings.showwarning
    warnings.showwarning = _show_plain
    try:
        yield
    finally:
        warnings.showwarning = previous


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``lfsam`` command; returns the exit status."""
    with plain_warnings():
        parser = build_parser()
        args = parser.parse_args(argv)
        if not getattr(args, "func", None):
            parser.print_help()
            return 0
        try:
            if getattr(args, "device", None) is not None:  # --device: before any input is read
                resolve_device(args.device)
            return int(args.func(args) or 0)
        except LfsamError as exc:
            print(f"lfsam: error: {exc}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print("lfsam: interrupted; no output file was written", file=sys.stderr)
            return 130


if __name__ == "__main__":
    sys.exit(main())
