"""The estimator's independent steps run beside each other and give what they give one after
the other (issue 65; docs/design.md section 3.2, "Speed: cache-sized pieces")."""

from __future__ import annotations

import threading
from concurrent.futures import Future

import numpy as np
import torch

import lfsam.disparity.occlusion_aware as occlusion_aware
from lfsam.devices import thread_share, threads_of
from lfsam.disparity import estimate_disparity
from lfsam.synth import generate_scene


class _OneAfterTheOther:
    """An executor that runs each job when it is submitted."""

    def __init__(self, max_workers: int) -> None:
        self.max_workers = max_workers

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        return None

    def submit(self, function, *args, **kwargs) -> Future:
        future: Future = Future()
        future.set_result(function(*args, **kwargs))
        return future


def test_the_wide_scale_and_the_structure_tensor_beside_the_fine_scale(monkeypatch):
    lf = generate_scene(grid=(5, 5), size=(48, 64), seed=3)
    threads = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        beside = estimate_disparity(lf, view=(1, 3), device="cpu")
        # one after the other, each at all of torch's threads (not at its share of them)
        monkeypatch.setattr(occlusion_aware, "ThreadPoolExecutor", _OneAfterTheOther)
        monkeypatch.setattr(occlusion_aware, "thread_share",
                            lambda streams, device: torch.get_num_threads())
        alone = estimate_disparity(lf, view=(1, 3), device="cpu")
    finally:
        torch.set_num_threads(threads)
    assert beside.meta["fusion"] and beside.meta["wide_feature_radius"] == 2
    np.testing.assert_array_equal(beside.disparity, alone.disparity)
    np.testing.assert_array_equal(beside.confidence, alone.confidence)


def test_threads_beside_each_other_split_torch_threads_and_keep_their_own():
    threads = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        assert thread_share(3, torch.device("cpu")) == 1
        assert thread_share(1, torch.device("cpu")) == 2
        assert thread_share(3, torch.device("cuda")) == 2
        inside, outside = threading.Event(), threading.Event()
        seen = {}

        def worker() -> None:
            with threads_of(1):
                seen["worker"] = torch.get_num_threads()
                inside.set()
                outside.wait(10)
            seen["worker after"] = torch.get_num_threads()

        thread = threading.Thread(target=worker)
        thread.start()
        inside.wait(10)
        seen["caller"] = torch.get_num_threads()  # while the worker runs at one thread
        outside.set()
        thread.join(10)
        assert seen == {"worker": 1, "caller": 2, "worker after": 2}
        with threads_of(1):
            assert torch.get_num_threads() == 1
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(threads)
