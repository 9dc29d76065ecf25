"""Which SAM 2 models lfsam knows: name -> hydra config, model-hub id, checkpoint file.

The names follow the model hub (``facebook/<name>``) and Meta's ``sam2.build_sam``
(``HF_MODEL_ID_TO_FILENAMES``): SAM 2.1 and SAM 2.0 in four sizes each (Ravi et al. 2024, "SAM 2:
Segment Anything in Images and Videos", model table of the ``sam2`` README). The paper uses
``sam2.1-hiera-small`` (paper section 4, implementation details; docs/design.md section 3.1), the
default.

``sam2-tiny-test`` is the same SAM 2.1 architecture shrunk by hydra overrides of the tiny config to
about 0.9 M parameters and a 256-pixel input (docs/design.md section 6). It has no published
weights: it runs with random weights (or a checkpoint the tests write) so the whole SAM 2 code path
can be exercised in tests on a CPU.

:data:`TRANSFORMERS_MODELS` are the models lfsam runs from Hugging Face ``transformers``
checkpoints (:mod:`lfsam.segmenters.transformers.backend`; docs/design.md section 3.8): EdgeTAM
(Zhou et al.
2025, "EdgeTAM: On-Device Track Anything Model", CVPR 2025), SAM 2's on-device variant with a
RepViT image encoder, from the hub's transformers-format copy ``yonigozlan/EdgeTAM-hf`` (the
checkpoint ``transformers``' own EdgeTAM documentation uses), and ``edgetam-tiny-test``, the same
classes at a tiny size. :data:`TRANSFORMERS_FOLDER` (``--model transformers``) is any local
transformers-format folder given with ``--checkpoint DIR`` (its ``config.json`` names the model
type).
"""

from __future__ import annotations

from dataclasses import dataclass

from lfsam.errors import LfsamError

__all__ = [
    "DEFAULT_MODEL",
    "MODELS",
    "ORACLE",
    "TINY_EDGETAM_TEST_MODEL",
    "TINY_TEST_MODEL",
    "TRANSFORMERS_FOLDER",
    "TRANSFORMERS_MODELS",
    "ModelSpec",
    "TransformersModelSpec",
    "get_model_spec",
    "model_family",
]

DEFAULT_MODEL = "sam2.1-hiera-small"
"""The paper's model (Hiera-S, SAM 2.1)."""

ORACLE = "oracle"
"""Name of the ground-truth oracle backend (not a SAM 2 model)."""

TINY_TEST_MODEL = "sam2-tiny-test"
"""A 0.9 M-parameter SAM 2.1 for tests and quick demos (random weights)."""

# Hydra overrides that shrink the SAM 2.1 tiny config (docs/design.md section 6). Widths must agree:
# the neck width (32) is the SAM heads' and memory attention's width and the memory encoder's
# input; the memory encoder's output (16) is the cross-attention key width; the position
# encodings match the widths they are added to; RoPE feature sizes are image_size / 16. Hiera
# with stages [1, 1, 2, 1] pools at blocks 1, 2 and 4, so its one global block is block 3.
_TINY_OVERRIDES: tuple[str, ...] = (
    "++model.image_size=256",
    "++model.image_encoder.trunk.embed_dim=16",
    "++model.image_encoder.trunk.stages=[1,1,2,1]",
    "++model.image_encoder.trunk.global_att_blocks=[3]",
    "++model.image_encoder.neck.d_model=32",
    "++model.image_encoder.neck.backbone_channel_list=[128,64,32,16]",
    "++model.image_encoder.neck.position_encoding.num_pos_feats=32",
    "++model.memory_attention.d_model=32",
    "++model.memory_attention.num_layers=1",
    "++model.memory_attention.layer.d_model=32",
    "++model.memory_attention.layer.dim_feedforward=64",
    "++model.memory_attention.layer.self_attention.embedding_dim=32",
    "++model.memory_attention.layer.self_attention.feat_sizes=[16,16]",
    "++model.memory_attention.layer.cross_attention.embedding_dim=32",
    "++model.memory_attention.layer.cross_attention.feat_sizes=[16,16]",
    "++model.memory_attention.layer.cross_attention.kv_in_dim=16",
    "++model.memory_encoder.in_dim=32",
    "++model.memory_encoder.out_dim=16",
    "++model.memory_encoder.position_encoding.num_pos_feats=16",
    "++model.memory_encoder.mask_downsampler.embed_dim=32",
    "++model.memory_encoder.fuser.layer.dim=32",
)


@dataclass(frozen=True)
class ModelSpec:
    """How to build one SAM 2 model and where its weights live.

    Parameters
    ----------
    name : str
        lfsam's name for the model (``--model``).
    config : str
        Hydra config name inside the ``sam2`` package, as ``sam2.build_sam`` uses it.
    hub_id : str or None
        Model-hub repository holding the checkpoint, or None if there are no published weights.
    checkpoint_file : str or None
        The checkpoint's file name in that repository (and the name users download by hand).
    params : int
        Number of parameters of the architecture (``sum(p.numel())`` of the built model; checked
        against a real build in ``tests/test_segmenters_registry.py``).
    image_size : int
        Side of the square model input in pixels.
    overrides : tuple of str
        Extra hydra overrides applied to ``config``.
    description : str
        One line for ``lfsam models``.
    """

    name: str
    config: str
    hub_id: str | None
    checkpoint_file: str | None
    params: int
    image_size: int = 1024
    overrides: tuple[str, ...] = ()
    description: str = ""

    @property
    def random_only(self) -> bool:
        """True if no published weights exist (the model is built with random weights)."""
        return self.hub_id is None

    @property
    def backbone_feature_sizes(self) -> list[tuple[int, int]]:
        """Spatial sizes of the three backbone levels the SAM heads use: image_size / 4, 8, 16."""
        return [(self.image_size // k, self.image_size // k) for k in (4, 8, 16)]


def _real(version: str, size: str, short: str, params: int, note: str) -> ModelSpec:
    prefix = "sam2.1" if version == "2.1" else "sam2"
    folder = "sam2.1" if version == "2.1" else "sam2"
    return ModelSpec(
        name=f"{prefix}-hiera-{size}",
        config=f"configs/{folder}/{prefix}_hiera_{short}.yaml",
        hub_id=f"facebook/{prefix}-hiera-{size}",
        checkpoint_file=f"{prefix}_hiera_{size.replace('-', '_')}.pt",
        params=params,
        description=f"SAM {version} Hiera-{note}",
    )


MODELS: dict[str, ModelSpec] = {
    spec.name: spec
    for spec in (
        _real("2.1", "tiny", "t", 38_962_498, "T"),
        _real("2.1", "small", "s", 46_060_354, "S (the paper's model)"),
        _real("2.1", "base-plus", "b+", 80_850_178, "B+"),
        _real("2.1", "large", "l", 224_446_642, "L"),
        _real("2.0", "tiny", "t", 38_945_986, "T"),
        _real("2.0", "small", "s", 46_043_842, "S"),
        _real("2.0", "base-plus", "b+", 80_833_666, "B+"),
        _real("2.0", "large", "l", 224_430_130, "L"),
        ModelSpec(
            name=TINY_TEST_MODEL,
            config="configs/sam2.1/sam2.1_hiera_t.yaml",
            hub_id=None,
            checkpoint_file=None,
            params=883_914,
            image_size=256,
            overrides=_TINY_OVERRIDES,
            description="tiny SAM 2.1 for tests (random weights: no useful masks)",
        ),
    )
}
"""Every SAM 2 model by name, in the order ``lfsam models`` lists them."""


TINY_EDGETAM_TEST_MODEL = "edgetam-tiny-test"
"""A 0.1 M-parameter EdgeTAM for tests (random weights)."""

TRANSFORMERS_FOLDER = "transformers"
"""``--model`` for a transformers-format folder given with ``--checkpoint DIR`` (the default
when such a folder is given without ``--model``)."""


@dataclass(frozen=True)
class TransformersModelSpec:
    """One model lfsam runs from a ``transformers`` checkpoint (docs/design.md section 3.8).

    Parameters
    ----------
    name : str
        ``--model`` name.
    model_type : str
        ``config.json``'s ``model_type`` family: ``"edgetam"`` or ``"sam2"``.
    hub_id : str or None
        Model-hub repository in transformers format, or None (random weights only).
    params : int
        Parameters of the image model (encoder and SAM heads; checked against a real build in
        ``tests/test_segmenters_transformers.py``).
    image_size : int
        Side of the square model input.
    description : str
        One line for ``lfsam models``.
    """

    name: str
    model_type: str
    hub_id: str | None
    params: int
    image_size: int = 1024
    description: str = ""

    @property
    def random_only(self) -> bool:
        """True if no published weights exist."""
        return self.hub_id is None


TRANSFORMERS_MODELS: dict[str, TransformersModelSpec] = {
    spec.name: spec
    for spec in (
        TransformersModelSpec(
            name="edgetam",
            model_type="edgetam",
            hub_id="yonigozlan/EdgeTAM-hf",
            params=9_120_641,
            description="EdgeTAM: on-device SAM 2, RepViT encoder (the fast one)",
        ),
        TransformersModelSpec(
            name=TINY_EDGETAM_TEST_MODEL,
            model_type="edgetam",
            hub_id=None,
            params=108_133,
            image_size=256,
            description="tiny EdgeTAM for tests (random weights: no useful masks)",
        ),
    )
}
"""Models run from ``transformers`` checkpoints, in the order ``lfsam models`` lists them."""


def model_family(name: str) -> str | None:
    """The architecture family of a model name: ``"sam2"`` (Meta's SAM 2 models), ``"edgetam"``,
    or None (the oracle, :data:`TRANSFORMERS_FOLDER`: any family)."""
    if name in MODELS:
        return "sam2"
    if name in TRANSFORMERS_MODELS:
        return TRANSFORMERS_MODELS[name].model_type
    return None


def get_model_spec(name: str) -> ModelSpec:
    """The :class:`ModelSpec` of a SAM 2 model name.

    Raises
    ------
    LfsamError
        If the name is unknown (the message lists the known names).
    """
    try:
        return MODELS[name]
    except KeyError:
        known = ", ".join([*MODELS, *TRANSFORMERS_MODELS, TRANSFORMERS_FOLDER, ORACLE])
        raise LfsamError(
            f"unknown model {name!r}; choose one of: {known} (see `lfsam models`)"
        ) from None
