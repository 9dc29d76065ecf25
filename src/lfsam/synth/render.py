"""Rendering a synthetic scene into a light field with exact ground truth.

For each view (docs/design.md section 6):

- **RGB**, anti-aliased: ``k x k`` samples per pixel (``supersample = k``) at offsets
  ``(j + 0.5) / k - 0.5``; each sample is z-buffered (:func:`lfsam.synth.raster.zbuffer`) and
  coloured by bilinear lookup in the winning patch's texture at its local coordinates (inverse
  affine warping); the samples of a pixel are averaged.
- **Disparity and labels**, exact at pixel centres: one z-buffer pass in float64 at the
  integer pixel positions; the disparity is the winning plane's value there (float32 output),
  the label its instance label.

Views are rendered one at a time on the chosen torch device (CPU by default, CUDA works).
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from tqdm import tqdm

from lfsam.camera import synthetic_camera
from lfsam.devices import resolve_device
from lfsam.lightfield import LightField
from lfsam.synth.materials import (
    GLASS_REFLECTANCE,
    REFLECTANCE,
    SEE_THROUGH,
    assign_materials,
    inner_region,
    mirror_colour,
    reflection_texture,
    refracted_grid,
)
from lfsam.synth.raster import region, zbuffer
from lfsam.synth.scene import random_scene
from lfsam.synth.shapes import inside
from lfsam.synth.spec import PlanarObject, SceneSpec
from lfsam.synth.specular import add_highlight
from lfsam.synth.textures import make_texture

__all__ = ["demo_scene", "generate_scene", "render_scene", "sample_geometry"]

_MAX_TEXTURE = 2048


def _texture(obj: PlanarObject, supersample: int, device: torch.device) -> torch.Tensor:
    rows = int(np.clip(round(2 * obj.half_size[0] * supersample), 4, _MAX_TEXTURE))
    cols = int(np.clip(round(2 * obj.half_size[1] * supersample), 4, _MAX_TEXTURE))
    return make_texture(obj.texture, obj.texture_seed, (rows, cols), zoom=supersample).to(device)


def _sample_grid(size: tuple[int, int], step: int, dtype, device):
    """Sample rows/columns: ``step`` per pixel, centred on the pixel (pixel ``i`` spans
    ``i - 0.5 .. i + 0.5``)."""
    rows = (torch.arange(size[0] * step, dtype=dtype, device=device) + 0.5) / step - 0.5
    cols = (torch.arange(size[1] * step, dtype=dtype, device=device) + 0.5) / step - 0.5
    return rows[:, None], cols[None, :]


def _render_rgb(
    objects,
    textures,
    ds: float,
    dt: float,
    us: torch.Tensor,
    vs: torch.Tensor,
    specular: float = 0.0,
    reach: float = 1.0,
    materials: dict[int, str] | None = None,
    reflections: dict[int, torch.Tensor] | None = None,
) -> torch.Tensor:
    """Z-buffer and colour every sample in one pass; returns ``[3, rows, cols]``.

    Each patch is evaluated on its bounding box only: where its outline covers a sample and it
    is closer than what is there, its bilinearly sampled texture replaces the colour. Inside the
    frame of a glass or mirror object (``materials``, :mod:`lfsam.synth.materials`) the colour
    mixes in the scene behind it (rendered without it, refracted) or its reflection.
    """
    shape = (us.shape[0], vs.shape[1])
    rgb = torch.zeros((3, *shape), dtype=torch.float32, device=us.device)
    best = torch.full(shape, float("-inf"), dtype=us.dtype, device=us.device)
    first = True
    for obj, texture in zip(objects, textures, strict=True):
        rows, cols = region(obj, ds, dt, us, vs)
        u, v = us[rows], vs[:, cols]
        if u.numel() == 0 or v.numel() == 0:
            continue
        local, plane = obj.view_maps(ds, dt)
        # Sampling grid (x, y) written in place; x and y are views into it.
        grid = torch.empty((u.shape[0], v.shape[1], 2), dtype=us.dtype, device=us.device)
        torch.add(local[1, 0] * u + local[1, 2], local[1, 1] * v, out=grid[..., 0])
        torch.add(local[0, 0] * u + local[0, 2], local[0, 1] * v, out=grid[..., 1])
        x, y = grid[..., 0], grid[..., 1]
        d = (plane[0] * u + plane[2]) + plane[1] * v
        sampled = F.grid_sample(
            texture[None],
            grid[None].float(),
            mode="bilinear",
            padding_mode="reflection" if obj.shape == "plane" else "border",
            align_corners=False,
        )[0]
        if specular > 0 and obj.shape != "plane":
            sampled = add_highlight(sampled, obj, x, y, ds, dt, reach, specular)
        material = (materials or {}).get(obj.label, "matte")
        if material != "matte" and obj.shape != "plane":
            sampled = _see_inside(
                sampled, obj, material, x, y, u, v, (objects, textures, ds, dt, us, vs),
                (rows, cols), reflections,
            )
        if first and obj.shape == "plane":
            best, rgb = d.expand(shape).clone(), sampled  # the first, unbounded patch
            first = False
            continue
        first = False
        take = inside(obj.shape, x, y, obj.vertices, obj.corner) & (d > best[rows, cols])
        best[rows, cols] = torch.where(take, d, best[rows, cols])
        rgb[:, rows, cols] = torch.where(take[None], sampled, rgb[:, rows, cols])
    return rgb


def _see_inside(
    sampled: torch.Tensor,
    obj: PlanarObject,
    material: str,
    x: torch.Tensor,
    y: torch.Tensor,
    u: torch.Tensor,
    v: torch.Tensor,
    scene: tuple,
    window: tuple[slice, slice],
    reflections: dict[int, torch.Tensor] | None,
) -> torch.Tensor:
    """The colour of a glass or mirror object's samples: its texture on the frame, inside the
    frame the scene behind (glass) or the reflection (mirror) mixed with it."""
    objects, textures, ds, dt, us, vs = scene
    if material == "glass":
        keep = [i for i, other in enumerate(objects) if other is not obj]
        ru, rv = refracted_grid(obj, ds, dt, us, vs)
        behind = _render_rgb(
            [objects[i] for i in keep], [textures[i] for i in keep], ds, dt, ru, rv
        )[:, window[0], window[1]]
        reflected = mirror_colour(obj, ds, dt, u, v, (reflections or {})[obj.label])
        mixed = (
            SEE_THROUGH * behind
            + GLASS_REFLECTANCE * reflected
            + (1.0 - SEE_THROUGH - GLASS_REFLECTANCE) * sampled
        )
    else:
        reflected = mirror_colour(obj, ds, dt, u, v, (reflections or {})[obj.label])
        mixed = REFLECTANCE * reflected + (1.0 - REFLECTANCE) * sampled
    return torch.where(inner_region(obj, x, y)[None], mixed, sampled)


def _box_average(rgb: torch.Tensor, k: int) -> torch.Tensor:
    """Mean over ``k x k`` blocks of a ``[3, k H, k W]`` image (anti-aliasing filter)."""
    blocks = rgb.view(3, rgb.shape[1] // k, k, rgb.shape[2] // k, k)
    total = blocks[:, :, 0, :, 0].clone()
    for i in range(k):
        for j in range(k):
            if i or j:
                total += blocks[:, :, i, :, j]
    return total / (k * k)


def render_scene(
    spec: SceneSpec,
    supersample: int = 2,
    device: str | torch.device | None = None,
    specular: float = 0.0,
    materials: dict[int, str] | None = None,
) -> LightField:
    """Render every view of a scene with its exact disparity and labels.

    Parameters
    ----------
    spec : SceneSpec
        The scene.
    supersample : int
        Samples per pixel along each axis for the RGB (1 = no anti-aliasing).
    device : str or torch.device, optional
        Where to compute (default CPU; any spelling of :func:`lfsam.devices.resolve_device`).
    specular : float
        Brightness of a specular highlight on every object that moves across views
        (:mod:`lfsam.synth.specular`; 0 = Lambertian surfaces, the default).
    materials : dict, optional
        ``{label: "glass" | "mirror" | "matte"}`` (:mod:`lfsam.synth.materials`): glass and
        mirror objects show the scene behind them or a reflection inside an opaque frame; the
        disparity and labels stay their surface's. Default: every object matte.

    Returns
    -------
    LightField
        ``views`` uint8, ``disparity`` [S, T, U, V] float32 and ``labels`` [S, T, U, V] int32
        in the package convention, ``categories`` naming each label by texture and shape
        (``"brick disc"``, :attr:`lfsam.synth.spec.PlanarObject.category`); ``meta["generator"]``
        describes the scene.
    """
    device = resolve_device("cpu" if device is None else device)
    supersample = max(1, int(supersample))
    s_count, t_count = spec.grid
    height, width = spec.size
    center = spec.center
    objects = spec.objects
    textures = [_texture(obj, supersample, device) for obj in objects]
    materials = {int(k): str(m) for k, m in (materials or {}).items() if m != "matte"}
    reflections = {
        obj.label: reflection_texture(obj, tuple(textures[i].shape[1:]), supersample).to(device)
        for i, obj in enumerate(objects)
        if materials.get(obj.label) in ("glass", "mirror")
    }
    label_of = torch.tensor([obj.label for obj in objects] + [0], dtype=torch.int32, device=device)
    us, vs = _sample_grid(spec.size, supersample, torch.float32, device)
    pu, pv = _sample_grid(spec.size, 1, torch.float64, device)
    views = np.empty((s_count, t_count, height, width, 3), dtype=np.uint8)
    disparity = np.empty((s_count, t_count, height, width), dtype=np.float32)
    labels = np.empty((s_count, t_count, height, width), dtype=np.int32)
    order = [(s, t) for s in range(s_count) for t in range(t_count)]
    reach = float(max(center[0], s_count - 1 - center[0], center[1], t_count - 1 - center[1], 1))
    for s, t in tqdm(order, desc="rendering views", unit="view", disable=None, leave=False):
        ds, dt = float(s - center[0]), float(t - center[1])
        rgb = _render_rgb(
            objects, textures, ds, dt, us, vs, specular, reach, materials, reflections
        )
        if supersample > 1:
            rgb = _box_average(rgb, supersample)
        rgb = (rgb * 255.0).round().clamp(0, 255).to(torch.uint8)
        views[s, t] = rgb.permute(1, 2, 0).cpu().numpy()
        winner, best, _ = zbuffer(objects, ds, dt, pu, pv)
        best = torch.where(torch.isfinite(best), best, torch.full_like(best, float("nan")))
        disparity[s, t] = best.float().cpu().numpy()
        labels[s, t] = label_of[winner].cpu().numpy()
    seed = spec.meta.get("seed")
    meta = {
        "source": f"synthetic (seed {seed})" if seed is not None else "synthetic",
        "format": "synth",
        "orientation": "package convention (generated)",
        "generator": {
            **spec.meta,
            "supersample": supersample,
            **({"specular": float(specular)} if specular > 0 else {}),
            **({"materials": {str(k): m for k, m in materials.items()}} if materials else {}),
            "objects": [obj.describe() for obj in objects],
        },
    }
    if seed is not None:
        meta["seed"] = int(seed)
    if "disparity_range" in spec.meta:  # metres for the disparities (docs/design.md section 11)
        meta["camera"] = synthetic_camera(spec.size, spec.meta["disparity_range"]).to_json()
    categories = {obj.label: obj.category for obj in objects if obj.label != 0}
    return LightField(
        views, disparity=disparity, labels=labels, meta=meta, categories=categories or None
    )


def sample_geometry(spec: SceneSpec, s: int, t: int, u, v) -> tuple[np.ndarray, np.ndarray]:
    """Exact label and disparity of view ``(s, t)`` at arbitrary (sub-pixel) positions.

    Parameters
    ----------
    spec : SceneSpec
        The scene.
    s, t : int
        The view.
    u, v : array_like
        Pixel rows and columns (any matching shape), evaluated in float64.

    Returns
    -------
    labels : ndarray of int32
        Label of the visible patch (0 where none).
    disparity : ndarray of float64
        Its disparity (-inf where none).
    """
    u = torch.as_tensor(np.asarray(u, dtype=np.float64))
    v = torch.as_tensor(np.asarray(v, dtype=np.float64))
    u, v = torch.broadcast_tensors(u, v)
    flat_u, flat_v = u.reshape(-1), v.reshape(-1)
    ds, dt = float(s - spec.center[0]), float(t - spec.center[1])
    winner, best, _ = zbuffer(spec.objects, ds, dt, flat_u, flat_v)
    label_of = torch.tensor([obj.label for obj in spec.objects] + [0], dtype=torch.int32)
    return (
        label_of[winner].reshape(u.shape).numpy(),
        best.reshape(u.shape).numpy(),
    )


def generate_scene(
    grid: tuple[int, int] = (9, 9),
    size: tuple[int, int] = (240, 320),
    seed: int = 0,
    num_objects: int = 6,
    disparity_range: tuple[float, float] = (-2.0, 2.0),
    slanted_fraction: float = 0.5,
    label_background: bool = True,
    supersample: int = 2,
    device: str | torch.device | None = None,
    hidden_objects: int = 0,
    specular: float = 0.0,
    glass: int = 0,
    mirror: int = 0,
) -> LightField:
    """A random synthetic light field with exact per-view disparity and instance labels.

    A textured, gently slanted background plane (label 1 unless ``label_background`` is False)
    and ``num_objects`` textured planar objects (labels 2, 3, ...) at different depths, some
    slanted, overlapping so that they occlude and disocclude each other; textures from
    scikit-image's sample photographs and procedural patterns; sub-pixel disparities within
    ``disparity_range``; anti-aliased RGB. Deterministic per ``seed``.

    The background is labelled by default so that every pixel carries a label, which makes the
    coverage of the ground-truth label field (docs/design.md section 7) meaningful and lets the
    oracle segmenter reach full coverage.

    Parameters
    ----------
    grid : (S, T)
        Views per column and row.
    size : (U, V)
        Pixel rows and columns of each view.
    seed : int
        Random seed.
    num_objects : int
        Objects in front of the background.
    disparity_range : (LO, HI)
        All disparities lie in this range (pixels per view step; larger = closer). The baseline
        scales with it.
    slanted_fraction : float
        Probability that an object is slanted.
    label_background : bool
        Whether the background plane gets its own label.
    supersample : int
        RGB samples per pixel along each axis.
    device : str or torch.device, optional
        Torch device for rendering (default CPU; see :func:`render_scene`).
    hidden_objects : int
        Extra small objects that the center view cannot see (entirely behind nearer objects
        there) but that at least one corner view sees with at least
        :func:`lfsam.synth.hidden.default_min_area` pixels (issue 16). Their labels follow the
        other objects' and are listed in ``meta["generator"]["hidden_labels"]``; the rest of the
        scene is the one generated with ``hidden_objects=0``.
    specular : float
        Brightness (0 to 1) of a specular highlight on every object that slides over it from
        view to view (non-Lambertian surfaces, :mod:`lfsam.synth.specular`); 0 (default): none.
        The geometry and labels are those of ``specular=0``.
    glass, mirror : int
        How many objects are glass (the first ``glass`` objects after the background) and how
        many mirrors (the next ``mirror``): inside an opaque frame they show the scene behind
        them, refracted, or a reflection (:mod:`lfsam.synth.materials`). Geometry, labels and
        ground truth are those of ``glass=mirror=0`` (the same scene made matte).

    Returns
    -------
    LightField
        See :func:`render_scene`.

    Examples
    --------
    >>> lf = generate_scene(grid=(3, 3), size=(32, 48), seed=1, num_objects=2)
    >>> lf.views.shape, lf.disparity.shape, lf.labels.dtype
    ((3, 3, 32, 48, 3), (3, 3, 32, 48), dtype('int32'))
    """
    spec = random_scene(
        grid=grid,
        size=size,
        seed=seed,
        num_objects=num_objects,
        disparity_range=disparity_range,
        slanted_fraction=slanted_fraction,
        label_background=label_background,
        hidden_objects=hidden_objects,
    )
    labels = [obj.label for obj in spec.objects[1:]]
    materials = assign_materials(labels, glass, mirror) if glass or mirror else None
    return render_scene(
        spec, supersample=supersample, device=device, specular=specular, materials=materials
    )


def demo_scene() -> LightField:
    """The bundled default scene (used by ``make demo``): 9x9 views of 240x320, seed 0."""
    return generate_scene(grid=(9, 9), size=(240, 320), seed=0)
