"""The same synthetic scene without chosen objects: the ground truth of object removal.

:func:`scene_without` drops objects from a :class:`~lfsam.synth.spec.SceneSpec`;
:func:`generate_scene_without` renders the twin of :func:`lfsam.synth.generate_scene` (same seed,
same settings) without them: what lies behind the objects, with its exact disparity and labels
(docs/design.md section 13).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace
from typing import Any

from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.synth.materials import assign_materials
from lfsam.synth.render import render_scene
from lfsam.synth.scene import random_scene
from lfsam.synth.spec import SceneSpec

__all__ = ["generate_scene_without", "scene_without"]


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
