"""Write the bytecode of what lfsam imports, once, after ``make install`` (issue 65).

``pip install`` compiles every ``.py`` file of every package it installs: for lfsam's
dependencies (torch, transformers' hundreds of model folders, ray, napari, sympy, ...) that took
116 of the 213 seconds of a fresh ``.venv`` on the 2-core machine, for modules lfsam never
imports. ``make install`` now installs with ``--no-compile`` and then runs this script, which
imports every module of lfsam (the viewer's and the CLI's included) and the test tools with
bytecode writing on, so exactly the modules a run imports get their ``.pyc`` (37 s). Python
writes the rest on first import, unless ``PYTHONDONTWRITEBYTECODE`` is set: with it, a module
not warmed here is compiled in memory at each import (slower, never wrong). docs/performance.md,
"`make test` in two processes", has the measurements.

Usage::

    .venv/bin/python tools/compile_bytecode.py

Prints one line: how many modules were imported, in how long, and any lfsam module that failed
to import (named, with its error; the exit status stays 0: this only warms a cache, and the
tests report a module that does not import).
"""

from __future__ import annotations

import importlib
import pkgutil
import sys
import time

EXTRA = ("pytest", "xdist", "hypothesis", "pytestqt", "timm.models.repvit",
         "transformers.models.edgetam.modeling_edgetam",
         "transformers.models.edgetam_video.modeling_edgetam_video",
         "transformers.models.sam2.modeling_sam2",
         "transformers.models.sam2_video.modeling_sam2_video",
         "transformers.models.sam3.modeling_sam3",
         "transformers.models.timm_wrapper.modeling_timm_wrapper")
"""Modules lfsam or its tests import lazily (inside functions), warmed too."""


def main() -> int:
    sys.dont_write_bytecode = False
    start = time.perf_counter()
    import lfsam

    failed = []
    names = [info.name for info in pkgutil.walk_packages(lfsam.__path__, "lfsam.")]
    for name in [*names, *EXTRA]:
        try:
            importlib.import_module(name)
        except Exception as exc:  # a cache warmer names the failure and goes on
            failed.append(f"{name} ({type(exc).__name__}: {str(exc)[:80]})")
    seconds = time.perf_counter() - start
    line = f"compile_bytecode: {len(sys.modules)} modules imported in {seconds:.0f} s"
    print(line + (f"; failed: {', '.join(failed)}" if failed else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
