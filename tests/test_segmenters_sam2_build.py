"""Building SAM 2: devices, seeded random weights, checkpoints, offline behaviour, video model."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
import torch

from lfsam.errors import LfsamError
from lfsam.segmenters.hub import hub_cache_dir
from lfsam.segmenters.registry import TINY_TEST_MODEL
from lfsam.segmenters.sam2.build import (
    build_sam2,
    build_sam2_video,
    cached_checkpoint,
    inference_context,
    load_checkpoint,
    resolve_checkpoint,
    resolve_device,
)


def _same_weights(a: torch.nn.Module, b: torch.nn.Module) -> bool:
    sa, sb = a.state_dict(), b.state_dict()
    return sa.keys() == sb.keys() and all(torch.equal(sa[k].cpu(), sb[k].cpu()) for k in sa)


@pytest.fixture
def empty_hub(tmp_path, monkeypatch) -> Path:
    """An empty Hugging Face cache and no network for the hub."""
    home = tmp_path / "hf_home"
    home.mkdir()
    monkeypatch.setenv("HF_HOME", str(home))
    monkeypatch.setenv("HF_HUB_CACHE", str(home / "hub"))
    monkeypatch.delenv("HUGGINGFACE_HUB_CACHE", raising=False)
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    return home


@pytest.fixture(scope="module")
def tiny_checkpoint(tmp_path_factory) -> tuple[Path, torch.nn.Module]:
    """The tiny model (seed 3) saved in SAM 2's checkpoint format."""
    model = build_sam2(TINY_TEST_MODEL, device="cpu", seed=3)
    path = tmp_path_factory.mktemp("ckpt") / "tiny.pt"
    torch.save({"model": model.state_dict()}, path)
    return path, model


# --- device ---------------------------------------------------------------------------------
def test_resolve_device():
    assert resolve_device("cpu") == torch.device("cpu")
    auto = resolve_device(None)
    assert auto == resolve_device("auto")
    expected = "cuda" if torch.cuda.is_available() else None
    if expected:
        assert auto.type == expected
    elif not (getattr(torch.backends, "mps", None) and torch.backends.mps.is_available()):
        assert auto.type == "cpu"
    with pytest.raises(LfsamError, match="unknown device"):
        resolve_device("gpu0")
    if not torch.cuda.is_available():
        with pytest.raises(LfsamError, match="CUDA is not available"):
            resolve_device("cuda")


def test_inference_context_disables_autograd():
    x = torch.ones(2, requires_grad=True)
    with inference_context(torch.device("cpu")):
        assert torch.is_inference_mode_enabled()
        y = x * 2
    assert not y.requires_grad
    with inference_context(torch.device("cpu"), inference_mode=False):
        assert not torch.is_grad_enabled() and not torch.is_inference_mode_enabled()


# --- random weights -------------------------------------------------------------------------
def test_random_weights_are_deterministic_per_seed_and_leave_global_rng_alone():
    torch.manual_seed(123)
    expected_next = torch.rand(1)
    torch.manual_seed(123)
    a = build_sam2(TINY_TEST_MODEL, device="cpu", seed=0)
    assert torch.equal(torch.rand(1), expected_next)  # global RNG stream untouched
    b = build_sam2(TINY_TEST_MODEL, device="cpu", seed=0)
    c = build_sam2(TINY_TEST_MODEL, device="cpu", seed=1)
    assert _same_weights(a, b)
    assert not _same_weights(a, c)
    assert not a.training
    info = a.lfsam_info
    assert info["random_weights"] is True and info["checkpoint"] is None
    assert info["name"] == TINY_TEST_MODEL and info["params"] == sum(
        p.numel() for p in a.parameters()
    )


def test_random_weights_and_checkpoint_are_exclusive(tiny_checkpoint):
    path, _ = tiny_checkpoint
    with pytest.raises(LfsamError, match="not both"):
        build_sam2(TINY_TEST_MODEL, checkpoint=path, random_weights=True, device="cpu")


# --- checkpoints ----------------------------------------------------------------------------
def test_checkpoint_file_is_loaded(tiny_checkpoint):
    path, original = tiny_checkpoint
    loaded = build_sam2(TINY_TEST_MODEL, checkpoint=path, device="cpu", seed=0)
    assert _same_weights(loaded, original)
    assert not _same_weights(loaded, build_sam2(TINY_TEST_MODEL, device="cpu", seed=0))
    assert loaded.lfsam_info["random_weights"] is False
    assert loaded.lfsam_info["checkpoint"] == str(path)


def test_missing_checkpoint_file_is_a_user_error(tmp_path):
    with pytest.raises(LfsamError, match="not found") as info:
        build_sam2(TINY_TEST_MODEL, checkpoint=tmp_path / "nope.pt", device="cpu")
    assert "\n" not in str(info.value)


def test_corrupt_checkpoint_is_a_user_error(tmp_path, tiny_checkpoint):
    corrupt = tmp_path / "corrupt.pt"
    corrupt.write_bytes(tiny_checkpoint[0].read_bytes()[:1000])  # truncated download
    with pytest.raises(LfsamError, match="cannot be read") as info:
        build_sam2(TINY_TEST_MODEL, checkpoint=corrupt, device="cpu")
    assert "\n" not in str(info.value)
    text = tmp_path / "text.pt"
    text.write_text("not a checkpoint")
    with pytest.raises(LfsamError, match="cannot be read"):
        build_sam2(TINY_TEST_MODEL, checkpoint=text, device="cpu")


def test_checkpoint_of_wrong_format_or_model_is_a_user_error(tmp_path, tiny_checkpoint):
    _, original = tiny_checkpoint
    state = original.state_dict()
    bare = tmp_path / "bare.pt"
    torch.save(state, bare)  # a state dict without the {"model": ...} wrapper
    with pytest.raises(LfsamError, match="not a SAM 2 checkpoint"):
        build_sam2(TINY_TEST_MODEL, checkpoint=bare, device="cpu")

    model = build_sam2(TINY_TEST_MODEL, device="cpu")
    key = next(iter(state))
    missing = tmp_path / "missing.pt"
    torch.save({"model": {k: v for k, v in state.items() if k != key}}, missing)
    with pytest.raises(LfsamError, match="1 missing") as info:
        load_checkpoint(model, missing, TINY_TEST_MODEL)
    assert key in str(info.value)
    reshaped = dict(state)
    reshaped[key] = torch.zeros(3, 1, 2)
    other = tmp_path / "other.pt"
    torch.save({"model": reshaped}, other)
    with pytest.raises(LfsamError, match="1 differently shaped"):
        load_checkpoint(model, other, TINY_TEST_MODEL)
    assert _same_weights(model, build_sam2(TINY_TEST_MODEL, device="cpu"))  # left untouched


# --- hub cache and offline ------------------------------------------------------------------
def test_offline_without_cache_fails_fast_with_one_line(empty_hub):
    start = time.perf_counter()
    with pytest.raises(LfsamError) as info:
        build_sam2("sam2.1-hiera-small", device="cpu")
    elapsed = time.perf_counter() - start
    message = str(info.value)
    assert elapsed < 2.0
    assert "\n" not in message
    assert "sam2.1_hiera_small.pt" in message and "--checkpoint FILE" in message
    assert not any(p.is_file() for p in empty_hub.rglob("*"))  # nothing partial left


def test_unreachable_hub_fails_fast(empty_hub, monkeypatch):
    monkeypatch.delenv("HF_HUB_OFFLINE")
    monkeypatch.delenv("TRANSFORMERS_OFFLINE", raising=False)
    for var in ("HTTPS_PROXY", "https_proxy"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("HF_ENDPOINT", "http://127.0.0.1:9")  # discard port: refused at once
    start = time.perf_counter()
    with pytest.raises(LfsamError, match="cannot be reached") as info:
        resolve_checkpoint("sam2-hiera-large", timeout=1.0)
    assert time.perf_counter() - start < 3.0
    assert "sam2_hiera_large.pt" in str(info.value)
    assert not any(p.is_file() for p in empty_hub.rglob("*"))


def test_cached_weights_are_found_without_network(empty_hub):
    cache = hub_cache_dir()
    assert cache == empty_hub / "hub"
    assert cached_checkpoint("sam2.1-hiera-small") is None
    repo = cache / "models--facebook--sam2.1-hiera-small"
    (repo / "refs").mkdir(parents=True)
    (repo / "refs" / "main").write_text("0123abcd")
    snapshot = repo / "snapshots" / "0123abcd"
    snapshot.mkdir(parents=True)
    (snapshot / "sam2.1_hiera_small.pt").write_bytes(b"weights")
    found = cached_checkpoint("sam2.1-hiera-small")
    assert found == snapshot / "sam2.1_hiera_small.pt"
    assert resolve_checkpoint("sam2.1-hiera-small") == found  # offline, from the cache
    assert cached_checkpoint("sam2.1-hiera-tiny") is None
    assert cached_checkpoint(TINY_TEST_MODEL) is None


def test_tiny_model_without_weights_needs_random_or_checkpoint():
    with pytest.raises(LfsamError, match="no published weights"):
        resolve_checkpoint(TINY_TEST_MODEL)


# --- video predictor ------------------------------------------------------------------------
@pytest.mark.filterwarnings("ignore::UserWarning")  # hole filling needs sam2's CUDA extension
def test_video_predictor_tracks_on_tiny_model(tmp_path, tiny_checkpoint):
    import imageio.v3 as iio

    path, original = tiny_checkpoint
    video = build_sam2_video(TINY_TEST_MODEL, checkpoint=path, device="cpu")
    assert type(video).__name__ == "SAM2VideoPredictor"
    assert _same_weights(video, original)  # the image checkpoint fits the video model
    rng = np.random.default_rng(0)
    for i in range(3):
        iio.imwrite(tmp_path / f"{i}.jpg", rng.integers(0, 255, (32, 48, 3), dtype=np.uint8))
    with inference_context(video.device):
        state = video.init_state(str(tmp_path))
        video.add_new_points_or_box(
            state, frame_idx=0, obj_id=1, points=np.array([[20.0, 10.0]]), labels=np.array([1])
        )
        video.add_new_points_or_box(state, frame_idx=0, obj_id=7, box=np.array([5, 5, 30, 25]))
        frames = {f: (ids, m.shape) for f, ids, m in video.propagate_in_video(state)}
    assert sorted(frames) == [0, 1, 2]
    assert all(ids == [1, 7] and shape == (2, 1, 32, 48) for ids, shape in frames.values())
