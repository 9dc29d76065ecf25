"""Load the segmenters' native libraries safely next to Qt and OpenGL (docs/design.md section 8).

``sam2`` imports ``torchvision.ops``, which imports ``torch._dynamo``, which imports ``triton``;
``triton._C.libtriton`` carries its own copy of LLVM. Under Mesa's software OpenGL (a virtual X
display, a remote desktop, a server without a GPU) Mesa has loaded its LLVM into the process's
global symbol scope as soon as napari draws; a ``libtriton`` loaded after that binds some of its
LLVM symbols to Mesa's copy and crashes in its static initialisers (``Segmentation fault`` while
the viewer's worker loads the model). Loading ``libtriton`` with ``RTLD_DEEPBIND`` makes it
resolve its symbols in itself first, whatever was loaded before, so the order no longer matters.

:func:`preload_native_libraries` does this once, in the main thread, from every door into the
viewer (``lfsam view``, the plugin's reader and dock widget) and again, as a no-op when already
done, before the session loads a segmenter.
"""

from __future__ import annotations

import importlib
import os
import sys
import threading

__all__ = ["preload_native_libraries"]

_lock = threading.Lock()
_done = False


def _import_isolated(name: str) -> None:
    """Import ``name`` with ``RTLD_DEEPBIND`` (where the platform has it); absent is fine."""
    if name in sys.modules:
        return
    deepbind = getattr(os, "RTLD_DEEPBIND", 0)
    flags = sys.getdlopenflags()
    sys.setdlopenflags(flags | deepbind)
    try:
        importlib.import_module(name)
    except ImportError:  # a torch without triton (CPU-only or macOS wheels): nothing to isolate
        pass
    finally:
        sys.setdlopenflags(flags)


def preload_native_libraries() -> None:
    """Import torch, triton (isolated) and torchvision's operators now, once per process.

    Call it from the main thread before the first napari window draws where possible; it is also
    safe later (the isolation does not depend on the order). Costs a few seconds the first time
    (torch and its compiler stack), nothing after.
    """
    global _done
    with _lock:
        if _done:
            return
        import torch  # noqa: F401  (normal flags: its own libraries are not the problem)

        _import_isolated("triton")
        importlib.import_module("torchvision.ops")  # what sam2 imports; pulls torch._dynamo
        _done = True
