"""EdgeTAM's (and transformers SAM 2's) video memory over the reference views (issue 35,
docs/design.md section 10): driven one frame at a time, with a bounded window and one encoder
pass per frame, it gives transformers' own streaming video inference."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from lfsam.errors import LfsamError
from lfsam.segmenters import load_segmenter
from lfsam.segmenters.transformers.video_build import (
    SHARED_MODULES,
    tiny_edgetam_video_config,
    video_model_for,
)
from lfsam.video.memory.hf_memory import TransformersReferenceMemory, has_transformers_video_memory

SHAPE = (64, 80)


@pytest.fixture(scope="module")
def tiny():
    return load_segmenter("edgetam-tiny-test", device="cpu")


@pytest.fixture
def present(tiny):
    """Random weights give logits near 0 and an object score near 0 (objects flicker in and
    out of being "absent", masks all -1024): seeded noise on every weight of the video model
    (the segmenter's shared modules included) and a raised object-score bias give real masks
    that the memory changes, as with trained weights. Restored afterwards."""
    model = video_model_for(tiny.model)
    saved = {k: v.clone() for k, v in model.state_dict().items()}
    gen = torch.Generator().manual_seed(3)
    with torch.no_grad():
        for tensor in model.parameters():
            tensor.add_(0.1 * torch.randn(tensor.shape, generator=gen))
        model.mask_decoder.pred_obj_score_head.proj_out.bias += 50.0
    yield tiny
    model.load_state_dict(saved)


def _frames(count: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Noise frames with two squares moving a pixel a frame (one right, one left), and their
    frame-0 masks."""
    rng = np.random.default_rng(seed)
    images = rng.integers(0, 256, (count, *SHAPE, 3), dtype=np.uint8)
    for f in range(count):
        images[f, 10:30, 12 + f % 20:40 + f % 20] = (220, 30, 30)
        images[f, 40:58, 50 - f % 20:70 - f % 20] = (30, 30, 220)
    first, second = np.zeros(SHAPE, bool), np.zeros(SHAPE, bool)
    first[10:30, 12:40] = True
    second[40:58, 50:70] = True
    return images, first, second


def _schedule(masks, prompts):
    """Prompts by frame: ``{frame: {obj_id: mask}}``; default every mask on frame 0."""
    return prompts if prompts is not None else {0: dict(enumerate(masks, start=1))}


def _stream(segmenter, images, masks, window=None, check=None, prompts=None):
    """Logits (F, N, U, V) of the memory driven frame by frame, masks added on frame 0 (or as
    ``prompts`` says)."""
    prompts = _schedule(masks, prompts)
    memory = TransformersReferenceMemory(segmenter, SHAPE)
    if window is not None:
        memory.window = window
    logits = []
    for f, image in enumerate(images):
        memory.next_frame(f, image)
        for obj_id, mask in prompts.get(f, {}).items():
            memory.add_mask(obj_id, mask)
        tracked = memory.track()
        memory.forget()
        assert list(tracked) == memory.object_ids
        assert all(m.shape == SHAPE and m.dtype == bool for m in tracked.values())
        logits.append(memory.logits.copy())
        if check is not None:
            check(memory)
    same = len({x.shape for x in logits}) == 1
    return memory, (np.stack(logits) if same else logits)


def _transformers_run(model, images, masks, prompts=None):
    """transformers' own streaming video inference: processor, session, model(frame=...)."""
    from transformers import Sam2ImageProcessor, Sam2VideoProcessor, Sam2VideoVideoProcessor

    prompts = _schedule(masks, prompts)
    side = int(model.config.image_size)
    size = {"height": side, "width": side}
    processor = Sam2VideoProcessor(image_processor=Sam2ImageProcessor(size=size),
                                   video_processor=Sam2VideoVideoProcessor(size=size),
                                   target_size=side)
    session = processor.init_video_session(inference_device="cpu", dtype=torch.float32)
    logits = []
    for f, image in enumerate(images):
        inputs = processor(images=image, device="cpu", return_tensors="pt")
        if prompts.get(f):
            processor.add_inputs_to_inference_session(
                session, frame_idx=f, obj_ids=list(prompts[f]),
                input_masks=list(prompts[f].values()))
        out = model(inference_session=session, frame=inputs.pixel_values[0])
        full = processor.post_process_masks([out.pred_masks], inputs["original_sizes"],
                                            binarize=False)[0]
        logits.append(full[:, 0].numpy())
    return logits


def test_one_frame_at_a_time_is_transformers_streaming_run(present):
    images, first, second = _frames(5)
    _, ours = _stream(present, images, [first, second])
    tracked = ours[1:] > 0
    assert tracked.any(axis=(2, 3)).all() and not tracked.all(axis=(2, 3)).any()  # real masks
    theirs = np.stack(_transformers_run(video_model_for(present.model), images,
                                        [first, second]))
    np.testing.assert_allclose(ours, theirs, atol=1e-5, rtol=0)
    np.testing.assert_array_equal(ours > 0, theirs > 0)
    np.testing.assert_array_equal(ours[0] > 0, np.stack([first, second]))


def test_objects_start_and_are_prompted_again_at_later_frames(present):
    """An object that starts at frame 2 (its mask there while the other is tracked) and a
    re-prompt of the first at frame 3: conditioning frames of both kept, transformers' masks."""
    images, first, second = _frames(6, seed=9)
    prompts = {0: {1: first}, 2: {2: second}, 3: {1: first}}
    memory, ours = _stream(present, images, [], prompts=prompts)
    assert memory.object_ids == [1, 2]
    cond = [sorted(memory.session.output_dict_per_obj[i]["cond_frame_outputs"]) for i in (0, 1)]
    assert cond == [[0, 3], [2]]
    theirs = _transformers_run(video_model_for(present.model), images, [], prompts=prompts)
    for f in range(6):
        assert ours[f].shape[0] == (1 if f < 2 else 2)
        np.testing.assert_allclose(ours[f], theirs[f], atol=1e-5, rtol=0)
        np.testing.assert_array_equal(ours[f] > 0, theirs[f] > 0)
    np.testing.assert_array_equal(ours[3][0] > 0, first)


def test_the_window_is_lossless_and_the_session_stays_flat(present):
    memory = TransformersReferenceMemory(present, SHAPE)
    assert memory.window == 14  # 16 object pointers, 7 memories: frames f - 14 .. f kept
    frames = 3 * (memory.window + 2)
    images, first, second = _frames(frames)

    def bounded(memory):
        session, f = memory.session, memory.frame
        for obj_idx in (0, 1):
            outputs = session.output_dict_per_obj[obj_idx]
            assert list(outputs["cond_frame_outputs"]) == [0]
            assert all(f - memory.window <= k <= f for k in outputs["non_cond_frame_outputs"])
            assert len(outputs["non_cond_frame_outputs"]) <= memory.window + 1
            assert len(session.frames_tracked_per_obj[obj_idx]) <= memory.window + 1
            assert set(session.mask_inputs_per_obj[obj_idx]) <= {f}
        assert list(session.cache._vision_features) == [f]
        assert not session.processed_frames

    _, ours = _stream(present, images, [first, second], check=bounded)
    assert (ours[1:] > 0).any(axis=(2, 3)).all()
    past = memory.window + 5  # an unbounded session gives the same masks past the window
    _, unbounded = _stream(present, images[:past], [first, second], window=10**6)
    np.testing.assert_array_equal(ours[:past], unbounded)


def test_one_frame_less_than_the_window_changes_the_masks(present, monkeypatch):
    """A model looking one frame back (1 memory, 1 object pointer behind the current frame):
    the window keeps no frame behind the current one and loses nothing; dropping that one
    frame too changes frame 2."""
    model = video_model_for(present.model)
    monkeypatch.setattr(model, "num_maskmem", 2)
    monkeypatch.setattr(model.config, "max_object_pointers_in_encoder", 2)
    images, first, _ = _frames(4, seed=1)
    memory, ours = _stream(present, images, [first])
    assert memory.window == 0
    _, unbounded = _stream(present, images, [first], window=10**6)
    np.testing.assert_array_equal(ours, unbounded)
    np.testing.assert_allclose(ours, np.stack(_transformers_run(model, images, [first])),
                               atol=1e-5, rtol=0)
    _, short = _stream(present, images[:3], [first], window=-1)
    np.testing.assert_array_equal(short[:2], ours[:2])
    assert np.abs(short[2] - ours[2]).max() > 1e-2 * np.abs(ours[2]).max()
    assert ((short[2] > 0) != (ours[2] > 0)).any()


def test_one_encoder_pass_per_frame_gives_the_segmenters_embedding(tiny):
    model = video_model_for(tiny.model)
    calls = []
    hook = model.vision_encoder.register_forward_hook(lambda *_: calls.append(1))
    images, first, _ = _frames(3, seed=2)
    memory = TransformersReferenceMemory(tiny, SHAPE)
    embeddings = []
    try:
        for f, image in enumerate(images):
            before = tiny.encode_calls
            embeddings.append(memory.next_frame(f, image))
            assert tiny.encode_calls == before + 1
            if f == 0:
                memory.add_mask(1, first)
            memory.track()
            if f == 2:
                memory.correct(1, [(20.0, 15.0)])
            memory.forget()
            assert len(calls) == f + 1
    finally:
        hook.remove()
    for image, embedding in zip(images, embeddings, strict=True):  # after the model used them
        ref = tiny.encode(image[None])[0]
        assert embedding.image_size == ref.image_size == SHAPE
        ours = [embedding.data.image_embed, *embedding.data.high_res_feats]
        theirs = [ref.data.image_embed, *ref.data.high_res_feats]
        for a, b in zip(ours, theirs, strict=True):
            torch.testing.assert_close(a, b, atol=1e-5, rtol=0)


def test_frames_go_forward_one_at_a_time(tiny):
    memory = TransformersReferenceMemory(tiny, SHAPE)
    image = np.zeros((*SHAPE, 3), np.uint8)
    with pytest.raises(LfsamError, match="call next_frame first"):
        memory.track()
    memory.next_frame(3, image)  # a stream may start anywhere
    assert memory.track() == {} and memory.logits.shape == (0, *SHAPE)
    for index in (3, 5, 2):
        with pytest.raises(LfsamError, match="frames go forward one at a time"):
            memory.next_frame(index, image)
    with pytest.raises(LfsamError, match="64 x 80 x 3 uint8"):
        memory.next_frame(4, np.zeros((32, 80, 3), np.uint8))


def test_a_negative_click_corrects_the_tracked_mask(present):
    images, first, second = _frames(2, seed=3)

    def corrected():
        memory = TransformersReferenceMemory(present, SHAPE)
        memory.next_frame(0, images[0])
        memory.add_mask(1, first)
        memory.add_mask(2, second)
        memory.track()
        memory.next_frame(1, images[1])
        tracked = memory.track()
        before = memory.logits.copy()
        rows, cols = np.nonzero(tracked[1])
        click = (float(cols[len(cols) // 2]), float(rows[len(rows) // 2]))
        after = memory.correct(1, [click])
        inputs = memory.session.point_inputs_per_obj[0][1]
        assert inputs["point_labels"].tolist() == [[[0]]]
        torch.testing.assert_close(inputs["point_coords"][0, 0, 0],
                                   torch.tensor([click[0] * 256 / 80, click[1] * 256 / 64]))
        return before, memory.logits.copy(), tracked, after, click

    before, logits, tracked, after, (x, y) = corrected()
    assert sorted(after) == [1, 2]
    assert np.abs(logits[0] - before[0]).max() > 1e-3  # the click was taken into account
    np.testing.assert_array_equal(logits[1], before[1])  # the other object is as tracked
    np.testing.assert_array_equal(after[2], tracked[2])
    np.testing.assert_array_equal(logits, corrected()[1])  # deterministic
    memory = TransformersReferenceMemory(present, SHAPE)
    memory.next_frame(0, images[0])
    with pytest.raises(LfsamError, match="object 7 is not tracked"):
        memory.correct(7, [(x, y)])


def test_the_video_model_shares_the_segmenters_modules(tiny):
    model = video_model_for(tiny.model)
    assert model is video_model_for(tiny.model)  # built once per image model
    hf = tiny.model.hf_model
    for name in SHARED_MODULES:
        assert getattr(model, name) is getattr(hf, name)
    ours = {k: v for k, v in model.state_dict().items() if k.startswith(SHARED_MODULES)}
    theirs = {k: v for k, v in hf.state_dict().items() if k.startswith(SHARED_MODULES)}
    assert ours.keys() == theirs.keys() and len(ours) > 50
    assert all(torch.equal(ours[k], theirs[k]) for k in ours)
    assert model.config.memory_encoder_output_channels == 16


def _save_image_only(tmp_path, kind: str):
    """A transformers-format image-only folder: a tiny EdgeTamModel or SAM (v1) SamModel."""
    from transformers import EdgeTamModel, SamConfig, SamModel, SamVisionConfig

    from lfsam.segmenters.transformers.build import tiny_edgetam_config

    folder = tmp_path / kind
    if kind == "edgetam":
        model = EdgeTamModel(tiny_edgetam_config())
    else:
        vision = SamVisionConfig(hidden_size=32, num_hidden_layers=1, num_attention_heads=2,
                                 image_size=256, patch_size=16, output_channels=32,
                                 num_pos_feats=16, global_attn_indexes=[0], mlp_dim=64)
        model = SamModel(SamConfig(
            vision_config=vision,
            prompt_encoder_config={"hidden_size": 32, "image_size": 256, "patch_size": 16},
            mask_decoder_config={"hidden_size": 32, "mlp_dim": 64, "num_attention_heads": 2,
                                 "iou_head_hidden_dim": 32},
        ))
    _tie_fourier(model)
    model.save_pretrained(folder)
    return folder


def _tie_fourier(model) -> None:
    """One Fourier matrix for the image and the prompts, as SAM's checkpoints have."""
    with torch.no_grad():
        model.prompt_encoder.shared_embedding.positional_embedding.copy_(
            model.shared_image_embedding.positional_embedding)


def test_which_segmenters_have_memory(tiny, tmp_path):
    assert has_transformers_video_memory(tiny)
    assert not has_transformers_video_memory(load_segmenter("sam2-tiny-test", device="cpu",
                                                            random_weights=True))
    for kind, message in (("edgetam", r"image-only edgetam model .*'edgetam'.* video "
                                      r"checkpoint \(model type 'edgetam_video'\), or use "
                                      r"--tracking prompts"),
                          ("sam", r"\(sam\) has no video memory; track with --tracking prompts")):
        folder = _save_image_only(tmp_path, kind)
        segmenter = load_segmenter("transformers", checkpoint=folder, device="cpu")
        assert not has_transformers_video_memory(segmenter)
        with pytest.raises(LfsamError, match=message) as error:
            TransformersReferenceMemory(segmenter, SHAPE)
        assert "\n" not in str(error.value)
        if kind == "edgetam":
            assert str(folder) in str(error.value)


def test_a_video_checkpoint_folder_brings_its_memory_weights(tmp_path):
    """A tiny EdgeTamVideoModel (memories 64 channels wide, as transformers builds them) saved
    with save_pretrained: lfsam loads the segmenter from the folder and the memory's weights
    from it, and tracks as the same model loaded by transformers does."""
    from transformers import EdgeTamVideoModel

    torch.manual_seed(4)
    saved = EdgeTamVideoModel(tiny_edgetam_video_config(width=128)).eval()
    with torch.no_grad():  # no weight left at its initial constant; objects present
        for tensor in saved.parameters():
            tensor.add_(0.02 * torch.randn(tensor.shape))
        saved.mask_decoder.pred_obj_score_head.proj_out.bias += 50.0
    _tie_fourier(saved)
    folder = tmp_path / "edgetam-video-tiny"
    saved.save_pretrained(folder)

    segmenter = load_segmenter("transformers", checkpoint=folder, device="cpu")
    assert has_transformers_video_memory(segmenter)
    images, first, second = _frames(4, seed=5)
    memory, ours = _stream(segmenter, images, [first, second])
    # every weight as saved, but the image encoder's: lfsam runs it fused (its batch norms and
    # RepVGG branches folded into convolutions, test_segmenters_transformers.py), so its
    # function is checked below, by tracking as transformers does
    encoder = "vision_encoder.backbone."
    expected = {k: v for k, v in saved.state_dict().items() if not k.startswith(encoder)}
    loaded = {k: v for k, v in memory.model.state_dict().items() if not k.startswith(encoder)}
    assert loaded.keys() == expected.keys()
    assert all(torch.equal(loaded[k], expected[k]) for k in expected)
    assert (ours[1:] > 0).any(axis=(2, 3)).all()
    theirs = np.stack(_transformers_run(EdgeTamVideoModel.from_pretrained(folder).eval(),
                                        images, [first, second]))
    np.testing.assert_allclose(ours, theirs, atol=1e-5, rtol=0)


def _tiny_sam2_video_config():
    """A tiny Sam2VideoConfig transformers can save and load: Hiera of 5 blocks (16-128 wide),
    FPN and heads 128 wide, one memory-attention layer, 64-channel memories, 256 pixels."""
    from transformers import Sam2HieraDetConfig, Sam2VideoConfig, Sam2VisionConfig

    hiera = Sam2HieraDetConfig(
        hidden_size=16, image_size=[256, 256], blocks_per_stage=[1, 1, 2, 1],
        embed_dim_per_stage=[16, 32, 64, 128], num_attention_heads_per_stage=[1, 1, 1, 1],
        window_size_per_stage=[8, 4, 4, 4], global_attention_blocks=[3],
        window_positional_embedding_background_size=[4, 4])
    vision = Sam2VisionConfig(backbone_config=hiera, backbone_channel_list=[128, 64, 32, 16],
                              backbone_feature_sizes=[[64, 64], [32, 32], [16, 16]],
                              fpn_hidden_size=128)
    return Sam2VideoConfig(
        vision_config=vision, image_size=256,
        prompt_encoder_config={"hidden_size": 128, "image_size": 256},
        mask_decoder_config={"hidden_size": 128, "mlp_dim": 256, "num_attention_heads": 2,
                             "iou_head_hidden_dim": 128},
        memory_attention_hidden_size=128, memory_attention_num_layers=1,
        memory_attention_feed_forward_hidden_size=256, memory_attention_rope_feat_sizes=[16, 16],
        memory_encoder_hidden_size=128, memory_encoder_output_channels=64,
        mask_downsampler_embed_dim=128, memory_fuser_embed_dim=128,
        memory_fuser_intermediate_dim=256, memory_fuser_num_layers=1)


def test_a_sam2_video_folder_tracks_as_transformers_does(tmp_path):
    """The same code drives Sam2VideoModel (a transformers-format SAM 2 video checkpoint)."""
    from transformers import Sam2VideoModel

    torch.manual_seed(6)
    saved = Sam2VideoModel(_tiny_sam2_video_config()).eval()
    gen = torch.Generator().manual_seed(6)
    with torch.no_grad():
        for tensor in saved.parameters():
            tensor.add_(0.05 * torch.randn(tensor.shape, generator=gen))
        saved.mask_decoder.pred_obj_score_head.proj_out.bias += 50.0
    _tie_fourier(saved)
    folder = tmp_path / "sam2-video-tiny"
    saved.save_pretrained(folder)

    segmenter = load_segmenter("transformers", checkpoint=folder, device="cpu")
    assert segmenter.info["model_type"] == "sam2" and has_transformers_video_memory(segmenter)
    images, first, second = _frames(4, seed=7)
    prompts = {0: {1: first}, 2: {2: second}}  # the second starts while the first is tracked
    memory, ours = _stream(segmenter, images, [], prompts=prompts)
    assert type(memory.model).__name__ == "Sam2VideoModel"
    assert all("high_res_masks" not in out  # the full-size masks are not kept
               for outputs in memory.session.output_dict_per_obj.values()
               for kept in outputs.values() for out in kept.values())
    assert all((logits > 0).any(axis=(1, 2)).all() for logits in ours)
    theirs = _transformers_run(Sam2VideoModel.from_pretrained(folder).eval(), images, [],
                               prompts=prompts)
    for a, b in zip(ours, theirs, strict=True):
        np.testing.assert_allclose(a, b, atol=1e-5, rtol=0)
        np.testing.assert_array_equal(a > 0, b > 0)


def test_a_bfloat16_segmenter_encodes_on_its_own(tmp_path):
    """With bfloat16 autocast the segmenter's embeddings come from another arithmetic than the
    float32 memory's: next_frame gives None (and counts no encoding); tracking works."""
    segmenter = load_segmenter("edgetam-tiny-test", device="cpu", precision="bfloat16")
    memory = TransformersReferenceMemory(segmenter, SHAPE)
    images, first, _ = _frames(2, seed=8)
    for f, image in enumerate(images):
        assert memory.next_frame(f, image) is None
        if f == 0:
            memory.add_mask(1, first)
        assert memory.track()[1].shape == SHAPE
        memory.forget()
    assert segmenter.encode_calls == 0
