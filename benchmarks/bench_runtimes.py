"""SAM 2's image encoder on CPU: eager PyTorch against ONNX Runtime and OpenVINO (issue 18).

The encoder is measured exactly as :meth:`lfsam.segmenters.sam2.backend.Sam2Segmenter.encode`
runs it (``_encode_batch``): SAM 2's transforms (resize to the model's square input, ImageNet
normalisation) outside, then ``forward_image`` (trunk, neck and the decoder's two 1x1 high-res
convolutions), ``_prepare_backbone_features`` and ``no_mem_embed`` inside the exported graph.
The graph's three outputs are everything the mask decoder and semantic occluding use
(docs/design.md section 3, "efficiency facts"): ``image_embed`` (1, 256, 64, 64) and the two
high-resolution levels (1, 32, 256, 256) and (1, 64, 128, 128).

One run: export to ONNX once, build an ONNX Runtime session and an OpenVINO CPU model from the
same file, then time the runtimes interleaved (torch, onnx, openvino, torch, ...) on the same
input view for ``--repeats`` rounds after one warm-up call each, so load from other processes
on a shared machine falls on all of them alike; the table gives the median seconds per view,
the speed-up over eager PyTorch and the largest absolute difference of each output from
PyTorch's. Random weights (speed does not depend on them; the differences are of the same
order for trained weights, whose activations have a similar scale).

Run: ``python benchmarks/bench_runtimes.py [--model sam2.1-hiera-small] [--repeats 5]``
(needs ``pip install onnx onnxruntime openvino``; a missing runtime is reported and skipped).
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from lfsam.segmenters import load_segmenter
from lfsam.synth import generate_scene

OUTPUTS = ("image_embed", "high_res_0", "high_res_1")


class EncoderGraph(torch.nn.Module):
    """``Sam2Segmenter._encode_batch`` after the transforms, as one module to export."""

    def __init__(self, model: torch.nn.Module) -> None:
        super().__init__()
        self.model = model

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        model = self.model
        backbone_out = model.forward_image(x)
        _, vision_feats, _, feat_sizes = model._prepare_backbone_features(backbone_out)
        if model.directly_add_no_mem_embed:
            vision_feats[-1] = vision_feats[-1] + model.no_mem_embed
        batch = x.shape[0]
        levels = [
            feat.permute(1, 2, 0).reshape(batch, -1, *size)
            for feat, size in zip(vision_feats, feat_sizes, strict=True)
        ]
        return levels[-1], levels[0], levels[1]


def model_input(segmenter, view: np.ndarray) -> torch.Tensor:
    """The encoder input of one view, as ``_encode_batch`` makes it (resize + normalise)."""
    x = torch.from_numpy(np.ascontiguousarray(view[None])).permute(0, 3, 1, 2).float() / 255.0
    return segmenter._predictor._transforms.transforms(x).contiguous()


def export_onnx(graph: EncoderGraph, x: torch.Tensor, path: Path) -> float:
    """Export with the TorchScript-based exporter; returns seconds taken."""
    start = time.perf_counter()
    with torch.no_grad():
        torch.onnx.export(
            graph, (x,), str(path), input_names=["image"], output_names=list(OUTPUTS),
            opset_version=17, dynamo=False,
        )
    return time.perf_counter() - start


def make_runners(graph: EncoderGraph, x: torch.Tensor, onnx_path: Path | None, wanted: list[str]):
    """name -> callable returning the three outputs as float32 NumPy arrays."""
    runners = {}
    if "torch" in wanted:

        def run_torch():
            with torch.inference_mode():
                return [t.float().numpy() for t in graph(x)]

        runners["torch"] = run_torch
    feed = x.numpy()
    if "onnx" in wanted and onnx_path is not None:
        try:
            import onnxruntime as ort
        except ImportError:
            print("onnxruntime is not installed: skipped (pip install onnxruntime)")
        else:
            options = ort.SessionOptions()
            options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
            session = ort.InferenceSession(
                str(onnx_path), options, providers=["CPUExecutionProvider"]
            )
            runners["onnx"] = lambda: session.run(list(OUTPUTS), {"image": feed})
    if "openvino" in wanted and onnx_path is not None:
        try:
            import openvino as ov
        except ImportError:
            print("openvino is not installed: skipped (pip install openvino)")
        else:
            core = ov.Core()
            compiled = core.compile_model(
                core.read_model(str(onnx_path)), "CPU",
                {"INFERENCE_PRECISION_HINT": "f32", "PERFORMANCE_HINT": "LATENCY"},
            )
            request = compiled.create_infer_request()

            def run_openvino():
                result = request.infer({"image": feed})
                return [np.asarray(result[compiled.output(name)]) for name in OUTPUTS]

            runners["openvino"] = run_openvino
    return runners


def main() -> None:
    """Export, run interleaved, print the table."""
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    parser.add_argument("--model", default="sam2.1-hiera-small")
    parser.add_argument("--size", default="480x640", help="view size, rows x columns")
    parser.add_argument("--repeats", type=int, default=5, help="interleaved rounds")
    parser.add_argument("--runtimes", default="torch,onnx,openvino")
    parser.add_argument("--keep", metavar="DIR", help="keep the .onnx file in DIR")
    args = parser.parse_args()
    wanted = [r.strip() for r in args.runtimes.split(",") if r.strip()]
    size = tuple(int(v) for v in args.size.lower().split("x"))

    torch.manual_seed(0)
    segmenter = load_segmenter(args.model, random_weights=True, device="cpu")
    view = generate_scene(grid=(1, 1), size=size, seed=0, num_objects=4).views[0, 0]
    x = model_input(segmenter, view)
    graph = EncoderGraph(segmenter.model).eval()
    print(f"bench_runtimes: {args.model} (random weights), input {tuple(x.shape)}, "
          f"torch {torch.__version__} with {torch.get_num_threads()} threads, "
          f"{os.cpu_count()} CPUs, load {os.getloadavg()[0]:.2f}", flush=True)

    # The exported graph is the segmenter's encoder: same outputs as Sam2Segmenter.encode.
    reference = segmenter.encode(view)[0].data
    with torch.inference_mode():
        mine = graph(x)
    same = max(
        float((a - b).abs().max())
        for a, b in zip(mine, [reference.image_embed, *reference.high_res_feats], strict=True)
    )
    print(f"graph vs Sam2Segmenter.encode: max |diff| {same:.2e}", flush=True)

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(args.keep or tmp)
        folder.mkdir(parents=True, exist_ok=True)
        onnx_path = None
        if {"onnx", "openvino"} & set(wanted):
            onnx_path = folder / f"{args.model}-encoder.onnx"
            seconds = export_onnx(graph, x, onnx_path)
            print(f"exported {onnx_path.name} in {seconds:.1f} s "
                  f"({onnx_path.stat().st_size / 1e6:.0f} MB)", flush=True)
        runners = make_runners(graph, x, onnx_path, wanted)
        outputs = {name: run() for name, run in runners.items()}  # warm-up, and the outputs
        times: dict[str, list[float]] = {name: [] for name in runners}
        for round_ in range(args.repeats):
            for name, run in runners.items():
                start = time.perf_counter()
                run()
                times[name].append(time.perf_counter() - start)
            print(f"round {round_ + 1}: "
                  + ", ".join(f"{n} {t[-1]:.2f} s" for n, t in times.items()), flush=True)

    base = statistics.median(times["torch"]) if "torch" in times else None
    print("\n| runtime | s per view (median) | min | max | speed-up vs torch | "
          + " | ".join(f"max abs diff {o}" for o in OUTPUTS) + " |")
    print("|---|---|---|---|---|" + "---|" * len(OUTPUTS))
    for name, values in times.items():
        med = statistics.median(values)
        diffs = (
            [float(np.abs(a - b).max()) for a, b in zip(outputs[name], outputs["torch"],
                                                         strict=True)]
            if "torch" in outputs else [float("nan")] * len(OUTPUTS)
        )
        speed = f"{base / med:.2f}x" if base else "-"
        print(f"| {name} | {med:.3f} | {min(values):.3f} | {max(values):.3f} | {speed} | "
              + " | ".join(f"{d:.1e}" for d in diffs) + " |")
    print(f"(medians of {args.repeats} interleaved rounds; load average now "
          f"{os.getloadavg()[0]:.2f})")


if __name__ == "__main__":
    main()
