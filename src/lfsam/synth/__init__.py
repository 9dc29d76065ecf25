"""Synthetic light fields with exact ground truth (docs/design.md section 6).

No public data set can be downloaded where this package is developed and tested, so it ships a
generator: textured planar patches at different depths, seen by a grid of cameras, rendered with
exact per-view disparity and instance labels in the package convention.

- :func:`generate_scene` — a random scene, rendered (the usual entry point);
- :func:`demo_scene` — the default scene used by ``make demo``;
- :func:`random_scene` / :func:`render_scene` — the two steps separately, for custom scenes built
  from :class:`PlanarObject` and :class:`SceneSpec` (the data model, :mod:`lfsam.synth.spec`);
- :func:`sample_geometry` — exact labels and disparity of any view at sub-pixel positions;
- :func:`generate_scene_without` — the same scene without chosen objects (what lies behind them);
  :func:`seen_behind` — which of the objects' pixels another view sees behind.
"""

from lfsam.synth.render import demo_scene, generate_scene, render_scene, sample_geometry
from lfsam.synth.scene import random_scene
from lfsam.synth.spec import PlanarObject, SceneSpec
from lfsam.synth.textures import TEXTURES, make_texture
from lfsam.synth.twin import generate_scene_without, scene_without, seen_behind

__all__ = [
    "TEXTURES",
    "PlanarObject",
    "SceneSpec",
    "demo_scene",
    "generate_scene",
    "generate_scene_without",
    "make_texture",
    "random_scene",
    "render_scene",
    "sample_geometry",
    "scene_without",
    "seen_behind",
]
