"""End-to-end checks of the LFSAM pipeline (paper section 3; docs/design.md section 7 targets).

With the oracle segmenter and ground-truth disparity the pipeline's quality is compared with the
scores of the ground-truth label field itself, which are not perfect (disocclusions and the frame
border keep its SIoU below 1).
"""

from __future__ import annotations

import time

import numpy as np
import pytest
import torch

from lfsam.api import RunOptions, SegmentOptions, make_prompts, segment
from lfsam.metrics import evaluate_labels
from lfsam.pipeline import PipelineConfig
from lfsam.segmenters import load_segmenter
from lfsam.synth import generate_scene


@pytest.fixture(scope="module")
def scenes():
    return [
        generate_scene(grid=(9, 9), size=(64, 96), seed=0, num_objects=5),
        generate_scene(grid=(9, 9), size=(64, 96), seed=1, num_objects=6),
        generate_scene(grid=(5, 7), size=(64, 96), seed=2, num_objects=6),
    ]


def _oracle_run(lf, config, disparity="gt"):
    segmenter = load_segmenter("oracle", lightfield=lf)
    return segment(lf, model=segmenter, disparity=disparity, options=_quiet(config))


def _quiet(config=None):
    return SegmentOptions(pipeline=config or PipelineConfig(), run=RunOptions(progress=False))


@pytest.mark.parametrize("index", [0, 1, 2])
def test_oracle_with_gt_disparity_meets_design_targets(scenes, index):
    lf = scenes[index]
    result = _oracle_run(lf, PipelineConfig())
    ours = evaluate_labels(result.labels, lf)
    ceiling = evaluate_labels(lf.labels, lf)
    assert ours["siou"] >= 0.97 * ceiling["siou"]
    assert ours["lpp"] <= 1.03 * ceiling["lpp"]
    assert ours["aa"] >= 0.99
    assert ours["coverage"] >= 0.97 * ceiling["coverage"]
    # Every view encoded exactly once: the center plus every other view.
    assert result.meta["views_encoded"] == lf.num_views


def test_ablation_rows_are_ordered_like_table_2(scenes):
    lf = scenes[1]
    scores = {
        name: evaluate_labels(_oracle_run(lf, PipelineConfig.from_ablation(name)).labels, lf)
        for name in ("none", "ref", "ref+occ")
    }
    # Refinement (exact oracle masks in each view) can only help consistency and accuracy.
    assert scores["ref"]["aa"] >= scores["none"]["aa"]
    assert scores["ref+occ"]["aa"] >= scores["none"]["aa"]
    assert scores["ref+occ"]["ue"] <= scores["none"]["ue"] + 1e-9


def test_geometric_occluding_reduces_leakage_into_occluders(scenes):
    # Without refinement, a propagated mask of a partly hidden object covers its occluder in
    # views where the occluder moves over it; the z-buffer removes those pixels.
    lf = scenes[0]

    def leakage(occlusion):
        result = _oracle_run(lf, PipelineConfig(refine=False, occlusion=occlusion))
        total, wrong = 0, 0
        for n in range(result.num_masks):
            masks = result.masks.mask(n)
            center_gt = lf.labels[lf.center][masks[lf.center]]
            source_label = np.bincount(center_gt).argmax()
            total += masks.sum()
            wrong += (masks & (lf.labels != source_label)).sum()
        return wrong / total

    assert leakage("geometric") < 0.8 * leakage("none")


def test_prompts_make_one_object_each_with_labels_in_prompt_order(scenes):
    lf = scenes[0]
    center = lf.center_labels
    picks = []
    for label in np.unique(center)[1:3]:
        rows, cols = np.nonzero(center == label)
        k = len(rows) // 2
        picks.append((label, (float(cols[k]), float(rows[k]))))
    prompts = make_prompts([xy for _, xy in picks])
    result = segment(
        lf, prompts, model=load_segmenter("oracle", lightfield=lf), disparity="gt",
        options=_quiet(),
    )
    assert result.num_masks == 2
    for i, (label, _) in enumerate(picks):
        # Mask i (label i + 1) is the ground-truth object under point i in every view.
        gt = lf.labels == label
        pred = result.masks.mask(i)
        assert (pred & gt).sum() / (pred | gt).sum() > 0.95


def test_estimated_disparity_runs_and_is_recorded(scenes):
    lf = scenes[2]
    result = _oracle_run(lf, PipelineConfig(), disparity="estimate")
    assert result.meta["disparity_source"].startswith("estimate")
    assert result.timings["disparity"] > 0
    assert evaluate_labels(result.labels, lf)["aa"] > 0.9


def test_tiny_sam2_end_to_end_encodes_each_view_once():
    lf = generate_scene(grid=(3, 3), size=(48, 64), seed=3, num_objects=3)
    segmenter = load_segmenter("sam2-tiny-test", random_weights=True, device="cpu")
    prompts = make_prompts([(20.0, 20.0), (40.0, 30.0)], [])
    result = segment(
        lf, prompts, model=segmenter, disparity=lf.center_disparity,
        options=_quiet(PipelineConfig(occlusion="both")),
    )
    assert segmenter.encode_calls == lf.num_views
    assert result.labels.shape == (3, 3, 48, 64)
    assert result.masks.shape == (2, 3, 3, 48, 64)
    assert result.fallback.shape == (2, 3, 3)
    assert set(result.timings) >= {"encode", "initial", "propagate", "occlude", "refine", "total"}
    # Center-view masks are the initial segmentation itself.
    assert not result.fallback[:, 1, 1].any()


def test_no_refine_no_semantic_encodes_only_the_center(scenes):
    lf = scenes[2]
    segmenter = load_segmenter("oracle", lightfield=lf)
    none = PipelineConfig.from_ablation("none")
    segment(lf, model=segmenter, disparity="gt", options=_quiet(none))
    assert segmenter.encode_calls == 1


def test_deterministic(scenes):
    lf = scenes[2]
    a = _oracle_run(lf, PipelineConfig(occlusion="both"))
    b = _oracle_run(lf, PipelineConfig(occlusion="both"))
    assert np.array_equal(a.labels, b.labels)
    assert torch.equal(torch.as_tensor(a.masks.data), torch.as_tensor(b.masks.data))


def test_the_center_disparity_estimate_is_its_own_stage(scenes):
    """Issue 46: the estimate, made on first use while step 1 carries the clicks, is timed as
    ``disparity``, not ``initial``; stages nested in others are not counted twice."""
    from lfsam.predictor import LightFieldPredictor
    from lfsam.prompts import ObjectPrompts, PointPrompt
    from lfsam.segmenters import load_segmenter
    from lfsam.timing import StageTimer

    lf = scenes[2]
    predictor = LightFieldPredictor(load_segmenter("oracle", lightfield=lf), progress=False)
    predictor.set_lightfield(lf, disparity="estimate")
    predictor.set_object(ObjectPrompts(1, (PointPrompt(20.0, 20.0, True, (0, 0)),)))
    timings = predictor.to_result().timings
    assert timings["disparity"] > 10 * timings["initial"]  # the oracle's decode is instant
    stages = sum(v for k, v in timings.items() if k != "total")
    assert stages <= timings["total"] + 1e-6

    timer = StageTimer(torch.device("cpu"))
    with timer("outer"):
        with timer("inner"):
            time.sleep(0.05)
    assert timer.seconds["inner"] >= 0.05 and timer.seconds["outer"] < 0.05
    assert timer.outermost["outer"] >= 0.05 and "inner" not in timer.outermost


def test_stage_timer_with_events_charges_the_same_stages_without_waiting(monkeypatch):
    """On CUDA the stage boundaries are events read when the times are read (issue 44's GPU
    run: a synchronisation per boundary was half of one click's host waits): the stages get
    the seconds host clocks give them, and the events are waited for once, at the first read."""
    import lfsam.timing as timing

    waits = []

    class FakeEvent:  # stands in for torch.cuda.Event: stamped when recorded
        def __init__(self) -> None:
            self.at = time.perf_counter()

        def synchronize(self) -> None:
            waits.append(self)

        def elapsed_time(self, end: FakeEvent) -> float:
            return (end.at - self.at) * 1000.0

    monkeypatch.setattr(timing, "_cuda_event", FakeEvent)
    timer = timing.StageTimer(torch.device("cpu"), events=True)
    clock = timing.StageTimer(torch.device("cpu"))
    for each in (timer, clock):
        with each("outer"):
            time.sleep(0.01)
            with each("inner"):
                time.sleep(0.03)
            time.sleep(0.01)
        with each("inner"):
            time.sleep(0.02)
    assert not waits  # nothing waited for while timing
    assert set(timer.seconds) == {"outer", "inner"} and len(waits) == 1
    for stage, expected in (("outer", 0.02), ("inner", 0.05)):
        assert timer.seconds[stage] == pytest.approx(clock.seconds[stage], abs=0.008)
        assert timer.seconds[stage] >= expected
    assert timer.outermost["outer"] >= 0.05 and timer.outermost["inner"] >= 0.02
    assert timer.outermost["outer"] == pytest.approx(clock.outermost["outer"], abs=0.008)
    assert len(waits) == 1  # read once, then kept


def test_stage_timer_keeps_a_bounded_number_of_events(monkeypatch):
    """A timer whose times are never read (a long interactive session) reads its events after
    ``MAX_PENDING`` intervals instead of keeping every one."""
    import lfsam.timing as timing

    class FakeEvent:
        def synchronize(self) -> None:
            pass

        def elapsed_time(self, end: FakeEvent) -> float:
            return 1.0

    monkeypatch.setattr(timing, "_cuda_event", FakeEvent)
    monkeypatch.setattr(timing, "MAX_PENDING", 10)
    timer = timing.StageTimer(torch.device("cpu"), events=True)
    for _ in range(100):
        with timer("step"):
            pass
        assert len(timer._pending) < 10
    assert timer.seconds["step"] == pytest.approx(100 * 0.001)
