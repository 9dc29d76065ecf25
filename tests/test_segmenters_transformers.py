"""The transformers backend (issue 34; docs/design.md section 3.8): EdgeTAM and transformers-format
SAM 2 folders behind lfsam's segmenter interface.

- lfsam's masks for a click are those of transformers' own processor + model call;
- Meta's SAM 2 and transformers' ``Sam2Model`` fed the same random weights give the same masks
  through lfsam's two backends;
- the tiny EdgeTAM runs the whole pipeline (clicks, --auto, sparse views, the cache, videos);
- what a user sees: ``lfsam models``, ``--checkpoint DIR`` without ``--model``, one-line errors
  offline and for folders of the wrong kind;
- SAM (v1) folders (``model_type: sam``): the padded geometry gives transformers' own pixels,
  logits, IoU predictions and masks on non-square views, and the whole pipeline runs.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

import lfsam
from lfsam.cli.main import main
from lfsam.errors import LfsamError
from lfsam.io import write_lightfield
from lfsam.result import load_result
from lfsam.segmenters import load_segmenter
from lfsam.segmenters.base import Prompts
from lfsam.segmenters.registry import TRANSFORMERS_MODELS
from lfsam.segmenters.sam2.adapter import image_transforms
from lfsam.segmenters.sam2.backend import Sam2Segmenter
from lfsam.segmenters.sam2.build import build_sam2
from lfsam.segmenters.transformers.backend import TransformersSegmenter
from lfsam.segmenters.transformers.build import edgetam_config, tiny_edgetam_config
from lfsam.segmenters.transformers.convert import sam2_to_transformers
from lfsam.segmenters.transformers.sam1 import PaddedTransforms, preprocess_padded, view_grid
from lfsam.synth import generate_scene


def _perturbed_meta_tiny(seed: int = 3) -> torch.nn.Module:
    """sam2-tiny-test with seeded noise on every weight (no parameter left at a constant)."""
    model = build_sam2("sam2-tiny-test", random_weights=True, device="cpu", seed=seed)
    gen = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for tensor in [*model.parameters(), *model.buffers()]:
            if tensor.is_floating_point():
                tensor.add_(0.05 * torch.randn(tensor.shape, generator=gen))
    return model


@pytest.fixture(scope="module")
def sam2_folder(tmp_path_factory) -> tuple[Path, torch.nn.Module]:
    """A transformers-format SAM 2 folder (save_pretrained) of the perturbed tiny Meta model,
    with its processor, and the Meta model itself."""
    from transformers import Sam2ImageProcessor, Sam2Processor

    meta = _perturbed_meta_tiny()
    hf = sam2_to_transformers(meta)
    folder = tmp_path_factory.mktemp("sam2-hf") / "sam2-tiny-hf"
    hf.save_pretrained(folder)
    side = int(meta.image_size)
    processor = Sam2Processor(
        image_processor=Sam2ImageProcessor(size={"height": side, "width": side}), target_size=side
    )
    processor.save_pretrained(folder)
    return folder, meta


def tiny_sam_config():
    """A tiny ``SamConfig``: ViT of 2 layers (32 wide, 2 heads, one windowed of 4, one global),
    patch 16 on a 256-pixel input (a 16 x 16 embedding), prompt encoder and decoder 32 wide."""
    from transformers import SamConfig, SamVisionConfig

    vision = SamVisionConfig(hidden_size=32, num_hidden_layers=2, num_attention_heads=2,
                             image_size=256, patch_size=16, output_channels=32, num_pos_feats=16,
                             global_attn_indexes=[1], window_size=4, mlp_dim=64)
    return SamConfig(
        vision_config=vision,
        prompt_encoder_config={"hidden_size": 32, "image_size": 256, "patch_size": 16},
        mask_decoder_config={"hidden_size": 32, "mlp_dim": 64, "num_attention_heads": 2,
                             "iou_head_hidden_dim": 32},
    )


@pytest.fixture(scope="module")
def sam1_folder(tmp_path_factory) -> tuple[Path, torch.nn.Module]:
    """A transformers-format SAM (v1) folder: the tiny SamModel with seeded noise on every
    weight (its Fourier matrix of unit scale, so the masks are smooth), saved with
    save_pretrained (the tied matrix once) and a SamProcessor of 256 pixels; and the model."""
    from transformers import SamImageProcessor, SamModel, SamProcessor

    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(0)
        model = SamModel(tiny_sam_config()).eval()
    gen = torch.Generator().manual_seed(3)
    with torch.no_grad():
        for tensor in model.parameters():
            tensor.add_(0.05 * torch.randn(tensor.shape, generator=gen))
        model.shared_image_embedding.positional_embedding.copy_(
            torch.randn(2, 16, generator=gen))
    folder = tmp_path_factory.mktemp("sam-hf") / "sam-tiny-hf"
    model.save_pretrained(folder)
    SamProcessor(SamImageProcessor(size={"longest_edge": 256},
                                   pad_size={"height": 256, "width": 256})).save_pretrained(folder)
    return folder, model


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("scene") / "scene"
    write_lightfield(generate_scene(grid=(5, 5), size=(48, 64), seed=2, num_objects=3), path)
    return path


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("lfsam: error:"), err
    return err[0]


# --- the registry's facts -------------------------------------------------------------------
@pytest.mark.parametrize("name", list(TRANSFORMERS_MODELS))
def test_registry_parameter_counts_match_a_build(name):
    from transformers import EdgeTamModel

    spec = TRANSFORMERS_MODELS[name]
    config = tiny_edgetam_config() if spec.random_only else edgetam_config()
    model = EdgeTamModel(config)
    assert sum(p.numel() for p in model.parameters()) == spec.params
    assert config.prompt_encoder_config.image_size == spec.image_size


def _click_without_refinement(folder, tmp_path, capsys):
    """`lfsam segment SCENE --checkpoint FOLDER --point X,Y --no-refine --occlusion none` (no
    --model) on a 3x3 scene of 60x80: the scene, the result and the click."""
    lf = generate_scene(grid=(3, 3), size=(60, 80), seed=4, num_objects=3)
    scene = tmp_path / "scene"
    write_lightfield(lf, scene)
    out = tmp_path / "r.npz"
    x, y = 37, 22
    code = main(["segment", str(scene), "--checkpoint", str(folder), "--point", f"{x},{y}",
                 "--no-refine", "--occlusion", "none", "--disparity", "gt", "--device", "cpu",
                 "--out", str(out), "--quiet"])
    assert code == 0, capsys.readouterr().err
    return lf, load_result(out), (x, y)


# --- correctness without trained weights ----------------------------------------------------
def test_click_gives_transformers_own_mask(sam2_folder, tmp_path, capsys):
    """`lfsam segment --checkpoint DIR --no-refine --occlusion none` (no --model): the center
    view's mask is the one transformers' processor + Sam2Model give for that click."""
    from transformers import Sam2Model, Sam2Processor

    folder, _ = sam2_folder
    lf, result, (x, y) = _click_without_refinement(folder, tmp_path, capsys)
    assert result.meta["segmenter"]["backend"] == "transformers"
    ours = result.masks.mask(0)[lf.center]

    processor = Sam2Processor.from_pretrained(folder)
    model = Sam2Model.from_pretrained(folder).eval()
    center = lf.views[lf.center]
    inputs = processor(images=center, input_points=[[[[x, y]]]], input_labels=[[[1]]],
                       return_tensors="pt")
    with torch.no_grad():
        output = model(**inputs, multimask_output=True)
    masks = processor.post_process_masks(output.pred_masks, inputs["original_sizes"])[0][0]
    theirs = masks[int(output.iou_scores[0, 0].argmax())].numpy()
    assert 0 < theirs.sum() < theirs.size  # a real mask, not an empty or full one
    np.testing.assert_array_equal(ours, theirs)


def test_meta_and_transformers_backends_give_the_same_masks(sam2_folder):
    """The same random weights in Meta's sam2 and in transformers' Sam2Model: the same masks and
    IoU predictions through both of lfsam's backends. The view is the models' input size, so
    both pre-processings (a float resize in Meta's, a uint8 resize in transformers') are the
    identity and the two backends see the same pixels."""
    folder, meta = sam2_folder
    ours_meta = Sam2Segmenter(meta)
    ours_hf = load_segmenter("transformers", checkpoint=folder, device="cpu")
    side = int(meta.image_size)
    view = np.random.default_rng(0).integers(0, 256, (side, side, 3), dtype=np.uint8)
    prompts = Prompts(
        points=[[[40.0, 60.0]], [[200.0, 100.0]], [[120.0, 180.0]]],
        point_labels=[[1], [1], [1]],
        boxes=[[10, 20, 90, 120], [150, 60, 250, 160], [80, 140, 180, 230]],
    )
    for multimask in (True, False):
        a = ours_meta.predict(ours_meta.encode(view[None])[0], prompts, multimask)
        b = ours_hf.predict(ours_hf.encode(view[None])[0], prompts, multimask)
        torch.testing.assert_close(a.iou_predictions, b.iou_predictions, atol=1e-5, rtol=0)
        torch.testing.assert_close(a.low_res_logits, b.low_res_logits, atol=1e-4, rtol=0)
        assert torch.equal(a.masks, b.masks)
        assert 0 < int(a.masks.sum()) < a.masks.numel()


def test_same_weights_agree_on_a_resized_view(sam2_folder):
    """On a view that is resized, the two pre-processings differ by the rounding of the uint8
    resize (at most one grey level): the masks still agree on nearly every pixel."""
    folder, meta = sam2_folder
    ours_meta = Sam2Segmenter(meta)
    ours_hf = load_segmenter("transformers", checkpoint=folder, device="cpu")
    view = generate_scene(grid=(1, 1), size=(96, 128), seed=1, num_objects=2).views[0, 0]
    prompts = Prompts(points=[[[50.0, 40.0]]], point_labels=[[1]])
    a = ours_meta.predict(ours_meta.encode(view[None])[0], prompts)
    b = ours_hf.predict(ours_hf.encode(view[None])[0], prompts)
    agree = (a.masks == b.masks).float().mean().item()
    assert agree > 0.99, agree


# --- EdgeTAM through the pipeline -----------------------------------------------------------
def test_tiny_edgetam_segments_with_sparse_views(scene_dir, tmp_path, capsys):
    out = tmp_path / "e.npz"
    code = main(["segment", str(scene_dir), "--model", "edgetam-tiny-test", "--point", "20,20",
                 "--point", "40,30", "--refine-views", "sparse", "--disparity", "gt",
                 "--out", str(out), "--quiet", "--device", "cpu"])
    assert code == 0, capsys.readouterr().err
    result = load_result(out)
    assert result.meta["views_encoded"] == 9  # 5x5 views, sparse: 9 of 25 encoded
    assert result.meta["segmenter"]["name"] == "edgetam-tiny-test"
    assert result.meta["segmenter"]["model_type"] == "edgetam"
    assert result.labels.shape == (5, 5, 48, 64)


def test_tiny_edgetam_automatic_mode_and_the_cache(scene_dir, tmp_path):
    """--auto through SAM 2's automatic generator on EdgeTAM's embeddings; a second run reads
    every embedding from the disk cache and gives the same labels."""
    import lfsam
    from lfsam.api import ModelOptions, RunOptions, SegmentOptions
    from lfsam.io import read_lightfield

    lf = read_lightfield(scene_dir)
    segmenter = load_segmenter(
        "edgetam-tiny-test", device="cpu", amg_options={"points_per_side": 8,
                                                        "pred_iou_thresh": 0.0,
                                                        "stability_score_thresh": 0.0},
    )
    options = SegmentOptions(
        model=ModelOptions(name="edgetam-tiny-test"),
        run=RunOptions(cache_dir=str(tmp_path / "cache"), progress=False),
    )
    first = lfsam.segment(lf, None, model=segmenter, disparity="gt", options=options)
    encoded = segmenter.encode_calls
    assert first.num_masks >= 1 and encoded == 25
    second = lfsam.segment(lf, None, model=segmenter, disparity="gt", options=options)
    assert segmenter.encode_calls == encoded  # all 25 from the cache
    np.testing.assert_array_equal(first.labels, second.labels)


def test_tiny_edgetam_with_corner_references_and_text(scene_dir, tmp_path, capsys):
    """--auto --references corners, and --text (SAM 3 finds, EdgeTAM carries), through the CLI."""
    out = tmp_path / "corners.npz"
    amg = ["--amg", "points_per_side=8", "--amg", "pred_iou_thresh=0.0",
           "--amg", "stability_score_thresh=0.0"]
    code = main(["segment", str(scene_dir), "--model", "edgetam-tiny-test", "--auto",
                 "--references", "corners", *amg, "--disparity", "gt", "--out", str(out),
                 "--quiet", "--device", "cpu"])
    assert code == 0, capsys.readouterr().err
    assert load_result(out).meta["references"] == "corners"
    out = tmp_path / "text.npz"
    code = main(["segment", str(scene_dir), "--model", "edgetam-tiny-test", "--text", "thing",
                 "--text-model", "sam3-tiny-test", "--random-weights", "--text-threshold", "0",
                 "--refine-views", "sparse", "--disparity", "gt", "--out", str(out),
                 "--device", "cpu"])
    assert code == 0, capsys.readouterr().err
    result = load_result(out)
    assert result.num_masks > 0 and result.meta["segmenter"]["backend"] == "transformers"


def test_tiny_edgetam_tracks_a_video_with_prompts(tmp_path, capsys):
    from lfsam.video.io.synth import generate_video, write_video_frames

    video = tmp_path / "video"
    write_video_frames(generate_video(grid=(3, 3), size=(40, 56), frames=3, num_objects=2,
                                      seed=1), video)
    out = tmp_path / "track"
    code = main(["segment", str(video), "--model", "edgetam-tiny-test", "--point", "20,20",
                 "--disparity", "gt", "--out", str(out), "--quiet", "--device", "cpu"])
    assert code == 0, capsys.readouterr().err
    assert lfsam.load_result(out).meta["tracking"] == "edgetam-memory"  # issue 35: its memory
    code = main(["segment", str(video), "--model", "edgetam-tiny-test", "--point", "20,20",
                 "--tracking", "prompts", "--disparity", "gt", "--out", str(tmp_path / "m"),
                 "--quiet", "--device", "cpu"])
    assert code == 0, capsys.readouterr().err
    assert lfsam.load_result(tmp_path / "m").meta["tracking"] == "constrained-prompts"


# --- what a user sees -----------------------------------------------------------------------
def test_models_lists_edgetam_with_size_and_cache_state(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("HF_HUB_CACHE", str(tmp_path / "hub"))
    assert main(["models", "--json"]) == 0
    rows = {row["name"]: row for row in json.loads(capsys.readouterr().out)["models"]}
    edgetam = rows["edgetam"]
    assert edgetam["hub_id"] == "yonigozlan/EdgeTAM-hf" and edgetam["weights"] == "not cached"
    assert edgetam["size_mb"] == round(edgetam["params"] * 4 / 1e6, 1) > 30
    assert rows["edgetam-tiny-test"]["weights"] == "random only"
    # a snapshot in the cache, laid out as huggingface_hub lays it out, is found without network
    repo = tmp_path / "hub" / "models--yonigozlan--EdgeTAM-hf"
    snapshot = repo / "snapshots" / "0123abc"
    snapshot.mkdir(parents=True)
    (snapshot / "config.json").write_text("{}")
    (snapshot / "model.safetensors").write_bytes(b"")
    (repo / "refs").mkdir()
    (repo / "refs" / "main").write_text("0123abc")
    assert main(["models", "--json"]) == 0
    rows = {row["name"]: row for row in json.loads(capsys.readouterr().out)["models"]}
    assert rows["edgetam"]["weights"] == "cached"
    assert main(["models"]) == 0
    assert "edgetam" in capsys.readouterr().out


def test_offline_without_edgetam_weights_is_one_line(scene_dir, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("HF_HUB_CACHE", str(tmp_path / "empty-hub"))
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    code = main(["segment", str(scene_dir), "--model", "edgetam", "--point", "20,20",
                 "--out", str(tmp_path / "r.npz"), "--quiet"])
    assert code == 2
    line = _one_line_error(capsys)
    assert "edgetam" in line and "--checkpoint DIR" in line and "EdgeTAM-hf" in line
    assert not (tmp_path / "r.npz").exists()


def test_random_weights_edgetam_needs_no_download(monkeypatch, tmp_path):
    monkeypatch.setenv("HF_HUB_CACHE", str(tmp_path / "empty-hub"))
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    segmenter = load_segmenter("edgetam", random_weights=True, device="cpu")
    assert isinstance(segmenter, TransformersSegmenter)
    assert segmenter.describe()["params"] == TRANSFORMERS_MODELS["edgetam"].params
    assert segmenter.model.image_size == 1024


def test_folder_of_another_family_is_one_line(sam2_folder, scene_dir, tmp_path, capsys):
    folder, _ = sam2_folder
    code = main(["segment", str(scene_dir), "--model", "edgetam", "--checkpoint", str(folder),
                 "--point", "20,20", "--out", str(tmp_path / "r.npz"), "--quiet"])
    assert code == 2
    assert "holds a sam2 model, not edgetam" in _one_line_error(capsys)


@pytest.mark.parametrize("content", ["not a model", "sam"])
def test_folders_lfsam_cannot_load_are_one_line(tmp_path, content):
    folder = tmp_path / "model"
    folder.mkdir()
    if content == "sam":
        (folder / "config.json").write_text(json.dumps({"model_type": "clip"}))
        (folder / "model.safetensors").write_bytes(b"")
    with pytest.raises(LfsamError, match=r"transformers-format model folder|'clip' model"):
        load_segmenter("transformers", checkpoint=folder, device="cpu")


def test_corrupt_weights_are_one_line(sam2_folder, tmp_path):
    import shutil

    folder = tmp_path / "broken"
    shutil.copytree(sam2_folder[0], folder)
    (folder / "model.safetensors").write_bytes(b"\x00" * 64)
    with pytest.raises(LfsamError, match="corrupt or incomplete"):
        load_segmenter("transformers", checkpoint=folder, device="cpu")


def test_bfloat16_precision_is_a_choice(sam2_folder, scene_dir, tmp_path, capsys):
    """--precision bfloat16: autocast on the CPU (channels-last encoder), described in the
    result; the masks stay close to float32's. The oracle refuses the option."""
    folder, _ = sam2_folder
    view = generate_scene(grid=(1, 1), size=(96, 128), seed=1, num_objects=2).views[0, 0]
    prompts = Prompts(points=[[[50.0, 40.0]], [[90.0, 60.0]]], point_labels=[[1], [1]])
    masks = {}
    for precision in ("float32", "bfloat16"):
        segmenter = load_segmenter("transformers", checkpoint=folder, device="cpu",
                                   precision=precision)
        assert segmenter.describe()["precision"] == (
            "float32" if precision == "float32" else "bfloat16 autocast")
        masks[precision] = segmenter.predict(segmenter.encode(view[None])[0], prompts).masks
    agree = (masks["float32"] == masks["bfloat16"]).float().mean().item()
    assert agree > 0.9, agree
    code = main(["segment", str(scene_dir), "--model", "oracle", "--precision", "bfloat16",
                 "--point", "20,20", "--out", str(tmp_path / "r.npz"), "--quiet"])
    assert code == 2 and "--precision" in _one_line_error(capsys)


# --- SAM (v1) in transformers format ---------------------------------------------------------
def test_sam1_click_gives_transformers_own_mask(sam1_folder, tmp_path, capsys):
    """`lfsam segment --checkpoint DIR` of a SamModel on a non-square scene (60 x 80 views, so
    the input is padded): the center view's mask is SamProcessor + SamModel +
    post_process_masks's highest-IoU candidate for the click."""
    from transformers import SamModel, SamProcessor

    folder, _ = sam1_folder
    lf, result, (x, y) = _click_without_refinement(folder, tmp_path, capsys)
    assert result.meta["segmenter"]["model_type"] == "sam"
    ours = result.masks.mask(0)[lf.center]

    processor = SamProcessor.from_pretrained(folder)
    model = SamModel.from_pretrained(folder).eval()
    inputs = processor(images=lf.views[lf.center], input_points=[[[x, y]]], return_tensors="pt")
    with torch.no_grad():
        output = model(**inputs, multimask_output=True)
    masks = processor.post_process_masks(output.pred_masks, inputs["original_sizes"],
                                         inputs["reshaped_input_sizes"])[0][0]
    theirs = masks[int(output.iou_scores[0, 0].argmax())].numpy()
    assert 0 < theirs.sum() < theirs.size
    np.testing.assert_array_equal(ours, theirs)


def test_sam1_prompts_give_transformers_own_logits(sam1_folder):
    """Points, boxes and both (SAM v1's convention: points, then the box, no padding point)
    through `predict`: SamModel's low-resolution logits and IoU predictions within 1e-4 and its
    post-processed masks; the pixels are SamImageProcessor's; a cached embedding round-trips."""
    from transformers import SamImageProcessor, SamProcessor

    folder, model = sam1_folder
    image_processor = SamImageProcessor.from_pretrained(folder)
    for hw in ((45, 80), (77, 50)):
        view = np.random.default_rng(hw[0]).integers(0, 256, (*hw, 3), dtype=np.uint8)
        theirs = image_processor(images=view, return_tensors="pt")["pixel_values"]
        ours = preprocess_padded(torch.from_numpy(view)[None], 256)
        torch.testing.assert_close(ours, theirs, atol=1e-6, rtol=0)

    processor = SamProcessor.from_pretrained(folder)
    segmenter = load_segmenter("transformers", checkpoint=folder, device="cpu")
    view = generate_scene(grid=(1, 1), size=(61, 80), seed=1, num_objects=3).views[0, 0]
    embedding = segmenter.encode(view[None])[0]
    assert segmenter.embedding_state(embedding).keys() == {"level0", "dtype"}
    points = [[[20.0, 30.0]], [[55.0, 12.0]], [[70.0, 50.0]]]
    boxes = [[5.0, 10.0, 40.0, 50.0], [30.0, 2.0, 78.0, 30.0], [45.0, 25.0, 79.0, 60.0]]
    cases = [
        ({"points": points, "point_labels": [[1], [1], [0]]},
         {"input_points": [points], "input_labels": [[[1], [1], [0]]]}),
        ({"boxes": boxes}, {"input_boxes": [boxes]}),
        ({"points": points, "point_labels": [[1], [1], [1]], "boxes": boxes},
         {"input_points": [points], "input_labels": [[[1], [1], [1]]], "input_boxes": [boxes]}),
    ]
    for ours_args, their_args in cases:
        inputs = processor(images=view, return_tensors="pt", **their_args)
        for multimask in (True, False):
            ours = segmenter.predict(embedding, Prompts(**ours_args), multimask)
            with torch.no_grad():
                output = model(**inputs, multimask_output=multimask)
            torch.testing.assert_close(ours.iou_predictions, output.iou_scores[0],
                                       atol=1e-4, rtol=0)
            torch.testing.assert_close(ours.low_res_logits, output.pred_masks[0].clamp(-32, 32),
                                       atol=1e-4, rtol=0)
            masks = processor.post_process_masks(output.pred_masks, inputs["original_sizes"],
                                                 inputs["reshaped_input_sizes"])[0]
            assert torch.equal(ours.masks, masks)
            assert 0 < int(masks.sum()) < masks.numel()

    # semantic occluding samples the cells over the view: 61 x 80 -> 195 x 256, 13 x 16 cells
    assert view_grid((61, 80), 256, 16) == (13, 16)
    assert segmenter._feature_grid(embedding).shape[-2:] == (13, 16)
    assert segmenter.sample_features(embedding, torch.tensor([[30, 40]])).shape == (1, 32)
    cached = segmenter.embedding_from_state(segmenter.embedding_state(embedding), (61, 80),
                                            (0, 0))
    again = segmenter.predict(cached, Prompts(points=points, point_labels=[[1], [1], [1]]))
    first = segmenter.predict(embedding, Prompts(points=points, point_labels=[[1], [1], [1]]))
    assert torch.equal(again.masks, first.masks)

    # automatic generation runs SAM 2's generator in the padded geometry
    generated = segmenter.generate(embedding, view, points=np.array([[20.0, 30.0]]))
    assert generated.masks.shape[1:] == (61, 80)
    assert isinstance(image_transforms(segmenter._mask_generator().predictor), PaddedTransforms)


def test_sam1_runs_the_whole_pipeline(sam1_folder, scene_dir, tmp_path, capsys):
    """Refinement and semantic occluding (the defaults) with sparse views on a 5x5 scene."""
    folder, _ = sam1_folder
    out = tmp_path / "s.npz"
    code = main(["segment", str(scene_dir), "--checkpoint", str(folder), "--point", "20,20",
                 "--point", "40,30", "--refine-views", "sparse", "--disparity", "gt",
                 "--out", str(out), "--quiet", "--device", "cpu"])
    assert code == 0, capsys.readouterr().err
    result = load_result(out)
    assert result.meta["views_encoded"] == 9
    assert result.meta["segmenter"]["model_type"] == "sam"
    assert result.meta["segmenter"]["backend"] == "transformers"
    assert result.labels.shape == (5, 5, 48, 64)
    assert (result.labels > 0).any()


def test_sam1_absent_points_leave_its_answer(sam1_folder):
    """SAM v1 lays out points, then the box corners (no padding point with a box): absent
    points among them are masked out there too (docs/design.md section 3.5)."""
    from lfsam.segmenters.base import ABSENT_POINT

    folder, _ = sam1_folder
    segmenter = load_segmenter("transformers", checkpoint=folder, device="cpu")
    assert segmenter.skips_absent_points
    view = generate_scene(grid=(1, 1), size=(61, 80), seed=1, num_objects=3).views[0, 0]
    embedding = segmenter.encode(view[None])[0]
    points = np.array([[[20.0, 30.0], [0.0, 0.0]], [[55.0, 12.0], [60.0, 14.0]]], np.float32)
    labels = np.array([[1, ABSENT_POINT], [1, 0]])
    boxes = np.array([[5.0, 10.0, 40.0, 50.0], [30.0, 2.0, 78.0, 30.0]], np.float32)
    for box in (None, boxes):
        both = segmenter.predict(embedding, Prompts(points=points, point_labels=labels,
                                                    boxes=box))
        alone = segmenter.predict(embedding, Prompts(points=points[:1, :1],
                                                     point_labels=labels[:1, :1],
                                                     boxes=None if box is None else box[:1]))
        torch.testing.assert_close(both.low_res_logits[:1], alone.low_res_logits, atol=1e-7,
                                   rtol=0)
        attended = segmenter.predict(embedding, Prompts(points=points, point_labels=[[1, -1],
                                                                                     [1, 0]],
                                                        boxes=box))
        # this model's logits are about 0.02: compare at its scale
        assert (attended.low_res_logits[:1] - alone.low_res_logits).abs().max() > 1e-5


# --- EdgeTAM's encoder fused (docs/design.md section 3.8) ------------------------------------
def test_fused_edgetam_encoder_gives_the_unfused_embeddings_and_masks(monkeypatch):
    """EdgeTAM's RepViT runs with its batch norms and RepVGG branches folded into single
    convolutions, channels-last: the embeddings of the model as transformers builds it within
    1e-5 of their largest value, its low-resolution logits within 1e-4, masks that agree. The
    batch norms get random statistics and affine terms first, so a fold that dropped or
    misplaced one would not pass."""
    import copy

    from lfsam.segmenters.transformers import model as model_module
    from lfsam.segmenters.transformers.build import _random_model

    generator = torch.Generator().manual_seed(5)
    reference = _random_model("edgetam", tiny_edgetam_config(), 0).eval()
    with torch.no_grad():
        for module in reference.vision_encoder.modules():
            if isinstance(module, torch.nn.BatchNorm2d):
                n = module.num_features
                module.running_mean.copy_(torch.randn(n, generator=generator) * 0.3)
                module.running_var.copy_(torch.rand(n, generator=generator) + 0.5)
                module.weight.copy_(torch.rand(n, generator=generator) + 0.5)
                module.bias.copy_(torch.randn(n, generator=generator) * 0.2)
    info = {"name": "edgetam-tiny-test"}
    fused = model_module.TransformersImageModel(copy.deepcopy(reference), info)
    assert fused.fused_encoder
    modules = list(fused.hf_model.vision_encoder.modules())
    assert not any(isinstance(m, torch.nn.BatchNorm2d) for m in modules)
    assert sum(isinstance(m, torch.nn.Conv2d) for m in modules) < sum(
        isinstance(m, torch.nn.Conv2d) for m in reference.vision_encoder.modules())

    pixels = torch.randn(2, 3, 256, 256, generator=generator)
    with torch.no_grad():
        theirs = reference.get_image_embeddings(pixels)
        ours = fused.image_embeddings(pixels.contiguous(memory_format=torch.channels_last))
    for a, b in zip(ours, theirs, strict=True):
        torch.testing.assert_close(a, b, atol=1e-5 * float(b.abs().max()), rtol=0)

    monkeypatch.setattr(model_module, "fuse_timm_encoder", lambda hf_model: False)
    plain = model_module.TransformersImageModel(copy.deepcopy(reference), info)
    assert not plain.fused_encoder
    fast, slow = TransformersSegmenter(fused), TransformersSegmenter(plain)
    assert fast.channels_last and not slow.channels_last
    view = generate_scene(grid=(1, 1), size=(48, 64), seed=2, num_objects=3).views[0, 0]
    prompts = Prompts(points=[[[20.0, 30.0]], [[50.0, 12.0]]], point_labels=[[1], [1]])
    a = fast.predict(fast.encode(view[None])[0], prompts)
    b = slow.predict(slow.encode(view[None])[0], prompts)
    torch.testing.assert_close(a.low_res_logits, b.low_res_logits, atol=1e-4, rtol=0)
    assert (a.masks == b.masks).float().mean().item() > 0.999
