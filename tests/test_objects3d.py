"""Objects in 3D (issue 37; docs/design.md section 11): point clouds, measures and trajectories
against exact synthetic ground truth, through the library and the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest
from plyfile import PlyData

from lfsam.camera import camera_of
from lfsam.cli.main import main
from lfsam.errors import LfsamError
from lfsam.io import read_lightfield, write_lightfield
from lfsam.objects3d import objects_in_3d, objects_over_video
from lfsam.result import SegmentationResult, save_result
from lfsam.spatial import read_ply, write_ply
from lfsam.synth import generate_scene
from lfsam.video.io.synth import generate_video, write_video_frames


def truth_points(lf, object_label: int) -> np.ndarray:
    """The object's exact 3D points in the center view, computed here from the ground truth
    (z = f b / (d + f b / z0), x = (v - c_x) z / f, y = (u - c_y) z / f)."""
    camera = camera_of(lf.meta)
    center = lf.center
    rows, cols = np.nonzero(lf.labels[center] == object_label)
    d = lf.disparity[center][rows, cols].astype(np.float64)
    fb = camera.focal_px * camera.baseline_m
    z = fb / (d + fb / camera.focus_distance_m)
    cy, cx = (lf.view_shape[0] - 1) / 2, (lf.view_shape[1] - 1) / 2
    return np.stack([(cols - cx) * z / camera.focal_px, (rows - cy) * z / camera.focal_px, z], 1)


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """A 9x9 synthetic scene with ground truth, its folder, and a result of its true labels
    (objects only: the background wall is no object here)."""
    folder = tmp_path_factory.mktemp("objects3d")
    lf = generate_scene(grid=(9, 9), size=(96, 128), seed=0, num_objects=5,
                        label_background=False)
    write_lightfield(lf, folder / "scene")
    save_result(SegmentationResult(labels=lf.labels), folder / "result.npz")
    return lf, folder


def test_ply_per_object_median_depth_within_1_percent(scene, tmp_path):
    """The issue's check: one PLY per object, estimated disparity, median depth within 1 % of
    the ground truth's; read back with plyfile."""
    lf, folder = scene
    out = tmp_path / "clouds"
    code = main(["export", str(folder / "result.npz"), "--to", "ply",
                 "--lightfield", str(folder / "scene"), "--out", str(out)])
    assert code == 0
    labels = [int(i) for i in np.unique(lf.labels[lf.center]) if i]
    assert sorted(p.name for p in out.glob("*.ply")) == [f"object_{i:04d}.ply" for i in labels]
    for label in labels:
        data = PlyData.read(str(out / f"object_{label:04d}.ply"))
        vertex = data["vertex"]
        assert data.text is False and data.byte_order == "<"
        assert [p.name for p in vertex.properties] == ["x", "y", "z", "red", "green", "blue"]
        z = np.asarray(vertex["z"], dtype=np.float64)
        truth = truth_points(lf, label)
        assert 0.5 * len(truth) <= len(z) <= len(truth)  # confident pixels only
        assert np.median(z) == pytest.approx(np.median(truth[:, 2]), rel=0.01)
    summary = json.loads((out / "objects.json").read_text())
    assert summary["disparity"] == "estimate" and len(summary["objects"]) == len(labels)


def test_centroids_and_depth_errors(scene):
    lf, _ = scene
    found = objects_in_3d(SegmentationResult(labels=lf.labels), lf)  # estimate
    for measure in found.measures:
        truth = truth_points(lf, measure.object_id)
        assert measure.centroid_m[2] == pytest.approx(truth[:, 2].mean(), rel=0.02)
        assert measure.pixels == len(truth)
        # against the ground truth the light field carries
        assert measure.median_depth_relative_error < 0.01
        assert measure.gt_median_depth_m == pytest.approx(np.median(truth[:, 2]), rel=1e-6)
        assert measure.box is not None and (measure.box.size > 0).all()
    exact = objects_in_3d(SegmentationResult(labels=lf.labels), lf, disparity="gt")
    for measure in exact.measures:
        truth = truth_points(lf, measure.object_id)
        np.testing.assert_allclose(measure.centroid_m, truth.mean(axis=0), rtol=1e-6, atol=1e-9)
        assert measure.gt_median_depth_m is None  # no second disparity to compare with
        assert measure.confident_share == 1.0


def test_an_object_hidden_in_the_center_view_gets_points_from_the_others():
    lf = generate_scene(grid=(5, 5), size=(64, 80), seed=4, num_objects=3, hidden_objects=1)
    hidden = lf.meta["generator"]["hidden_labels"][0]
    result = SegmentationResult(labels=lf.labels)
    center_only = objects_in_3d(result, lf, disparity="gt")
    by_id = {m.object_id: m for m in center_only.measures}
    assert by_id[hidden].pixels == 0 and by_id[hidden].points == 0
    everywhere = objects_in_3d(result, lf, disparity="gt", views="all")
    cloud = everywhere.clouds[hidden]
    assert len(cloud.xyz) > 0
    # every point of the hidden object projects back onto itself in the center camera: its z
    # is the one its disparity gives, the same from whichever view it came
    camera = everywhere.camera
    depth = camera.focal_px * camera.baseline_m / (cloud.disparity + camera.zero_disparity_offset)
    np.testing.assert_allclose(cloud.xyz[:, 2], depth, rtol=1e-9)


def test_no_camera_is_one_line(scene, tmp_path, capsys):
    lf, folder = scene
    bare = read_lightfield(folder / "scene")
    del bare.meta["camera"]
    write_lightfield(bare, tmp_path / "bare")
    code = main(["objects", str(folder / "result.npz"), "--lightfield", str(tmp_path / "bare"),
                 "--disparity", "gt"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1
    assert "focal_px" in err and "baseline_m" in err and "--camera" in err
    camera = tmp_path / "camera.json"
    camera.write_text(json.dumps(lf.meta["camera"]))
    assert main(["objects", str(folder / "result.npz"), "--lightfield", str(tmp_path / "bare"),
                 "--disparity", "gt", "--camera", str(camera)]) == 0
    with pytest.raises(LfsamError, match="--camera"):
        objects_in_3d(SegmentationResult(labels=lf.labels), bare, disparity="gt")


def test_objects_command_json_csv(scene, tmp_path, capsys):
    _, folder = scene
    out_json, out_csv = tmp_path / "o.json", tmp_path / "o.csv"
    code = main(["objects", str(folder / "result.npz"), "--lightfield", str(folder / "scene"),
                 "--disparity", "gt", "--json", str(out_json), "--csv", str(out_csv)])
    assert code == 0
    table = capsys.readouterr().out
    data = json.loads(out_json.read_text())
    assert data["camera"]["focus_distance_m"] == 1.0
    rows = out_csv.read_text().splitlines()
    assert len(rows) == 1 + len(data["objects"])
    for entry in data["objects"]:
        assert f"\n{entry['id']:>5} " in table
        assert entry["extent"]["size_m"][0] >= entry["extent"]["size_m"][1]


def test_unwritable_json_is_refused_before_work(scene, capsys):
    _, folder = scene
    code = main(["objects", str(folder / "result.npz"), "--lightfield", str(folder / "scene"),
                 "--json", "/proc/objects.json"])
    assert code == 2 and "--json" in capsys.readouterr().err


def test_ply_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    xyz = rng.normal(size=(500, 3)).astype(np.float32)
    rgb = rng.integers(0, 256, (500, 3)).astype(np.uint8)
    path = write_ply(tmp_path / "p.ply", xyz, rgb, comments=["units: metres"])
    back_xyz, back_rgb = read_ply(path)
    np.testing.assert_array_equal(back_xyz, xyz)
    np.testing.assert_array_equal(back_rgb, rgb)
    data = PlyData.read(str(path))
    np.testing.assert_array_equal(np.asarray(data["vertex"]["green"]), rgb[:, 1])
    assert "units: metres" in data.comments
    path.write_bytes(path.read_bytes()[:-7])
    with pytest.raises(LfsamError, match="truncated"):
        read_ply(path)


def test_video_trajectory_of_objects_moving_in_depth(tmp_path, capsys):
    """Frames whose objects move in depth: the trajectory's z per frame is the ground truth's
    mean depth (exactly with the ground-truth disparity; within 3 % with the estimate on these
    small 7x7 frames of 80x112, where objects have a few hundred pixels), and the speeds are
    the centroids' steps times the frame rate."""
    frames = list(generate_video(grid=(7, 7), size=(80, 112), frames=4, seed=1, num_objects=2))
    pairs = [(SegmentationResult(labels=lf.labels), lf) for lf in frames]
    _, exact = objects_over_video(pairs, fps=10.0, disparity="gt")
    truth = {p.object_id: [truth_points(lf, p.object_id)[:, 2].mean() for lf in frames]
             for p in exact if len(p.frames) == len(frames) and p.object_id != 1}
    label = max(truth, key=lambda i: np.ptp(truth[i]))  # the object that moves most in depth
    assert np.ptp(truth[label]) > 0.1  # it does move in depth: over 10 cm
    path = next(p for p in exact if p.object_id == label)
    np.testing.assert_allclose(path.positions[:, 2], truth[label], rtol=1e-9)
    steps = np.linalg.norm(np.diff(path.positions, axis=0), axis=1) * 10.0
    np.testing.assert_allclose(path.speeds[1:], steps, rtol=1e-9)
    assert np.isnan(path.speeds[0])
    _, estimated = objects_over_video(pairs, fps=10.0)
    path = next(p for p in estimated if p.object_id == label)
    np.testing.assert_allclose(path.positions[:, 2], truth[label], rtol=0.03)
    # the command on a video result folder and its video
    video = write_video_frames(iter(frames), tmp_path / "video")
    assert main(["segment", str(video), "--model", "oracle", "--auto", "--disparity", "gt",
                 "--out", str(tmp_path / "tracked"), "--quiet"]) == 0
    capsys.readouterr()
    code = main(["objects", str(tmp_path / "tracked"), "--lightfield", str(video),
                 "--disparity", "gt", "--fps", "10", "--csv", str(tmp_path / "t.csv"),
                 "--json", str(tmp_path / "t.json")])
    assert code == 0
    out = capsys.readouterr().out
    assert "trajectories (m/s):" in out and "frame 3:" in out
    data = json.loads((tmp_path / "t.json").read_text())
    assert len(data["frames"]) == 4 and data["trajectories"]
    assert (tmp_path / "t.csv").read_text().startswith("id,category,frame,x_m,y_m,z_m")


def test_ply_export_of_a_video_and_without_light_field(tmp_path, capsys):
    frames = list(generate_video(grid=(3, 3), size=(32, 40), frames=2, seed=2, num_objects=1))
    video = write_video_frames(iter(frames), tmp_path / "video")
    assert main(["segment", str(video), "--model", "oracle", "--auto", "--disparity", "gt",
                 "--out", str(tmp_path / "tracked"), "--quiet"]) == 0
    out = tmp_path / "clouds"
    assert main(["export", str(tmp_path / "tracked"), "--to", "ply", "--lightfield", str(video),
                 "--disparity", "gt", "--out", str(out)]) == 0
    for index, lf in enumerate(frames):
        names = sorted(p.name for p in (out / f"frame_{index:04d}").glob("object_*.ply"))
        assert len(names) == len(np.unique(lf.labels[lf.center]))
        xyz, _ = read_ply(out / f"frame_{index:04d}" / names[0])
        assert np.isfinite(xyz).all() and (xyz[:, 2] > 0).all()
    capsys.readouterr()
    code = main(["export", str(tmp_path / "tracked"), "--to", "ply", "--out",
                 str(tmp_path / "none")])
    assert code == 2 and "--lightfield" in capsys.readouterr().err
    assert not (tmp_path / "none").exists()


def test_views_all_with_an_estimate_estimates_each_view_once(monkeypatch):
    """``views="all"`` with an estimated disparity (issue 46): the range is found once, each
    view estimated once, and a second call on the same light field estimates nothing; each
    view's disparity is the estimator's own with that range."""
    import lfsam.objects3d as O
    from lfsam.disparity import estimate_disparity
    from lfsam.disparity.range import estimate_disparity_range

    lf = generate_scene(grid=(5, 5), size=(64, 80), seed=4, num_objects=3, hidden_objects=1)
    hidden = lf.meta["generator"]["hidden_labels"][0]
    calls = {"range": 0, "views": []}

    def counted_range(*args, **kwargs):
        calls["range"] += 1
        return estimate_disparity_range(*args, **kwargs)

    def counted(lightfield, disparity_range=None, **kwargs):
        calls["views"].append(kwargs["view"])
        return estimate_disparity(lightfield, disparity_range, **kwargs)

    monkeypatch.setattr(O, "estimate_disparity_range", counted_range)
    monkeypatch.setattr(O, "estimate_disparity", counted)
    result = SegmentationResult(labels=lf.labels)
    first = objects_in_3d(result, lf, views="all", device="cpu")
    assert calls["range"] == 1 and sorted(calls["views"]) == [(s, t) for s in range(5)
                                                              for t in range(5)]
    again = objects_in_3d(result, lf, views="all", device="cpu")
    center = objects_in_3d(result, lf, device="cpu")  # the center's estimate is kept too
    assert calls["range"] == 1 and len(calls["views"]) == 25
    for obj_id, cloud in first.clouds.items():
        np.testing.assert_array_equal(cloud.xyz, again.clouds[obj_id].xyz)
    # the center view does not see the hidden object. Whether any other view's estimate is
    # confident on it is not asserted: it is a sliver of 2-20 px per view at the frame's top
    # border here, estimated 2.3-2.6 px off in every view; until issue 45's border windows one
    # such pixel (1.73 against a true -0.56, confidence 0.15) passed the 0.1 threshold
    assert len(center.clouds[hidden].xyz) == 0
    kept = O.estimates_for(lf, "cpu")
    span = estimate_disparity_range(lf, device="cpu", view=lf.center)
    direct = estimate_disparity(lf, span, device="cpu", view=(0, 2))
    np.testing.assert_array_equal(kept((0, 2))[0], direct.disparity)
    assert kept.estimated == 25
