"""The SAM 2 video-tracking baseline end to end on the tiny SAM 2 (paper section 4).

The tiny model has random weights, so its tracked masks are meaningless away from the start view;
what is checked exactly is the plumbing: which pixels reach the tracker and in which order, which
object ends up in which slot and label, passes, metadata, the result file and its readers. To
know the start masks exactly, the start view is segmented by a SAM 2 segmenter whose prompt and
generation answers come from the ground truth (the tracker itself is Meta's, with the tiny
model's weights).
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from PIL import Image

from lfsam.baseline import video_baseline, video_predictor_for
from lfsam.cli.main import main
from lfsam.errors import LfsamError
from lfsam.io import write_lightfield
from lfsam.metrics import evaluate_labels
from lfsam.result import load_result, save_result
from lfsam.segmenters import Prompts, load_segmenter
from lfsam.segmenters.oracle import OracleSegmenter
from lfsam.segmenters.sam2.backend import Sam2Segmenter
from lfsam.synth import generate_scene

GRID, SIZE = (3, 3), (32, 48)
SNAKE_3X3 = [(0, 0), (0, 1), (0, 2), (1, 2), (1, 1), (1, 0), (2, 0), (2, 1), (2, 2)]


class GroundTruthStartSegmenter(Sam2Segmenter):
    """Tiny SAM 2 whose prompt answers and automatic masks come from the ground truth."""

    oracle: OracleSegmenter

    def encode(self, images, keys=None):
        embeddings = super().encode(images, keys)
        for embedding in embeddings:
            embedding.oracle = self.oracle.encode(images[:1], keys=[embedding.key])[0]
        return embeddings

    def predict(self, embedding, prompts, multimask_output=True):
        return self.oracle.predict(embedding.oracle, prompts, multimask_output)

    def generate(self, embedding, image, points=None):
        return self.oracle.generate(embedding.oracle, image, points=points)


@pytest.fixture(scope="module")
def lightfield():
    return generate_scene(grid=GRID, size=SIZE, seed=0, num_objects=2)


@pytest.fixture(scope="module")
def tiny():
    return load_segmenter("sam2-tiny-test", random_weights=True, device="cpu")


@pytest.fixture(scope="module")
def gt_segmenter(tiny, lightfield):
    segmenter = GroundTruthStartSegmenter(tiny.model)
    segmenter.oracle = OracleSegmenter(lightfield, device="cpu")
    return segmenter


def _run_recording(lightfield, segmenter, **options):
    """Run the baseline, recording every image the video predictor's encoder receives."""
    from sam2.sam2_video_predictor import SAM2VideoPredictor

    seen = []
    original = SAM2VideoPredictor.forward_image

    def recording(self, img_batch):
        seen.append(img_batch.detach().clone())
        return original(self, img_batch)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(SAM2VideoPredictor, "forward_image", recording)
        result = video_baseline(lightfield, segmenter, progress=False, **options)
    return result, seen


@pytest.fixture(scope="module")
def first_run(lightfield, gt_segmenter):
    """Paper setting: automatic masks on the first view, tracked forward, 2 objects a pass."""
    return _run_recording(lightfield, gt_segmenter, objects_per_pass=2, start="first")


@pytest.fixture(scope="module")
def center_run(lightfield, gt_segmenter):
    """Fair setting: center-view point prompts, tracked both ways, in one pass."""
    points = _object_points(lightfield)
    prompts = [Prompts(points=points[:, None, :], point_labels=np.ones((len(points), 1)))]
    return _run_recording(
        lightfield, gt_segmenter, prompts=prompts, objects_per_pass=2, start="center"
    )


def _object_points(lightfield):
    """One point deep inside each of the two largest center-view regions (column, row)."""
    from scipy.ndimage import distance_transform_edt

    labels = lightfield.center_labels
    ids, areas = np.unique(labels, return_counts=True)
    points = []
    for label in ids[np.argsort(-areas)][:2]:
        depth = distance_transform_edt(labels == label)
        row, col = np.unravel_index(np.argmax(depth), depth.shape)
        points.append((col, row))
    return np.array(points, dtype=np.float32)


def _sam2_frames(views, folder, image_size):
    """SAM 2's own loader on the views in the given order, saved losslessly."""
    from sam2.utils.misc import load_video_frames

    folder.mkdir()
    for index, view in enumerate(views):
        Image.fromarray(view).save(folder / f"{index}.jpg", format="PNG")
    frames, _, _ = load_video_frames(str(folder), image_size, offload_video_to_cpu=True)
    return frames


def _iou(a, b):
    return np.logical_and(a, b).sum() / max(np.logical_or(a, b).sum(), 1)


# --- what reaches the tracker ---------------------------------------------------------------
def test_tracker_gets_unchanged_views_in_snake_order(first_run, lightfield, tmp_path):
    _, seen = first_run
    expected = _sam2_frames([lightfield.views[st] for st in SNAKE_3X3], tmp_path / "f", 256)
    # Two passes, each encoding the start frame (adding masks) and then frames 1..8 in order.
    assert len(seen) == 2 * 9
    for index, image in enumerate(seen):
        assert image.shape == (1, 3, 256, 256)
        assert torch.equal(image[0], expected[index % 9]), f"frame {index % 9} differs"


def test_center_start_tracks_forward_then_back(center_run, lightfield, tmp_path):
    _, seen = center_run
    expected = _sam2_frames([lightfield.views[st] for st in SNAKE_3X3], tmp_path / "f", 256)
    per_pass = [4, 5, 6, 7, 8, 3, 2, 1, 0]  # center (1, 1) is frame 4 of the snake
    assert len(seen) == len(per_pass)
    for image, frame in zip(seen, per_pass, strict=True):
        assert torch.equal(image[0], expected[frame]), f"frame {frame} differs"


# --- objects, labels, passes ----------------------------------------------------------------
def test_start_view_objects_keep_their_slots_and_labels(first_run, lightfield):
    result, _ = first_run
    gt = lightfield.labels[0, 0]
    ids, areas = np.unique(gt, return_counts=True)
    by_area = ids[np.argsort(-areas, kind="stable")]  # automatic masks: larger first
    assert result.num_masks == len(ids) == 3
    tracked = result.masks.view(0, 0)
    for n, label in enumerate(by_area):
        assert _iou(tracked[n], gt == label) > 0.85, n
    # Non-overlapping start masks: the label field is the ground truth renumbered by area.
    expected = np.zeros_like(gt)
    for n, label in enumerate(by_area):
        expected[gt == label] = n + 1
    assert np.mean(result.labels[0, 0] == expected) > 0.9
    np.testing.assert_array_equal(result.scores, np.ones(3, np.float32))


def test_prompted_objects_follow_prompt_order(center_run, lightfield):
    result, _ = center_run
    gt = lightfield.center_labels
    tracked = result.masks.view(*lightfield.center)
    for n, (col, row) in enumerate(_object_points(lightfield)):
        assert _iou(tracked[n], gt == gt[int(row), int(col)]) > 0.85, n
    assert result.meta["start_view"] == [1, 1] and result.meta["passes"] == 1


@pytest.mark.parametrize("disparity", [None, "estimate"])
def test_center_prompts_carried_to_the_first_view_select_the_same_objects(
    gt_segmenter, lightfield, disparity
):
    points = _object_points(lightfield)
    prompts = [Prompts(points=points[:, None, :], point_labels=np.ones((len(points), 1)))]
    result = video_baseline(lightfield, gt_segmenter, prompts=prompts, start="first",
                            disparity=disparity, objects_per_pass=2, progress=False)
    source = result.meta["disparity_source"]
    assert source == "gt" if disparity is None else source.startswith("estimate")
    first = result.masks.view(0, 0)
    for n, (col, row) in enumerate(points):
        label = lightfield.center_labels[int(row), int(col)]
        assert _iou(first[n], lightfield.labels[0, 0] == label) > 0.85, n


def test_result_format_and_metadata(first_run):
    result, _ = first_run
    n = result.num_masks
    assert result.labels.shape == (*GRID, *SIZE) and result.labels.dtype == np.int32
    assert result.masks.shape == (n, *GRID, *SIZE)
    assert result.labels.max() <= n
    assert result.fallback.shape == (n, *GRID) and not result.fallback.any()
    assert np.isnan(result.refine_iou).all()
    meta = result.meta
    assert meta["method"] == "video-baseline"
    assert meta["objects_per_pass"] == 2 and meta["passes"] == 2 and meta["start"] == "first"
    assert meta["frame_order"] == [list(st) for st in SNAKE_3X3]
    assert meta["segmenter"]["name"] == "sam2-tiny-test"
    assert meta["segmenter"]["random_weights"] is True
    stages = {k: v for k, v in result.timings.items() if k != "total"}
    assert {"initial", "frames", "tracking", "fuse"} <= set(stages)
    assert all(v >= 0 for v in stages.values())
    assert sum(stages.values()) <= result.timings["total"] + 1e-6


def test_result_file_metrics_and_show(first_run, lightfield, tmp_path):
    result, _ = first_run
    out = save_result(result, tmp_path / "baseline.npz")
    loaded = load_result(out)
    np.testing.assert_array_equal(loaded.labels, result.labels)
    np.testing.assert_array_equal(loaded.masks.data, result.masks.data)
    assert loaded.meta["method"] == "video-baseline"
    metrics = evaluate_labels(loaded.labels, lightfield, loaded.timings)
    assert 0.0 <= metrics["coverage"] <= 1.0 and 0.0 <= metrics["aa"] <= 1.0
    total = loaded.timings["total"]
    assert loaded.ms_per_mask_view == pytest.approx(1000 * total / (loaded.num_masks * 9))
    scene = write_lightfield(lightfield, tmp_path / "scene")
    figure = tmp_path / "grid.png"
    code = main(["show", str(out), "--lightfield", str(scene), "--out", str(figure)])
    assert code == 0 and figure.stat().st_size > 0


def test_no_masks_gives_an_empty_result(tiny, lightfield):
    class Nothing(GroundTruthStartSegmenter):
        def generate(self, embedding, image, points=None):
            from lfsam.segmenters import AutoMasks

            return AutoMasks(masks=np.zeros((0, *SIZE), bool), scores=np.zeros(0, np.float32))

    segmenter = Nothing(tiny.model)
    segmenter.oracle = OracleSegmenter(lightfield, device="cpu")
    result = video_baseline(lightfield, segmenter, progress=False)
    assert result.num_masks == 0 and not result.labels.any() and result.meta["passes"] == 0


# --- same network, errors -------------------------------------------------------------------
def test_video_predictor_shares_the_image_models_weights(tiny):
    predictor = video_predictor_for(tiny)
    assert predictor is video_predictor_for(tiny)  # built once per image model
    image_state, video_state = tiny.model.state_dict(), predictor.state_dict()
    assert set(image_state) == set(video_state)
    for key, tensor in image_state.items():
        assert video_state[key].data_ptr() == tensor.data_ptr(), key
    assert type(predictor).__name__ == "SAM2VideoPredictor"


def test_oracle_cannot_track(lightfield):
    with pytest.raises(LfsamError, match="SAM 2"):
        video_baseline(lightfield, OracleSegmenter(lightfield), progress=False)


@pytest.mark.parametrize(
    "options, message",
    [
        ({"start": "middle"}, "baseline start"),
        ({"objects_per_pass": 0}, "objects-per-pass"),
        ({"frame_transform": "jpeg"}, "frame transform"),
    ],
)
def test_bad_options_are_user_errors(tiny, lightfield, options, message):
    with pytest.raises(LfsamError, match=message):
        video_baseline(lightfield, tiny, progress=False, **options)


def test_prompts_outside_the_center_view_are_rejected_before_transfer(tiny, lightfield):
    prompts = [Prompts(points=[[[500.0, 10.0]]], point_labels=[[1]])]
    with pytest.raises(LfsamError, match="outside the center view"):
        video_baseline(lightfield, tiny, prompts=prompts, start="first", progress=False)


# --- command line ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def scene_dir(lightfield, tmp_path_factory):
    return write_lightfield(lightfield, tmp_path_factory.mktemp("cli") / "scene")


def test_cli_video_baseline_with_points(scene_dir, tmp_path, capsys):
    out = tmp_path / "baseline.npz"
    code = main(
        ["segment", str(scene_dir), "--method", "video-baseline", "--model", "sam2-tiny-test",
         "--random-weights", "--point", "24,16", "--objects-per-pass", "1", "--disparity", "gt",
         "--out", str(out), "--quiet"]
    )
    assert code == 0
    result = load_result(out)
    assert result.meta["method"] == "video-baseline" and result.meta["start"] == "first"
    assert result.meta["disparity_source"] == "gt"  # --disparity gt moved the point
    assert result.num_masks == 1 and result.labels.shape == (*GRID, *SIZE)


def test_cli_oracle_video_baseline_is_one_line_error(scene_dir, tmp_path, capsys):
    out = tmp_path / "r.npz"
    code = main(["segment", str(scene_dir), "--method", "video-baseline", "--model", "oracle",
                 "--auto", "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("lfsam: error:")
    assert "SAM 2" in err[0] and not out.exists()
