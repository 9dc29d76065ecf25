"""The same synthetic scene without chosen objects: the ground truth of object removal.

:func:`scene_without` drops objects from a :class:`~lfsam.synth.spec.SceneSpec`;
:func:`generate_scene_without` renders the twin of :func:`lfsam.synth.generate_scene` (same seed,
same settings) without them: what lies behind the objects, with its exact disparity and labels
(docs/design.md section 13). :func:`seen_behind` says which of the objects' pixels another view
sees the surface behind: where a removal can be judged against the twin.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.synth.materials import assign_materials
from lfsam.synth.render import render_scene
from lfsam.synth.scene import random_scene
from lfsam.synth.spec import SceneSpec

__all__ = ["generate_scene_without", "scene_without", "seen_behind"]


def scene_without(spec: SceneSpec, labels: Iterable[int]) -> SceneSpec:
    """``spec`` with the objects of ``labels`` left out (the others keep their labels).

    Raises
    ------
    LfsamError
        For a label that is not an object of the scene (the message names the labels there).
    """
    drop = {int(label) for label in labels}
    present = [obj.label for obj in spec.objects]
    missing = sorted(drop - set(present))
    if missing:
        raise LfsamError(
            f"--without: no object {', '.join(map(str, missing))} in the scene; its labels are "
            f"{', '.join(map(str, present))}"
        )
    kept = tuple(obj for obj in spec.objects if obj.label not in drop)
    meta = {**spec.meta, "without": sorted(drop)}
    return replace(spec, objects=kept, meta=meta)


def generate_scene_without(without: Iterable[int], **settings: Any) -> LightField:
    """The twin of ``generate_scene(**settings)`` without the objects labelled ``without``.

    Parameters
    ----------
    without : iterable of int
        Labels of the objects to leave out (background = 1 when labelled, objects 2, 3, ...).
    **settings
        The keyword arguments of :func:`lfsam.synth.generate_scene`.

    Returns
    -------
    LightField
        The same views, exact disparity and labels as the full scene wherever the left-out
        objects were not seen; where they were, what lies behind them.

    Examples
    --------
    >>> lf = generate_scene_without([2], grid=(3, 3), size=(32, 48), seed=1, num_objects=2)
    >>> bool((lf.labels == 2).any())
    False
    """
    settings = dict(settings)
    render = {k: settings.pop(k) for k in ("supersample", "device", "specular")
              if k in settings}
    glass, mirror = settings.pop("glass", 0), settings.pop("mirror", 0)
    spec = random_scene(**settings)
    labels = [obj.label for obj in spec.objects[1:]]
    materials = assign_materials(labels, glass, mirror) if glass or mirror else None
    return render_scene(scene_without(spec, without), materials=materials, **render)


def seen_behind(scene: LightField, twin: LightField, labels: Iterable[int],
                tolerance: float = 0.25) -> np.ndarray:
    """Each view's pixels of the objects ``labels`` whose surface behind another view sees.

    The surface behind a pixel is the twin's there (at the twin's disparity ``d``); the view at
    ``(s', t')`` sees it at ``(u - d (s' - s), v - d (t' - t))`` if that lies inside the view,
    off the objects in ``scene`` (no object pixel in its bilinear footprint) and on a surface
    of the twin's disparity ``d`` there (within ``tolerance``: nothing else in front).

    Parameters
    ----------
    scene, twin : LightField
        A synthetic scene and its twin without the objects (:func:`generate_scene_without`),
        both with ground-truth labels and disparity.
    labels : iterable of int
        The removed objects.

    Returns
    -------
    (S, T, U, V) bool array
        True where another view sees what lies behind the objects (the pixels a removal can
        fill from the views); the objects' other pixels no view sees.
    """
    hidden = np.isin(scene.labels, list(labels))
    s_count, t_count, height, width = hidden.shape
    seen = np.zeros_like(hidden)
    flat = (s_count * t_count, 1, height, width)
    disparity = torch.from_numpy(np.asarray(twin.disparity, np.float32).reshape(flat))
    on_object = torch.from_numpy(hidden.reshape(flat).astype(np.float32))
    for s in range(s_count):
        for t in range(t_count):
            ys, xs = np.nonzero(hidden[s, t])
            if not ys.size:
                continue
            d = torch.from_numpy(np.asarray(twin.disparity[s, t], np.float32)[ys, xs])
            others = [(a, b) for a in range(s_count) for b in range(t_count) if (a, b) != (s, t)]
            rel = torch.tensor([(a - s, b - t) for a, b in others], dtype=torch.float32)
            u = torch.from_numpy(ys).float()[None] - d[None] * rel[:, :1]
            v = torch.from_numpy(xs).float()[None] - d[None] * rel[:, 1:]
            grid = torch.stack([2 * v / max(width - 1, 1) - 1, 2 * u / max(height - 1, 1) - 1],
                               -1)[:, None]
            index = [a * t_count + b for a, b in others]
            inside = (u >= 0) & (u <= height - 1) & (v >= 0) & (v <= width - 1)
            there = F.grid_sample(disparity[index], grid, mode="nearest", align_corners=True)
            blocked = F.grid_sample(on_object[index], grid, mode="bilinear", align_corners=True)
            visible = inside & ((there[:, 0, 0] - d[None]).abs() < tolerance)
            seen[s, t][ys, xs] = (visible & (blocked[:, 0, 0] < 1e-3)).any(0).numpy()
    return seen
