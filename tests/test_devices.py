"""One device vocabulary (lfsam.devices) and the encode batch size decided from the device."""

from __future__ import annotations

import pytest
import torch

import lfsam.pipeline.config as pipeline_config
from lfsam.api import RunOptions, SegmentOptions, segment
from lfsam.devices import check_device_spec, default_encode_batch_size, resolve_device
from lfsam.errors import LfsamError
from lfsam.pipeline import PipelineConfig
from lfsam.segmenters.oracle import OracleSegmenter
from lfsam.synth import generate_scene

HAS_CUDA = torch.cuda.is_available()
HAS_MPS = bool(getattr(torch.backends, "mps", None) and torch.backends.mps.is_available())


def test_auto_and_none_pick_cuda_then_mps_then_cpu():
    expected = "cuda" if HAS_CUDA else ("mps" if HAS_MPS else "cpu")
    assert resolve_device(None).type == expected
    assert resolve_device("auto") == resolve_device(None) == resolve_device(" AUTO ")


def test_cpu_in_any_spelling_and_as_torch_device():
    for spec in ("cpu", "CPU", " cpu ", torch.device("cpu")):
        assert resolve_device(spec) == torch.device("cpu")


@pytest.mark.parametrize("spec", ["gpu", "cuda0", "cuda:", "cuda:-1", "xpu", "", "cpu:0:1"])
def test_unknown_spellings_are_one_line_errors_naming_the_vocabulary(spec):
    with pytest.raises(LfsamError) as info:
        resolve_device(spec)
    message = str(info.value)
    assert "\n" not in message and "unknown device" in message
    assert "auto" in message and "cuda:N" in message and "mps" in message


def test_spelling_check_normalises_without_touching_the_hardware():
    assert check_device_spec(" CUDA:1 ") == "cuda:1"  # valid spelling even without a GPU
    with pytest.raises(LfsamError, match="--device gpu: unknown device"):
        check_device_spec("gpu")


@pytest.mark.skipif(HAS_CUDA, reason="checks the message on a machine without CUDA")
def test_cuda_without_a_gpu_says_what_to_use_instead():
    for spec in ("cuda", "cuda:0", torch.device("cuda")):
        with pytest.raises(LfsamError, match="CUDA is not available here; use --device auto"):
            resolve_device(spec)


@pytest.mark.cuda  # run by make gpu-check
@pytest.mark.skipif(not HAS_CUDA, reason="needs a CUDA device")
def test_cuda_index_beyond_the_machine_is_an_error():
    assert resolve_device("cuda:0") == torch.device("cuda:0")
    with pytest.raises(LfsamError, match="use cuda:0 or auto"):
        resolve_device(f"cuda:{torch.cuda.device_count()}")


@pytest.mark.skipif(HAS_MPS, reason="checks the message on a machine without MPS")
def test_mps_without_mps_is_an_error():
    with pytest.raises(LfsamError, match="MPS is not available here"):
        resolve_device("mps")


def test_encode_batch_size_comes_from_the_device():
    assert default_encode_batch_size(torch.device("cpu")) == 1
    assert default_encode_batch_size(torch.device("cuda")) > 1  # batched on CUDA
    assert default_encode_batch_size("cuda:1") == default_encode_batch_size("cuda")
    config = PipelineConfig()
    assert config.encode_batch_size is None
    assert config.batch_size_for("cpu") == 1
    assert config.batch_size_for("cuda") == default_encode_batch_size("cuda")
    assert PipelineConfig(encode_batch_size=3).batch_size_for("cuda") == 3
    with pytest.raises(LfsamError, match="at least 1"):
        PipelineConfig(encode_batch_size=0)


def test_pipeline_encodes_views_in_batches_of_the_device_default(monkeypatch):
    scene = generate_scene(grid=(3, 3), size=(32, 40), seed=2, num_objects=2)
    segmenter = OracleSegmenter(scene, device="cpu")
    sizes = []
    encode = segmenter.encode

    def counting_encode(images, keys=None):
        sizes.append(len(images))
        return encode(images, keys)

    monkeypatch.setattr(segmenter, "encode", counting_encode)
    monkeypatch.setattr(pipeline_config, "default_encode_batch_size", lambda device: 3)
    quiet = RunOptions(progress=False)
    segment(scene, model=segmenter, disparity=scene.disparity[1, 1],
            options=SegmentOptions(run=quiet))
    assert sizes == [1, 3, 3, 2]  # the center view, then the 8 others three at a time
    sizes.clear()
    config = PipelineConfig(encode_batch_size=5)
    segment(scene, model=segmenter, disparity=scene.disparity[1, 1],
            options=SegmentOptions(pipeline=config, run=quiet))
    assert sizes == [1, 5, 3]  # an explicit size wins over the device's
