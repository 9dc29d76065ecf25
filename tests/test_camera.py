"""The light-field camera (lfsam.camera; docs/design.md section 11): depth from disparity, the HCI
4D benchmark's conversion, back-projection from any view, and the camera sources."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lfsam.camera import (
    Camera,
    back_project,
    camera_from_hci,
    camera_of,
    depth_from_disparity,
    disparity_from_depth,
    load_camera,
    synthetic_camera,
)
from lfsam.errors import LfsamError
from lfsam.io import read_lightfield, write_lightfield
from lfsam.synth import generate_scene

#: An HCI 4D scene's parameters.cfg in the benchmark's layout (values of the kind its
#: "additional" scenes such as antinous carry: 9x9 views of 512x512, 100 mm lens, 35 mm sensor).
HCI_CFG = """\
[intrinsics]
focal_length_mm = 100
image_resolution_x_px = 512
image_resolution_y_px = 512
sensor_size_mm = 35
fstop = 100

[extrinsics]
focus_distance_m = 8.5
center_cam_x_m = 0.0
center_cam_y_m = 0.0
center_cam_z_m = 0.0
center_cam_rx_rad = 0.0
center_cam_ry_rad = 0.0
center_cam_rz_rad = 0.0
baseline_mm = 90.0
num_cams_x = 9
num_cams_y = 9
offset = 0.0

[meta]
disp_min = -3.0
disp_max = 3.0
frustum_disp_min = -3.0
frustum_disp_max = 3.0
depth_map_scale = 10.0
"""


def hci_toolkit_disp2depth(disp, baseline_mm, focal_length_mm, sensor_mm, width, height,
                           focus_dist_m):
    """The benchmark toolkit's own conversion, written as it states it (depth in metres)."""
    q = baseline_mm * focal_length_mm * max(width, height)
    return 1.0 / ((1000.0 * sensor_mm) * disp / q + (1.0 / focus_dist_m))


def test_depth_matches_the_hci_toolkit_on_antinous_style_parameters(tmp_path):
    (tmp_path / "parameters.cfg").write_text(HCI_CFG)
    from lfsam.io.hci4d import read_parameters

    camera = camera_from_hci(read_parameters(tmp_path / "parameters.cfg"))
    disparity = np.linspace(-3.0, 3.0, 61)
    ours = depth_from_disparity(disparity, camera)
    theirs = hci_toolkit_disp2depth(disparity, 90.0, 100.0, 35.0, 512, 512, 8.5)
    np.testing.assert_allclose(ours, theirs, rtol=1e-12)
    assert camera.focal_px == pytest.approx(100 * 512 / 35)


def test_hci_scene_folder_carries_its_camera(tmp_path, shared_data):
    scene = tmp_path / "antinous"
    scene.mkdir()
    for path in (shared_data / "hci_antinous").iterdir():
        (scene / path.name).symlink_to(path)
    assert camera_of(read_lightfield(scene).meta) is None  # no parameters.cfg: no camera
    (scene / "parameters.cfg").write_text(HCI_CFG)
    camera = camera_of(read_lightfield(scene).meta)
    assert camera.baseline_m == pytest.approx(0.09) and camera.focus_distance_m == 8.5


def test_missing_hci_parameters_are_named():
    with pytest.raises(LfsamError, match="baseline_mm"):
        camera_from_hci({"intrinsics": {"focal_length_mm": 100, "sensor_size_mm": 35,
                                        "image_resolution_x_px": 512,
                                        "image_resolution_y_px": 512}})


@settings(max_examples=200, deadline=None)
@given(
    z=st.floats(0.2, 20.0),
    focal=st.floats(50.0, 2000.0),
    baseline=st.floats(0.001, 0.2),
    z0=st.one_of(st.none(), st.floats(0.3, 30.0)),
)
def test_depth_and_disparity_are_inverse(z, focal, baseline, z0):
    camera = Camera(focal_px=focal, baseline_m=baseline, focus_distance_m=z0)
    d = disparity_from_depth(z, camera)
    assert float(depth_from_disparity(d, camera)) == pytest.approx(z, rel=1e-9)
    # larger disparity = closer (docs/design.md section 1)
    assert float(disparity_from_depth(z * 1.1, camera)) < float(d)


def test_beyond_infinity_has_no_depth():
    camera = Camera(focal_px=100.0, baseline_m=0.01, focus_distance_m=1.0)  # f b / z0 = 1
    assert np.isnan(depth_from_disparity([-1.0, -2.0], camera)).all()
    assert np.isnan(depth_from_disparity(0.0, Camera(focal_px=100.0, baseline_m=0.01)))


@settings(max_examples=200, deadline=None)
@given(
    x=st.floats(-1.0, 1.0), y=st.floats(-1.0, 1.0), z=st.floats(0.5, 5.0),
    ds=st.integers(-4, 4), dt=st.integers(-4, 4),
    z0=st.one_of(st.none(), st.floats(0.5, 10.0)),
)
def test_back_projection_inverts_a_pinhole_grid(x, y, z, ds, dt, z0):
    """A point projected into view (s, t) of a grid of pinholes (an independent forward model:
    cameras at (b dt, b ds, 0), sensors shifted so points at z0 have zero disparity) and
    back-projected from that view is the same point in the center camera's frame."""
    camera = Camera(focal_px=400.0, baseline_m=0.02, focus_distance_m=z0)
    size = (240, 320)
    cx, cy = (size[1] - 1) / 2, (size[0] - 1) / 2
    f, b = camera.focal_px, camera.baseline_m
    shift = 0.0 if z0 is None else f * b / z0
    v = f * (x - b * dt) / z + cx + shift * dt
    u = f * (y - b * ds) / z + cy + shift * ds
    d = f * b / z - shift
    point = back_project([u], [v], [d], camera, size, view_offset=(ds, dt))[0]
    np.testing.assert_allclose(point, [x, y, z], atol=1e-9)


def test_camera_file(tmp_path):
    path = tmp_path / "camera.json"
    path.write_text(json.dumps({"focal_px": 700, "baseline_m": 0.01, "focus_distance_m": 1.2}))
    assert load_camera(path) == Camera(700.0, 0.01, 1.2)
    path.write_text(json.dumps({"focal_px": 700}))
    with pytest.raises(LfsamError, match="lacks baseline_m"):
        load_camera(path)
    path.write_text("{not json")
    with pytest.raises(LfsamError, match="cannot read camera file"):
        load_camera(path)
    with pytest.raises(LfsamError, match="not found"):
        load_camera(tmp_path / "none.json")
    with pytest.raises(LfsamError, match="positive"):
        Camera(focal_px=-1.0, baseline_m=0.01)


def test_synthetic_scenes_carry_a_camera_through_their_folder(tmp_path):
    lf = generate_scene(grid=(3, 3), size=(32, 48), seed=2, num_objects=2,
                        disparity_range=(-3.0, 1.5))
    camera = camera_of(lf.meta)
    assert camera == synthetic_camera((32, 48), (-3.0, 1.5))
    depth = depth_from_disparity(lf.disparity, camera)
    assert np.isfinite(depth).all() and depth.max() <= 2.0 + 1e-6
    folder = write_lightfield(lf, tmp_path / "scene")
    assert json.loads((folder / "lfsam_scene.json").read_text())["camera"]["focal_px"] == 48.0
    assert camera_of(read_lightfield(folder).meta) == camera


def test_parameters_cfg_beside_a_light_field_of_another_format(tmp_path):
    from lfsam.objects3d import resolve_camera

    lf = generate_scene(grid=(3, 3), size=(24, 32), seed=0, num_objects=1)
    del lf.meta["camera"]
    path = write_lightfield(lf, tmp_path / "scene.npz")
    loaded = read_lightfield(path)
    with pytest.raises(LfsamError, match="focal_px"):
        resolve_camera(loaded)
    (tmp_path / "parameters.cfg").write_text(HCI_CFG)
    assert resolve_camera(loaded).focus_distance_m == 8.5
    assert resolve_camera(loaded, Camera(1.0, 1.0)) == Camera(1.0, 1.0)  # given wins
