"""The model registry agrees with Meta's sam2 package and with the built architectures."""

from __future__ import annotations

import pytest
import torch
from sam2.build_sam import HF_MODEL_ID_TO_FILENAMES

from lfsam.errors import LfsamError
from lfsam.segmenters import available_models
from lfsam.segmenters.registry import (
    DEFAULT_MODEL,
    MODELS,
    ORACLE,
    TINY_TEST_MODEL,
    TRANSFORMERS_FOLDER,
    TRANSFORMERS_MODELS,
    get_model_spec,
)
from lfsam.segmenters.sam2.build import build_sam2


def test_real_models_match_sam2_hub_table():
    """Every published model maps to the config and file that sam2.build_sam uses for it."""
    real = {spec.hub_id: spec for spec in MODELS.values() if not spec.random_only}
    assert set(real) == set(HF_MODEL_ID_TO_FILENAMES)
    for hub_id, (config, filename) in HF_MODEL_ID_TO_FILENAMES.items():
        spec = real[hub_id]
        assert spec.config == config
        assert spec.checkpoint_file == filename
        assert spec.name == hub_id.split("/")[1]


def test_default_is_the_papers_model_and_names_are_listed():
    assert DEFAULT_MODEL == "sam2.1-hiera-small"  # paper section 4: Hiera-S, SAM 2.1
    assert get_model_spec(DEFAULT_MODEL).hub_id == "facebook/sam2.1-hiera-small"
    names = available_models()
    assert names[-1] == ORACLE
    assert set(names[:-1]) == {*MODELS, *TRANSFORMERS_MODELS, TRANSFORMERS_FOLDER}
    assert TINY_TEST_MODEL in names


def test_unknown_model_is_a_one_line_user_error():
    with pytest.raises(LfsamError) as info:
        get_model_spec("sam3-huge")
    message = str(info.value)
    assert "\n" not in message
    assert "sam3-huge" in message and DEFAULT_MODEL in message and ORACLE in message


def test_tiny_model_spec_matches_its_build():
    spec = get_model_spec(TINY_TEST_MODEL)
    model = build_sam2(TINY_TEST_MODEL, device="cpu")
    assert spec.random_only
    assert sum(p.numel() for p in model.parameters()) == spec.params
    assert model.image_size == spec.image_size == 256
    assert spec.backbone_feature_sizes == [(64, 64), (32, 32), (16, 16)]
    # the same Hiera blocks: global attention only at block 3, which is not a pooling block
    trunk = model.image_encoder.trunk
    assert [blk.window_size for blk in trunk.blocks].count(0) == 1
    assert trunk.blocks[3].window_size == 0
    assert trunk.blocks[3].pool is None


@pytest.mark.slow
@pytest.mark.parametrize("name", ["sam2.1-hiera-tiny", "sam2.1-hiera-small", "sam2-hiera-small"])
def test_parameter_counts_match_real_architectures(name):
    spec = get_model_spec(name)
    model = build_sam2(name, random_weights=True, device="cpu")
    assert sum(p.numel() for p in model.parameters()) == spec.params
    assert model.image_size == spec.image_size == 1024
    assert isinstance(model.no_mem_embed, torch.nn.Parameter)
