"""Light-field videos of rigid textured boxes under known 3D motion (docs/design.md section 12).

The ground truth of 6D pose tracking (:mod:`lfsam.poses`). A metric camera
(:class:`lfsam.camera.Camera`: pinholes of focal length ``f`` pixels on a grid with spacing ``b``
metres, sensors shifted so the views converge at ``z0``) looks at a textured background plane
and a few textured boxes; every box turns about an axis of its own and moves a few millimetres
each frame. Every view is ray-cast (one vectorised slab test per box over all of the view's
rays, no loop over pixels): exact labels and disparity at pixel centres, anti-aliased colours
from ``supersample x supersample`` rays per pixel. Colours depend on the surface point only
(textures times a Lambert factor of the face's orientation), so the views are photo-consistent.

View ``(s, t)``'s pinhole sits at ``(b (t - t_c), b (s - s_c), 0)`` in the center camera's frame
(x right, y down, z forward) and its sensor is shifted by ``f b / z0`` per step; the ray of its
pixel ``(u, v)`` is ``O + z D`` with ``D = ((v - c_x) / f - b (t - t_c) / z0, (u - c_y) / f -
b (s - s_c) / z0, 1)``, so the ray parameter is the depth ``z`` and a point at depth ``z`` has
lfsam's disparity ``f b / z - f b / z0`` (:func:`lfsam.camera.disparity_from_depth`).

Each frame's light field carries ``meta["rigid"]``: per box its ``label``, ``size_m`` (full
edge lengths along its own axes) and ``pose`` (4x4, box frame to center camera frame, metres:
origin at the box's centre, axes along its edges); the motion of frame ``k`` is ``pose_k
pose_0^-1``. Deterministic per seed.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from lfsam.camera import Camera, disparity_from_depth
from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.synth.textures import GRAY_PHOTOS, PHOTOS, make_texture

__all__ = [
    "LEAVING_DEPTH",
    "LEAVING_GAP",
    "RIGID_CAMERA",
    "RigidBox",
    "RigidScene",
    "box_surface_points",
    "generate_rigid_video",
    "ray_cast",
    "render_rigid",
    "rigid_scenes",
    "rotation_about",
]

#: The issue's camera: f = 400 px, b = 1 cm, views converged at 1 m.
RIGID_CAMERA = Camera(focal_px=400.0, baseline_m=0.01, focus_distance_m=1.0)
#: Face textures (photographs and noise: distinct everywhere, so features match uniquely).
FACE_TEXTURES = (*PHOTOS, *GRAY_PHOTOS, "noise")
#: Texture pixels along a face's edge.
FACE_TEXELS = 160
#: Light direction of the Lambert factor (camera frame, towards the light).
LIGHT = np.array([-0.4, -0.6, -1.0]) / np.linalg.norm([-0.4, -0.6, -1.0])


def rotation_about(axis, angle: float) -> np.ndarray:
    """The 3x3 rotation by ``angle`` radians about ``axis`` (Rodrigues).

    Examples
    --------
    >>> np.round(rotation_about([0, 0, 1], np.pi / 2) @ [1.0, 0, 0], 12).tolist()
    [0.0, 1.0, 0.0]
    """
    k = np.asarray(axis, dtype=np.float64)
    k = k / np.linalg.norm(k)
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * cross + (1 - math.cos(angle)) * cross @ cross


@dataclass
class RigidBox:
    """One box: ``size_m`` (3,) full edge lengths, ``poses`` (F, 4, 4) box frame to camera per
    frame, ``textures`` six ``(H, W, 3)`` float arrays (faces -x, +x, -y, +y, -z, +z)."""

    label: int
    size_m: np.ndarray
    poses: np.ndarray
    textures: list[np.ndarray] = field(repr=False)

    @property
    def diameter_m(self) -> float:
        """The box's diameter (its space diagonal), the unit of ADD (Hinterstoisser 2012)."""
        return float(np.linalg.norm(self.size_m))


@dataclass
class RigidScene:
    """A video of rigid boxes: the camera, the grid, the view size, a background plane at
    ``background_z_m`` with its texture, and the boxes with every frame's pose."""

    camera: Camera
    grid: tuple[int, int]
    size: tuple[int, int]
    background_z_m: float
    background: np.ndarray = field(repr=False)
    boxes: list[RigidBox]
    seed: int

    @property
    def frames(self) -> int:
        return int(self.boxes[0].poses.shape[0]) if self.boxes else 1

    def describe(self, frame: int) -> dict:
        """``meta["rigid"]`` of ``frame`` (module docstring)."""
        return {
            "frame": int(frame),
            "frames": self.frames,
            "seed": self.seed,
            "units": "metres; poses map box frame (centre, edge axes) to the center camera's "
                     "frame (x right, y down, z forward)",
            "background_z_m": self.background_z_m,
            "objects": [{
                "label": box.label,
                "category": "box",
                "size_m": [round(float(x), 9) for x in box.size_m],
                "diameter_m": round(box.diameter_m, 9),
                "pose": np.round(box.poses[frame], 12).tolist(),
            } for box in self.boxes],
        }


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def box_surface_points(size_m, spacing_m: float = 0.005) -> np.ndarray:
    """Points on a box's six faces (box frame), about ``spacing_m`` apart: the model points of
    ADD (Hinterstoisser et al. 2012).

    Examples
    --------
    >>> pts = box_surface_points([0.1, 0.1, 0.1], 0.05)
    >>> pts.shape, float(np.abs(pts).max())
    ((26, 3), 0.05)
    """
    half = np.asarray(size_m, dtype=np.float64) / 2
    out = []
    for axis in range(3):
        a, c = [i for i in range(3) if i != axis]
        na = max(2, round(2 * half[a] / spacing_m) + 1)
        nc = max(2, round(2 * half[c] / spacing_m) + 1)
        ga, gc = np.meshgrid(np.linspace(-half[a], half[a], na),
                             np.linspace(-half[c], half[c], nc), indexing="ij")
        for sign in (-1.0, 1.0):
            face = np.zeros((ga.size, 3))
            face[:, axis] = sign * half[axis]
            face[:, a], face[:, c] = ga.ravel(), gc.ravel()
            out.append(face)
    return np.unique(np.round(np.concatenate(out), 12), axis=0)


def _corners(box: RigidBox, frame: int) -> np.ndarray:
    half = box.size_m / 2
    signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1], indexing="ij")).reshape(3, -1).T
    pose = box.poses[frame]
    return (signs * half) @ pose[:3, :3].T + pose[:3, 3]


def _fits(boxes: list[RigidBox], camera: Camera, size: tuple[int, int], margin_px: float,
          gap_m: float, may_leave: frozenset[int] = frozenset()) -> bool:
    """Every corner inside the center view (``margin_px`` in), and no box within ``gap_m`` of
    another (surface points of one tested against the other's slabs) in any frame; the boxes
    labelled in ``may_leave`` are exempt from the first test (they leave the view by design)."""
    cx, cy = camera.principal_point(size)
    samples = [box_surface_points(b.size_m, 0.01) for b in boxes]
    for frame in range(boxes[0].poses.shape[0]):
        for box in boxes:
            if box.label in may_leave:
                continue
            corners = _corners(box, frame)
            u = corners[:, 1] / corners[:, 2] * camera.focal_px + cy
            v = corners[:, 0] / corners[:, 2] * camera.focal_px + cx
            if (u.min() < margin_px or v.min() < margin_px or u.max() > size[0] - 1 - margin_px
                    or v.max() > size[1] - 1 - margin_px):
                return False
        for i, a in enumerate(boxes):
            world = samples[i] @ a.poses[frame][:3, :3].T + a.poses[frame][:3, 3]
            for j, b in enumerate(boxes):
                if i == j:
                    continue
                inv = np.linalg.inv(b.poses[frame])
                local = world @ inv[:3, :3].T + inv[:3, 3]
                if (np.abs(local) <= b.size_m / 2 + gap_m).all(axis=1).any():
                    return False
    return True


def _turning(rng: np.random.Generator, centres: np.ndarray,
             turn_deg: tuple[float, float]) -> np.ndarray:
    """Poses ``(frames, 4, 4)`` of a box at ``centres`` ``(frames, 3)`` that starts at a random
    orientation and turns every frame by an angle uniform in ``turn_deg`` about an axis of its
    own."""
    axis = rng.normal(size=3)
    rotation = _random_rotation(rng)
    poses = np.tile(np.eye(4), (len(centres), 1, 1))
    for frame, centre in enumerate(centres):
        if frame:
            rotation = rotation @ rotation_about(axis, math.radians(rng.uniform(*turn_deg)))
        poses[frame, :3, :3] = rotation
        poses[frame, :3, 3] = centre
    return poses


#: How much nearer than the other boxes (metres) the crossing box of ``rigid_scenes(crossing=
#: True)`` moves.
CROSSING_DEPTH = 0.35


def _crossing_box(rng: np.random.Generator, label: int, frames: int, z: float, camera: Camera,
                  size: tuple[int, int], box_size_m: tuple[float, float],
                  turn_deg: tuple[float, float]) -> RigidBox:
    """A box at depth ``z`` that crosses the view from one side to the other over ``frames``
    (left to right or right to left, at a random height), turning about an axis of its own."""
    edges = rng.uniform(*box_size_m, size=3)
    half_width = (size[1] / 2) / camera.focal_px * z
    reach = max(half_width - 0.6 * float(np.linalg.norm(edges)), 0.0)
    side = 1.0 if rng.uniform() < 0.5 else -1.0
    xs = np.linspace(-side * reach, side * reach, frames)
    y = rng.uniform(-0.03, 0.03)
    centres = np.stack([xs, np.full(frames, y), np.full(frames, z)], axis=1)
    return RigidBox(label, edges, _turning(rng, centres, turn_deg), [])


#: How much nearer than the other boxes (metres) the box of ``rigid_scenes(leaving=True)``
#: moves, and the frames it spends wholly outside every view.
LEAVING_DEPTH = 0.2
LEAVING_GAP = 3


def _leaving_box(rng: np.random.Generator, label: int, frames: int, z: float, camera: Camera,
                 size: tuple[int, int], grid: tuple[int, int], box_size_m: tuple[float, float],
                 turn_deg: tuple[float, float]) -> RigidBox:
    """A box at depth ``z`` that starts inside the view, moves out past its left or right edge,
    stays out of every view for :data:`LEAVING_GAP` frames and comes back in the way it left,
    turning about an axis of its own all the while. It starts and ends with its centre within
    0.4 of the half width from the middle (its bounding sphere inside the view), and is out at
    frames ``(frames - LEAVING_GAP) // 2`` on."""
    edges = rng.uniform(*box_size_m, size=3)
    radius = 0.5 * float(np.linalg.norm(edges))
    half_width = (size[1] / 2) / camera.focal_px * z
    # Out of every view: the bounding sphere past the center view's edge, plus the widest
    # view's parallax (its pinhole up to reach b away, its sensor shifted by f b / z0 a step).
    reach = max(grid) // 2
    parallax_m = reach * abs(float(disparity_from_depth(z, camera))) / camera.focal_px * z
    outside = half_width + radius / math.cos(math.atan(half_width / z)) + parallax_m + 0.01
    inside = rng.uniform(0.1, 0.4) * half_width
    side = 1.0 if rng.uniform() < 0.5 else -1.0
    going = (frames - LEAVING_GAP) // 2  # frames spent going out (and at least as many back)
    back = frames - going - LEAVING_GAP
    xs = np.concatenate([np.linspace(inside, outside, going + 1)[:going],
                         np.full(LEAVING_GAP, outside),
                         np.linspace(outside, inside, back + 1)[1:]])
    y = rng.uniform(-0.03, 0.03)
    centres = np.stack([side * xs, np.full(frames, y), np.full(frames, z)], axis=1)
    return RigidBox(label, edges, _turning(rng, centres, turn_deg), [])


def rigid_scenes(
    *,
    boxes: int = 3,
    frames: int = 10,
    grid: tuple[int, int] = (7, 7),
    size: tuple[int, int] = (240, 320),
    camera: Camera = RIGID_CAMERA,
    seed: int = 0,
    box_size_m: tuple[float, float] = (0.10, 0.17),
    distance_m: float = 1.0,
    turn_deg: tuple[float, float] = (2.0, 4.0),
    move_mm: tuple[float, float] = (4.0, 12.0),
    background_z_m: float = 1.6,
    texels: int = FACE_TEXELS,
    crossing: bool = False,
    leaving: bool = False,
) -> RigidScene:
    """A random video of rigid boxes (module docstring).

    With ``crossing`` (issue 64: poses through 3D occlusions) one more box, the last label,
    turns as the others do while it crosses the view from one side to the other at
    :data:`CROSSING_DEPTH` nearer than ``distance_m``, in front of the others: each of them is
    partly or wholly covered for some frames, in some views more than in others.

    With ``leaving`` (issue 64: tracks and poses across a long gap) one more box, the next
    label, :data:`LEAVING_DEPTH` nearer than ``distance_m``, starts inside the view, moves out
    past its left or right edge, is outside every view for :data:`LEAVING_GAP` frames in the
    middle of the video and comes back in, turning all the while (it needs at least
    ``LEAVING_GAP + 4`` frames).

    Each box: edges uniform in ``box_size_m``, a random orientation, its centre about
    ``distance_m`` away, side by side across the view; every frame it turns by an angle uniform
    in ``turn_deg`` about its own random axis (fixed in the box) and moves by a length uniform in
    ``move_mm`` along a random direction of its own. Draws are repeated (up to 200 times) until
    every box stays inside the center view and clear of the others in every frame.

    Raises
    ------
    LfsamError
        If no such draw is found (too many or too large boxes for the view).
    """
    if boxes < 1 or frames < 1:
        raise LfsamError(f"need at least one box and one frame, got {boxes} and {frames}")
    if leaving and frames < LEAVING_GAP + 4:
        raise LfsamError(f"a box that leaves and comes back needs at least {LEAVING_GAP + 4} "
                         f"frames, got {frames}; use more --frames")
    rng = np.random.default_rng([seed, 43])
    z = distance_m
    half_width = (size[1] / 2) / camera.focal_px * z
    reach = max(grid) // 2
    parallax = abs(float(disparity_from_depth(z - 0.15, camera))) * reach + 2
    for _ in range(200):
        found = []
        lanes = (np.arange(boxes) - (boxes - 1) / 2) * (1.6 * half_width / boxes)
        for index in range(boxes):
            edges = rng.uniform(*box_size_m, size=3)
            start = np.eye(4)
            start[:3, :3] = _random_rotation(rng)
            start[:3, 3] = (lanes[index] + rng.uniform(-0.02, 0.02),
                            rng.uniform(-0.05, 0.05), z + rng.uniform(-0.05, 0.05))
            axis = rng.normal(size=3)
            direction = rng.normal(size=3)
            direction /= np.linalg.norm(direction)
            poses = [start]
            for _frame in range(1, frames):
                step = np.eye(4)
                step[:3, :3] = rotation_about(axis, math.radians(rng.uniform(*turn_deg)))
                previous = poses[-1]
                pose = np.eye(4)
                pose[:3, :3] = previous[:3, :3] @ step[:3, :3]  # about the box's own axis
                pose[:3, 3] = previous[:3, 3] + direction * rng.uniform(*move_mm) / 1000
                poses.append(pose)
            found.append(RigidBox(index + 2, edges, np.stack(poses), []))
        if crossing:
            found.append(_crossing_box(rng, boxes + 2, frames, z - CROSSING_DEPTH, camera,
                                       size, box_size_m, turn_deg))
        if leaving:
            found.append(_leaving_box(rng, len(found) + 2, frames, z - LEAVING_DEPTH, camera,
                                      size, grid, box_size_m, turn_deg))
        if _fits(found, camera, size, parallax, 0.005,
                 frozenset({found[-1].label}) if leaving else frozenset()):
            break
    else:
        raise LfsamError(
            f"cannot place {boxes} boxes of {box_size_m[0]}-{box_size_m[1]} m in a {size[0]}x"
            f"{size[1]} view for {frames} frames; use fewer or smaller boxes or fewer frames"
        )
    tex_seed = int(rng.integers(2**31))
    for box in found:
        names = rng.choice(len(FACE_TEXTURES), size=6, replace=False)
        box.textures = [
            make_texture(FACE_TEXTURES[n], tex_seed + 7 * box.label + face, (texels, texels))
            .permute(1, 2, 0).numpy().astype(np.float64) for face, n in enumerate(names)
        ]
    background = make_texture("noise", tex_seed + 1, (2 * size[0], 2 * size[1])) \
        .permute(1, 2, 0).numpy().astype(np.float64)
    return RigidScene(camera, tuple(grid), tuple(size), float(background_z_m), background,
                      found, int(seed))


def ray_cast(scene: RigidScene, frame: int, offset: tuple[float, float], rows: np.ndarray,
             cols: np.ndarray, colours: bool = True):
    """Cast the rays of pixels ``(rows, cols)`` of the view at ``offset`` = ``(s - s_c, t -
    t_c)`` into ``frame``.

    Returns
    -------
    depth : (N,) float64
        The ray parameter of the nearest hit, which is the depth ``z`` in metres.
    label : (N,) int32
        1 for the background, the box's label otherwise.
    rgb : (N, 3) float64 in [0, 1] or None
        Colours (with ``colours``).
    """
    cam = scene.camera
    cx, cy = cam.principal_point(scene.size)
    ds, dt = offset
    z0 = cam.focus_distance_m
    shift = 0.0 if z0 is None else cam.baseline_m / z0
    rows = np.asarray(rows, dtype=np.float64).ravel()
    cols = np.asarray(cols, dtype=np.float64).ravel()
    n = rows.size
    origin = np.array([cam.baseline_m * dt, cam.baseline_m * ds, 0.0])
    direction = np.stack([(cols - cx) / cam.focal_px - shift * dt,
                          (rows - cy) / cam.focal_px - shift * ds, np.ones(n)], axis=1)
    depth = np.full(n, scene.background_z_m)
    label = np.ones(n, dtype=np.int32)
    face = np.zeros(n, dtype=np.int64)
    local = np.zeros((n, 3))
    which = np.full(n, -1)
    for index, box in enumerate(scene.boxes):
        pose = box.poses[frame]
        rot, trans = pose[:3, :3], pose[:3, 3]
        o = (origin - trans) @ rot  # R^T (O - t)
        d = direction @ rot
        half = box.size_m / 2
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / d
            t1 = (-half - o) * inv
            t2 = (half - o) * inv
        near = np.minimum(t1, t2)
        far = np.maximum(t1, t2)
        enter = near.max(axis=1)
        leave = far.min(axis=1)
        hit = (enter <= leave) & (enter > 0) & (enter < depth)
        depth[hit] = enter[hit]
        label[hit] = box.label
        axis = near[hit].argmax(axis=1)
        sign = d[hit, axis] < 0  # entering through the + face when moving towards -
        face[hit] = 2 * axis + sign
        local[hit] = o + enter[hit, None] * d[hit]
        which[hit] = index
    if not colours:
        return depth, label, None
    rgb = np.empty((n, 3))
    points = origin + depth[:, None] * direction
    back = which < 0
    bg = scene.background
    extent = scene.background_z_m * np.array(scene.size) / cam.focal_px
    tu = (points[back, 1] / extent[0] + 0.5) * (bg.shape[0] - 1)
    tv = (points[back, 0] / extent[1] + 0.5) * (bg.shape[1] - 1)
    rgb[back] = _bilinear(bg, tu, tv)
    for index, box in enumerate(scene.boxes):
        rot = box.poses[frame][:3, :3]
        for f in range(6):
            sel = (which == index) & (face == f)
            if not sel.any():
                continue
            axis, positive = divmod(f, 2)
            a, c = [i for i in range(3) if i != axis]
            tex = box.textures[f]
            half = box.size_m / 2
            tu = np.clip((local[sel, a] / half[a] + 1) / 2, 0, 1) * (tex.shape[0] - 1)
            tv = np.clip((local[sel, c] / half[c] + 1) / 2, 0, 1) * (tex.shape[1] - 1)
            normal = rot[:, axis] * (1.0 if positive else -1.0)
            shade = 0.6 + 0.4 * max(0.0, float(normal @ LIGHT))
            rgb[sel] = _bilinear(tex, tu, tv) * shade
    return depth, label, rgb


def _bilinear(image: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    rows = np.clip(rows, 0, image.shape[0] - 1)
    cols = np.clip(cols, 0, image.shape[1] - 1)
    r0 = np.minimum(np.floor(rows).astype(np.int64), image.shape[0] - 2)
    c0 = np.minimum(np.floor(cols).astype(np.int64), image.shape[1] - 2)
    fr = (rows - r0)[:, None]
    fc = (cols - c0)[:, None]
    return ((1 - fr) * (1 - fc) * image[r0, c0] + (1 - fr) * fc * image[r0, c0 + 1]
            + fr * (1 - fc) * image[r0 + 1, c0] + fr * fc * image[r0 + 1, c0 + 1])


def render_rigid(scene: RigidScene, frame: int, supersample: int = 2) -> LightField:
    """Frame ``frame`` of ``scene`` as a light field with exact per-view disparity and labels
    (at pixel centres), its camera and ``meta["rigid"]`` (module docstring)."""
    s_count, t_count = scene.grid
    height, width = scene.size
    sc, tc = s_count // 2, t_count // 2
    rows, cols = np.meshgrid(np.arange(height, dtype=np.float64),
                             np.arange(width, dtype=np.float64), indexing="ij")
    sub = (np.arange(supersample) + 0.5) / supersample - 0.5
    su, sv = np.meshgrid(sub, sub, indexing="ij")
    srows = (rows[:, :, None, None] + su).ravel()
    scols = (cols[:, :, None, None] + sv).ravel()
    views = np.empty((s_count, t_count, height, width, 3), dtype=np.uint8)
    disparity = np.empty((s_count, t_count, height, width), dtype=np.float32)
    labels = np.empty((s_count, t_count, height, width), dtype=np.int32)
    for s in range(s_count):
        for t in range(t_count):
            offset = (float(s - sc), float(t - tc))
            depth, label, _ = ray_cast(scene, frame, offset, rows, cols, colours=False)
            disparity[s, t] = disparity_from_depth(depth, scene.camera).reshape(height, width)
            labels[s, t] = label.reshape(height, width)
            _, _, rgb = ray_cast(scene, frame, offset, srows, scols)
            rgb = rgb.reshape(height, width, supersample * supersample, 3).mean(axis=2)
            views[s, t] = np.clip(np.round(rgb * 255), 0, 255).astype(np.uint8)
    meta = {
        "source": f"synthetic rigid boxes (seed {scene.seed}, frame {frame})",
        "format": "synth",
        "orientation": "package convention (generated)",
        "seed": scene.seed,
        "frame": int(frame),
        "camera": scene.camera.to_json(),
        "rigid": scene.describe(frame),
    }
    categories = {1: "background", **{box.label: "box" for box in scene.boxes}}
    return LightField(views, disparity=disparity, labels=labels, meta=meta,
                      categories=categories)


def generate_rigid_video(supersample: int = 2, **options) -> Iterator[LightField]:
    """Render every frame of :func:`rigid_scenes` (``options``) one after another.

    Examples
    --------
    >>> video = list(generate_rigid_video(boxes=1, frames=2, grid=(3, 3), size=(96, 128),
    ...                                   box_size_m=(0.06, 0.08), texels=32))
    >>> len(video), video[1].labels.shape, sorted(video[1].meta["rigid"]["objects"][0])[:3]
    (2, (3, 3, 96, 128), ['category', 'diameter_m', 'label'])
    """
    scene = rigid_scenes(**options)
    for frame in range(scene.frames):
        yield render_rigid(scene, frame, supersample=supersample)
