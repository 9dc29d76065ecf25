"""Views become SAM 2 video frames without a pixel changing, and the state matches init_state."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from PIL import Image

from lfsam.baseline import init_video_state, video_frames
from lfsam.errors import LfsamError


def _views(count: int = 3, size: tuple[int, int] = (32, 48), seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.integers(0, 256, (count, *size, 3), dtype=np.uint8)


def _sam2_loader_frames(views: np.ndarray, folder, image_size: int) -> torch.Tensor:
    """SAM 2's own video loader on the views saved losslessly (PNG bytes under .jpg names)."""
    from sam2.utils.misc import load_video_frames

    for index, view in enumerate(views):
        Image.fromarray(view).save(folder / f"{index}.jpg", format="PNG")
    frames, height, width = load_video_frames(
        str(folder), image_size, offload_video_to_cpu=True, compute_device=torch.device("cpu")
    )
    assert (height, width) == views.shape[1:3]
    return frames


def test_video_transform_equals_sam2_video_loader(tmp_path):
    views = _views()
    expected = _sam2_loader_frames(views, tmp_path, 64)
    frames = video_frames(views, 64, "cpu", "video")
    assert frames.shape == (3, 3, 64, 64) and frames.dtype == torch.float32
    assert torch.equal(frames, expected)


def test_image_transform_equals_image_predictor_transform():
    from sam2.utils.transforms import SAM2Transforms

    views = _views(count=10)  # more than one internal chunk
    transforms = SAM2Transforms(resolution=64, mask_threshold=0.0)
    expected = torch.stack([transforms(view) for view in views])  # ToTensor + Resize + Normalize
    frames = video_frames(views, 64, "cpu", "image")
    torch.testing.assert_close(frames, expected, rtol=0, atol=1e-6)


def test_frames_keep_view_content():
    """A uniform view stays uniform at exactly the normalised colour (no shift, no mixing)."""
    views = np.zeros((2, 20, 30, 3), np.uint8)
    views[0] = (255, 0, 128)
    views[1] = (10, 200, 30)
    for transform in ("video", "image"):
        frames = video_frames(views, 32, "cpu", transform)
        for view, frame in zip(views, frames, strict=True):
            rgb = view[0, 0] / 255.0
            expected = (rgb - np.array([0.485, 0.456, 0.406])) / np.array([0.229, 0.224, 0.225])
            np.testing.assert_allclose(
                frame.numpy(), np.broadcast_to(expected[:, None, None], frame.shape), atol=1e-5
            )


@pytest.mark.parametrize(
    "views, transform",
    [
        (np.zeros((2, 8, 8, 3), np.float32), "video"),
        (np.zeros((8, 8, 3), np.uint8), "video"),
        (np.zeros((0, 8, 8, 3), np.uint8), "video"),
        (np.zeros((1, 8, 8, 3), np.uint8), "jpeg"),
    ],
)
def test_bad_frames_are_user_errors(views, transform):
    with pytest.raises(LfsamError):
        video_frames(views, 32, "cpu", transform)


def test_state_matches_sam2_init_state(tmp_path):
    """Our in-memory state has init_state's keys and values (sam2 1.1), frames included."""
    from lfsam.segmenters.sam2.build import build_sam2_video

    predictor = build_sam2_video("sam2-tiny-test", random_weights=True, device="cpu")
    views = _views(count=2)
    for index, view in enumerate(views):
        Image.fromarray(view).save(tmp_path / f"{index}.jpg", format="PNG")
    reference = predictor.init_state(str(tmp_path))
    frames = video_frames(views, predictor.image_size, predictor.device, "video")
    state = init_video_state(predictor, frames, views.shape[1:3])
    assert set(state) == set(reference)
    assert torch.equal(state["images"], reference["images"])
    for key, value in reference.items():
        if key in ("images", "cached_features"):  # init_state pre-encodes frame 0; we do not
            continue
        assert type(state[key]) is type(value), key
        assert state[key] == value, key
