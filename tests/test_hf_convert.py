"""Meta SAM 2 -> transformers Sam2Model conversion (lfsam.segmenters.transformers.convert).

The same weights in both implementations must give the same image embeddings, low-resolution
mask logits and IoU predictions. Every weight of the Meta model is perturbed first (seeded), so
that parameters Meta initialises to constants (Hiera's position embeddings, LayerNorm weights and
biases) also tell a wrong mapping apart from a right one.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from lfsam.errors import LfsamError
from lfsam.segmenters.sam2.build import build_sam2, make_image_predictor
from lfsam.segmenters.transformers.convert import (
    sam2_config_for,
    sam2_state_dict_to_transformers,
    sam2_to_transformers,
)

RTOL = 1e-5
"""Allowed max abs difference relative to the magnitude (at least 1) of the Meta output."""


def _perturb(model: torch.nn.Module, seed: int = 1) -> torch.nn.Module:
    """Add seeded noise to every floating-point parameter and buffer, in place."""
    gen = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for tensor in [*model.parameters(), *model.buffers()]:
            if tensor.is_floating_point():
                noise = torch.randn(tensor.shape, generator=gen, dtype=tensor.dtype)
                tensor.add_(0.05 * noise.to(tensor.device))
    return model


def _close(meta: torch.Tensor | np.ndarray, ours: torch.Tensor, what: str) -> float:
    meta = torch.as_tensor(meta)
    assert meta.shape == ours.shape, f"{what}: shape {tuple(meta.shape)} vs {tuple(ours.shape)}"
    diff = (meta - ours).abs().max().item()
    scale = max(1.0, meta.abs().max().item())
    assert diff <= RTOL * scale, f"{what}: max abs diff {diff} (magnitude {scale})"
    return diff


def _meta_embeddings(model: torch.nn.Module, x: torch.Tensor) -> list[torch.Tensor]:
    """Meta's three levels as SAM2ImagePredictor.set_image builds them: (1, C, H, W)."""
    out = model.forward_image(x)
    _, feats, _, sizes = model._prepare_backbone_features(out)
    feats[-1] = feats[-1] + model.no_mem_embed
    return [f.permute(1, 2, 0).reshape(1, -1, *s) for f, s in zip(feats, sizes, strict=True)]


@pytest.fixture(scope="module")
def tiny():
    """The perturbed tiny test model, its conversion, a predictor and one encoded image."""
    model = _perturb(build_sam2("sam2-tiny-test", random_weights=True, device="cpu", seed=0))
    hf = sam2_to_transformers(model)
    size = int(model.image_size)
    rng = np.random.default_rng(0)
    image = rng.integers(0, 256, size=(size, size, 3), dtype=np.uint8)
    predictor = make_image_predictor(model)
    with torch.no_grad():
        predictor.set_image(image)
        x = predictor._transforms(image)[None]
        embeddings = hf.get_image_embeddings(x)
    return {"model": model, "hf": hf, "predictor": predictor, "x": x, "emb": embeddings}


def test_config_reads_the_architecture(tiny):
    cfg = sam2_config_for(tiny["model"])
    bb = cfg.vision_config.backbone_config
    assert bb.hidden_size == 16
    assert bb.blocks_per_stage == [1, 1, 2, 1]
    assert bb.embed_dim_per_stage == [16, 32, 64, 128]
    assert bb.num_attention_heads_per_stage == [1, 2, 4, 8]
    assert bb.global_attention_blocks == [3]
    assert bb.window_size_per_stage == [8, 4, 14, 7]
    assert bb.window_positional_embedding_background_size == [7, 7]
    assert bb.num_query_pool_stages == 3 and bb.query_stride == [2, 2]
    assert bb.image_size == [256, 256]
    assert cfg.vision_config.fpn_hidden_size == 32
    assert cfg.vision_config.backbone_channel_list == [128, 64, 32, 16]
    assert cfg.vision_config.fpn_top_down_levels == [2, 3]
    assert cfg.vision_config.num_feature_levels == 3
    assert cfg.vision_config.backbone_feature_sizes == [[64, 64], [32, 32], [16, 16]]
    assert cfg.prompt_encoder_config.hidden_size == 32
    assert cfg.prompt_encoder_config.image_size == 256
    assert cfg.prompt_encoder_config.patch_size == 16
    md = cfg.mask_decoder_config
    assert (md.hidden_size, md.mlp_dim, md.num_hidden_layers, md.num_attention_heads) == (
        32,
        2048,
        2,
        8,
    )
    assert (md.iou_head_depth, md.iou_head_hidden_dim, md.num_multimask_outputs) == (3, 256, 3)
    assert md.dynamic_multimask_via_stability is True
    assert md.dynamic_multimask_stability_delta == 0.05
    assert md.dynamic_multimask_stability_thresh == 0.98


def test_converted_model_state(tiny):
    hf, model = tiny["hf"], tiny["model"]
    assert not hf.training
    param = next(hf.parameters())
    assert param.dtype == torch.float32 and param.device == next(model.parameters()).device
    assert torch.equal(hf.no_memory_embedding, model.no_mem_embed)
    assert torch.equal(
        hf.prompt_encoder.point_embed.weight[2],
        model.sam_prompt_encoder.point_embeddings[2].weight[0],
    )


def test_image_embeddings_match(tiny):
    with torch.no_grad():
        meta = _meta_embeddings(tiny["model"], tiny["x"])
    assert len(tiny["emb"]) == 3
    for level, (a, b) in enumerate(zip(meta, tiny["emb"], strict=True)):
        _close(a, b, f"level {level}")
    # the predictor's cached features are the same ones
    feats = tiny["predictor"]._features
    _close(feats["image_embed"], tiny["emb"][-1], "predictor image_embed")


PROMPTS = {
    "click": {"points": [[100.0, 140.0]], "labels": [1], "box": None},
    "box": {"points": None, "labels": None, "box": [40.0, 60.0, 200.0, 190.0]},
    "point+box": {"points": [[120.0, 110.0]], "labels": [0], "box": [30.0, 50.0, 180.0, 220.0]},
    "two clicks": {"points": [[60.0, 70.0], [190.0, 150.0]], "labels": [1, 0], "box": None},
}


@pytest.mark.parametrize("multimask", [True, False], ids=["multimask", "single"])
@pytest.mark.parametrize("prompt", list(PROMPTS))
def test_decoder_matches_image_predictor(tiny, prompt, multimask):
    spec = PROMPTS[prompt]
    points = None if spec["points"] is None else np.array(spec["points"], dtype=np.float32)
    labels = None if spec["labels"] is None else np.array(spec["labels"], dtype=np.int32)
    box = None if spec["box"] is None else np.array(spec["box"], dtype=np.float32)
    # the image is image_size square, so its pixels are the model-input pixels
    _, meta_iou, meta_low = tiny["predictor"].predict(
        point_coords=points, point_labels=labels, box=box, multimask_output=multimask
    )
    kwargs = {}
    if points is not None:
        kwargs["input_points"] = torch.from_numpy(points)[None, None]  # (1, 1, P, 2)
        kwargs["input_labels"] = torch.from_numpy(labels)[None, None]  # (1, 1, P)
    if box is not None:
        kwargs["input_boxes"] = torch.from_numpy(box)[None, None]  # (1, 1, 4)
    with torch.no_grad():
        out = tiny["hf"](image_embeddings=tiny["emb"], multimask_output=multimask, **kwargs)
    n_masks = 3 if multimask else 1
    assert out.pred_masks.shape == (1, 1, n_masks, 64, 64)
    # SAM2ImagePredictor clamps its low-resolution logits to [-32, 32]
    _close(meta_low, out.pred_masks[0, 0].clamp(-32.0, 32.0), "low-res mask logits")
    _close(meta_iou, out.iou_scores[0, 0], "IoU predictions")


def test_single_mask_stable_branch(tiny, monkeypatch):
    """Random weights give stability scores near 0.5, so the single-mask tests above always
    take the fallback to the best multimask output; with threshold 0 both take token 0."""
    for decoder in (tiny["model"].sam_mask_decoder, tiny["hf"].mask_decoder):
        monkeypatch.setattr(decoder, "dynamic_multimask_stability_thresh", 0.0)
    assert (
        sam2_config_for(tiny["model"]).mask_decoder_config.dynamic_multimask_stability_thresh == 0
    )
    _, meta_iou, meta_low = tiny["predictor"].predict(
        point_coords=np.array([[100.0, 140.0]]), point_labels=np.array([1]), multimask_output=False
    )
    with torch.no_grad():
        out = tiny["hf"](
            image_embeddings=tiny["emb"],
            input_points=torch.tensor([[[[100.0, 140.0]]]]),
            input_labels=torch.tensor([[[1]]]),
            multimask_output=False,
        )
        all_masks = tiny["hf"](
            image_embeddings=tiny["emb"],
            input_points=torch.tensor([[[[100.0, 140.0]]]]),
            input_labels=torch.tensor([[[1]]]),
            multimask_output=True,
        )
    assert out.iou_scores[0, 0, 0] not in all_masks.iou_scores[0, 0]  # token 0, not 1..3
    _close(meta_low, out.pred_masks[0, 0].clamp(-32.0, 32.0), "low-res mask logits")
    _close(meta_iou, out.iou_scores[0, 0], "IoU predictions")


def test_decoder_matches_meta_heads_directly(tiny):
    """Points through Meta's prompt encoder and mask decoder, with the object score."""
    model, hf = tiny["model"], tiny["hf"]
    feats = tiny["predictor"]._features
    coords = torch.tensor([[[30.0, 200.0], [150.0, 90.0], [210.0, 20.0]]])
    labels = torch.tensor([[1, 1, 0]], dtype=torch.int32)
    with torch.no_grad():
        sparse, dense = model.sam_prompt_encoder(points=(coords, labels), boxes=None, masks=None)
        masks, iou, _, obj = model.sam_mask_decoder(
            image_embeddings=feats["image_embed"],
            image_pe=model.sam_prompt_encoder.get_dense_pe(),
            sparse_prompt_embeddings=sparse,
            dense_prompt_embeddings=dense,
            multimask_output=True,
            repeat_image=False,
            high_res_features=feats["high_res_feats"],
        )
        out = hf(
            image_embeddings=tiny["emb"],
            input_points=coords[None],
            input_labels=labels[None],
            multimask_output=True,
        )
    _close(masks, out.pred_masks[0], "mask logits")
    _close(iou, out.iou_scores[0], "IoU predictions")
    _close(obj, out.object_score_logits[0], "object score logits")


def test_real_size_architecture():
    """sam2.1-hiera-tiny (1024 px, random weights): embeddings and a 1-click decode."""
    model = _perturb(build_sam2("sam2.1-hiera-tiny", random_weights=True, device="cpu", seed=0))
    hf = sam2_to_transformers(model)
    cfg = hf.config.vision_config
    assert cfg.backbone_config.blocks_per_stage == [1, 2, 7, 2]
    assert cfg.backbone_config.global_attention_blocks == [5, 7, 9]
    assert cfg.backbone_feature_sizes == [[256, 256], [128, 128], [64, 64]]
    x = torch.randn(1, 3, 1024, 1024, generator=torch.Generator().manual_seed(0))
    coords = torch.tensor([[[400.0, 650.0]]])
    labels = torch.tensor([[1]], dtype=torch.int32)
    with torch.no_grad():
        meta = _meta_embeddings(model, x)
        ours = hf.get_image_embeddings(x)
        for level, (a, b) in enumerate(zip(meta, ours, strict=True)):
            _close(a, b, f"level {level}")
        sparse, dense = model.sam_prompt_encoder(points=(coords, labels), boxes=None, masks=None)
        masks, iou, _, obj = model.sam_mask_decoder(
            image_embeddings=meta[-1],
            image_pe=model.sam_prompt_encoder.get_dense_pe(),
            sparse_prompt_embeddings=sparse,
            dense_prompt_embeddings=dense,
            multimask_output=False,
            repeat_image=False,
            high_res_features=meta[:-1],
        )
        out = hf(
            image_embeddings=ours,
            input_points=coords[None],
            input_labels=labels[None],
            multimask_output=False,
        )
    _close(masks, out.pred_masks[0], "mask logits")
    _close(iou, out.iou_scores[0], "IoU predictions")
    _close(obj, out.object_score_logits[0], "object score logits")


# --- errors -----------------------------------------------------------------------------------
def test_unknown_key_raises(tiny):
    sd = dict(tiny["model"].state_dict())
    sd["sam_mask_decoder.extra_head.weight"] = torch.zeros(1)
    with pytest.raises(LfsamError, match=r"unknown SAM 2 state-dict keys.*extra_head"):
        sam2_state_dict_to_transformers(sd)


def test_missing_key_raises(tiny):
    reference = tiny["hf"].state_dict()
    sd = dict(tiny["model"].state_dict())
    assert set(sam2_state_dict_to_transformers(sd, reference=reference)) == set(reference)
    del sd["image_encoder.trunk.blocks.2.norm2.bias"]
    with pytest.raises(LfsamError, match=r"not filled.*blocks.2.layer_norm2.bias"):
        sam2_state_dict_to_transformers(sd, reference=reference)


@pytest.mark.parametrize(
    "key",
    [
        "no_mem_embed",
        "sam_prompt_encoder.pe_layer.positional_encoding_gaussian_matrix",
        "sam_prompt_encoder.point_embeddings.1.weight",
    ],
)
def test_missing_merged_key_raises_without_reference(tiny, key):
    sd = dict(tiny["model"].state_dict())
    del sd[key]
    with pytest.raises(LfsamError, match="lacks"):
        sam2_state_dict_to_transformers(sd)


def test_wrong_shape_raises(tiny):
    reference = tiny["hf"].state_dict()
    sd = dict(tiny["model"].state_dict())
    sd["sam_mask_decoder.conv_s0.bias"] = torch.zeros(5)
    with pytest.raises(LfsamError, match=r"shape mismatch.*conv_s0.bias"):
        sam2_state_dict_to_transformers(sd, reference=reference)


def test_the_mapping_names_sammodel_heads():
    """SAM v1's heads as Meta modules (no high-resolution maps, no object scores) convert, by the
    same mapping, to exactly the head parameters of transformers' SamModel, shapes included; the
    no-memory embedding is Sam2Model's alone."""
    from transformers import SamConfig, SamModel, SamVisionConfig

    from lfsam.segmenters.transformers.heads import build_meta_heads

    config = SamConfig(
        vision_config=SamVisionConfig(hidden_size=32, num_hidden_layers=1, num_attention_heads=2,
                                      image_size=128, output_channels=32, num_pos_feats=16,
                                      global_attn_indexes=[0], mlp_dim=64),
        prompt_encoder_config={"hidden_size": 32, "image_size": 128},
        mask_decoder_config={"hidden_size": 32, "mlp_dim": 64, "num_attention_heads": 2,
                             "iou_head_hidden_dim": 32},
    )
    heads = build_meta_heads(config)
    assert not heads.sam_mask_decoder.use_high_res_features
    assert not heads.sam_mask_decoder.pred_obj_scores
    reference = {
        k: v for k, v in SamModel(config).state_dict().items()
        if k.startswith(("prompt_encoder.", "mask_decoder.", "shared_image_embedding."))
    }
    converted = sam2_state_dict_to_transformers(
        heads.state_dict(), reference=reference, target="SamModel"
    )
    assert "mask_decoder.transformer.layers.0.mlp.lin1.weight" in converted
    assert "prompt_encoder.point_embed.3.weight" in converted
    with pytest.raises(LfsamError, match="not filled"):
        sam2_state_dict_to_transformers(heads.state_dict(), reference=reference)
