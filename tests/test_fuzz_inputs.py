"""Fuzzing every reader and every command-line number option (issue 17).

The rule: bad input gives a one-line :class:`~lfsam.errors.LfsamError` (exit status 2 on the
command line, no traceback) or a correct result; never another exception, and never an output
file after a failure. Examples are few and files tiny so the suite stays fast; ``derandomize``
makes every run test the same examples. For a deeper, random search set
``LFSAM_FUZZ_EXAMPLES`` (e.g. ``LFSAM_FUZZ_EXAMPLES=300 pytest tests/test_fuzz_inputs.py``).
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from PIL import Image

from lfsam.cli.main import main
from lfsam.errors import LfsamError
from lfsam.io import read_lightfield, write_lightfield
from lfsam.io.pfm import read_pfm, write_pfm
from lfsam.lightfield import LightField
from lfsam.result import SegmentationResult, load_result, save_result
from lfsam.synth import generate_scene

DEEP = int(os.environ.get("LFSAM_FUZZ_EXAMPLES", "0"))
FAST = settings(
    max_examples=DEEP or 25,
    deadline=None,
    derandomize=not DEEP,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
FEW = settings(FAST, max_examples=DEEP // 4 or 6)


def _clear(exc: LfsamError) -> None:
    message = str(exc)
    assert message and "\n" not in message


def _read_or_clear(path: Path, **kwargs) -> LightField | None:
    """Read a light field; a LfsamError must be one line. Anything else fails the test."""
    try:
        lf = read_lightfield(path, **kwargs)
    except LfsamError as exc:
        _clear(exc)
        return None
    assert lf.views.dtype == np.uint8 and lf.views.ndim == 5 and lf.views.shape[-1] == 3
    assert lf.present.shape == lf.grid_shape and lf.present[lf.center]
    return lf


@pytest.fixture(scope="module")
def originals(tmp_path_factory) -> dict[str, Path]:
    """One small valid file (or folder) per reader."""
    root = tmp_path_factory.mktemp("originals")
    scene = generate_scene(grid=(3, 3), size=(8, 10), seed=0, num_objects=1, supersample=1)
    files = {"npz": write_lightfield(scene, root / "lf.npz")}
    np.save(root / "lf.npy", scene.views)
    files["npy"] = root / "lf.npy"
    with h5py.File(root / "lf.h5", "w") as handle:
        handle["LF"] = scene.views
    files["h5"] = root / "lf.h5"
    scipy.io.savemat(root / "lf.mat", {"LF": scene.views})
    files["mat"] = root / "lf.mat"
    write_pfm(root / "d.pfm", scene.disparity[1, 1])
    files["pfm"] = root / "d.pfm"
    files["scene"] = write_lightfield(scene, root / "scene")
    labels = scene.labels.copy()
    files["result"] = save_result(
        SegmentationResult(labels=labels, present=np.ones((3, 3), bool)), root / "r.npz"
    )
    return files


_MUTATION = st.one_of(
    st.tuples(st.just("truncate"), st.floats(0, 1)),
    st.tuples(st.just("flip"), st.lists(st.tuples(st.floats(0, 1), st.integers(0, 255)),
                                         min_size=1, max_size=8)),
    st.tuples(st.just("random"), st.binary(max_size=300)),
)


def _mutate(data: bytes, mutation) -> bytes:
    kind, arg = mutation
    if kind == "truncate":
        return data[: int(arg * len(data))]
    if kind == "random":
        return arg
    out = bytearray(data)
    for where, value in arg:
        out[min(int(where * len(out)), len(out) - 1)] = value
    return bytes(out)


@pytest.mark.parametrize("name", ["npz", "npy", "h5", "mat"])
@FAST
@given(mutation=_MUTATION)
def test_damaged_array_files(originals, name, mutation):
    source = originals[name]
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / source.name
        path.write_bytes(_mutate(source.read_bytes(), mutation))
        _read_or_clear(path)


@FAST
@given(mutation=_MUTATION)
def test_damaged_pfm(originals, mutation):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "d.pfm"
        path.write_bytes(_mutate(originals["pfm"].read_bytes(), mutation))
        try:
            image = read_pfm(path)
        except LfsamError as exc:
            _clear(exc)
        else:
            assert image.dtype == np.float32 and image.ndim in (2, 3)


@FAST
@given(mutation=_MUTATION)
def test_damaged_result(originals, mutation):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "r.npz"
        path.write_bytes(_mutate(originals["result"].read_bytes(), mutation))
        try:
            result = load_result(path)
        except LfsamError as exc:
            _clear(exc)
        else:
            assert result.labels.ndim == 4 and result.present_mask.shape == result.grid_shape


@pytest.mark.parametrize("member", ["view_01_01.png", "view_00_02.png", "lfsam_scene.json"])
@FEW
@given(mutation=_MUTATION)
def test_damaged_scene_folder(originals, member, mutation):
    with tempfile.TemporaryDirectory() as folder:
        scene = Path(folder) / "scene"
        scene.mkdir()
        for path in originals["scene"].iterdir():
            (scene / path.name).write_bytes(path.read_bytes())
        target = scene / member
        target.write_bytes(_mutate(target.read_bytes(), mutation))
        _read_or_clear(scene)


@FEW
@given(
    names=st.lists(st.integers(0, 80), min_size=1, max_size=12, unique=True),
    cfg=st.one_of(st.none(), st.binary(max_size=80), st.tuples(st.integers(-3, 12),
                                                             st.integers(-3, 12))),
)
def test_hci_folders_with_any_subset_and_config(names, cfg):
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        for index in names:
            Image.fromarray(np.full((4, 5, 3), index, np.uint8)).save(
                root / f"input_Cam{index:03d}.png"
            )
        if isinstance(cfg, bytes):
            (root / "parameters.cfg").write_bytes(cfg)
        elif cfg is not None:
            (root / "parameters.cfg").write_text(
                f"[extrinsics]\nnum_cams_x = {cfg[1]}\nnum_cams_y = {cfg[0]}\n"
            )
        lf = _read_or_clear(root)
        if lf is not None:
            present = [int(lf.views[s, t, 0, 0, 0]) for s, t in lf.view_indices(True)]
            assert sorted(present) == sorted(names)  # every file is placed, none invented


@FEW
@given(
    positions=st.lists(st.tuples(st.integers(0, 4), st.integers(0, 4)), min_size=1, max_size=12,
                       unique=True),
    style=st.sampled_from(["{r}_{c}", "lf_{r:02d}_{c:02d}", "{r:02d}{c:02d}", "{r}-{c}"]),
)
def test_grid_folders_with_any_views(positions, style):
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        for r, c in positions:
            Image.fromarray(np.full((4, 5, 3), 10 * r + c + 1, np.uint8)).save(
                root / f"{style.format(r=r, c=c)}.png"
            )
        lf = _read_or_clear(root)
        if lf is not None:
            found = sorted(int(lf.views[s, t, 0, 0, 0]) for s, t in lf.view_indices(True))
            assert found == sorted({10 * r + c + 1 for r, c in positions}) or lf.meta.get(
                "naming", ""
            ).endswith("number")  # RRCC names may read as a linear numbering


@FEW
@given(mutation=_MUTATION, which=st.sampled_from(["2_2_disparity.npy", "1_1_label.npy"]))
def test_damaged_urbanlf_ground_truth(originals, mutation, which):
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        views = read_lightfield(originals["npz"]).views
        for s in range(3):
            for t in range(3):
                Image.fromarray(views[s, t]).save(root / f"{s + 1}_{t + 1}.png")
                np.save(root / f"{s + 1}_{t + 1}_disparity.npy", np.zeros((8, 10), np.float32))
                np.save(root / f"{s + 1}_{t + 1}_label.npy", np.zeros((8, 10), np.int64))
        target = root / which
        target.write_bytes(_mutate(target.read_bytes(), mutation))
        _read_or_clear(root)


_DTYPES = st.sampled_from(
    ["uint8", "int8", "uint16", "int32", "int64", "float16", "float32", "float64", "bool",
     "complex64", "<U2"]
)


def _arrays(max_dims: int = 6):
    shapes = st.one_of(
        hnp.array_shapes(min_dims=0, max_dims=max_dims, min_side=0, max_side=3),
        st.tuples(st.integers(1, 3), st.integers(1, 3), st.integers(1, 4), st.integers(1, 4),
                  st.sampled_from([1, 3, 4])),
    )
    return _DTYPES.flatmap(lambda dtype: hnp.arrays(dtype, shapes))


@FAST
@given(views=_arrays(), extra=st.one_of(st.none(), _arrays(4)), key=st.sampled_from(
    ["views", "LF", "other", "disparity", "labels", "present"]))
def test_npz_npy_with_any_dtype_and_shape(views, extra, key):
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        arrays = {"views": views}
        if extra is not None:
            arrays[key] = extra
        np.savez(root / "lf.npz", **arrays)
        lf = _read_or_clear(root / "lf.npz")
        np.save(root / "lf.npy", views)
        _read_or_clear(root / "lf.npy")
        stored = arrays["views"]
        if lf is not None and stored.dtype == np.uint8 and stored.ndim == 5:
            np.testing.assert_array_equal(lf.views, stored)


@FEW
@given(views=_arrays())
def test_h5_and_mat_with_any_dtype_and_shape(views):
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        if views.dtype.kind != "U":
            with h5py.File(root / "lf.h5", "w") as handle:
                handle["LF"] = views
            _read_or_clear(root / "lf.h5")
        if views.dtype.kind != "c" and views.dtype != np.float16:
            scipy.io.savemat(root / "lf.mat", {"LF": views})
            _read_or_clear(root / "lf.mat")


@FAST
@given(
    labels=_arrays(),
    masks_shape=st.one_of(st.none(), hnp.arrays("int64", st.integers(0, 6),
                                                 elements=st.integers(-2, 4))),
    present=st.one_of(st.none(), _arrays(3)),
    meta=st.sampled_from(["{}", "[1]", "not json", '{"input": 3}']),
)
def test_results_with_any_contents(labels, masks_shape, present, meta):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "r.npz"
        arrays = {"labels": labels, "meta": np.array(meta)}
        if masks_shape is not None:
            arrays["masks_shape"] = masks_shape
            arrays["masks_packed"] = np.zeros((1, 1, 1, 1), np.uint8)
        if present is not None:
            arrays["present"] = present
        np.savez(path, **arrays)
        try:
            result = load_result(path)
        except LfsamError as exc:
            _clear(exc)
            return
        np.testing.assert_array_equal(result.labels, labels)
        out = Path(folder) / "out"
        code = main(["export", str(path), "--to", "npy", "--out", str(out)])
        assert code in (0, 2) and (code == 0) == out.is_dir()


# --- command-line number options ------------------------------------------------------------

_GARBAGE = st.one_of(
    st.sampled_from(["nan", "inf", "-inf", "1e400", "-0", "", " ", "abc", "0x0", "1,2", "1,,2",
                     "1,2,3,4", "0", "1", "-1", "2147483648", "1e-300"]),
    st.text(alphabet="0123456789x,.-e", max_size=8),
)


def _number(low: int, high: int):
    return st.one_of(
        _GARBAGE,
        st.integers(low, high).map(str),
        st.floats(low, high, allow_nan=False).map(repr),
    )


def _pair(low: int, high: int, sep: str):
    return st.one_of(
        _GARBAGE,
        st.tuples(st.integers(low, high), st.integers(low, high)).map(
            lambda p: f"{p[0]}{sep}{p[1]}"
        ),
    )


def _run(argv: list[str], out: Path, capsys) -> None:
    """Run the CLI: success, or exit status 2 with a one-line message and no output file."""
    capsys.readouterr()
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse rejected a value: usage + one error line
        code = exc.code
    err = capsys.readouterr().err
    assert code in (0, 2), err
    if code == 2:
        assert "Traceback" not in err
        assert err.strip().splitlines()[-1].startswith(("lfsam: error:", "usage:", "lfsam "))
        assert not out.exists(), f"{out} written although the command failed"


@pytest.fixture(scope="module")
def cli_inputs(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("cli")
    scene = generate_scene(grid=(3, 3), size=(16, 20), seed=1, num_objects=1, supersample=1)
    write_lightfield(scene, root / "scene")
    save_result(SegmentationResult(labels=scene.labels.copy()), root / "r.npz")
    return {"scene": root / "scene", "result": root / "r.npz"}


_SYNTH = {
    "--grid": _pair(-2, 5, "x"),
    "--size": _pair(-2, 24, "x"),
    "--seed": _number(-5, 10**9),
    "--objects": _number(-3, 8),
    "--disparity-range": _pair(-5, 5, ","),
    "--supersample": _number(-2, 3),
}


@pytest.mark.parametrize("option", sorted(_SYNTH))
@FEW
@given(data=st.data())
def test_synth_number_options(option, data, tmp_path, capsys):
    value = data.draw(_SYNTH[option])
    out = tmp_path / "s.npz"
    _run(["synth", str(out), "--grid", "2x2", "--size", "8x8", "--supersample", "1",
          f"{option}={value}"], out, capsys)
    out.unlink(missing_ok=True)


_SHOW = {
    "--row": _number(-3, 30),
    "--col": _number(-3, 30),
    "--upsample": _number(-2, 100),
    "--alpha": _number(-1, 2),
    "--scale": _number(-1, 40),
    "--fps": _number(-1, 2000),
}


@pytest.mark.parametrize("option", sorted(_SHOW))
@FEW
@given(data=st.data())
def test_show_number_options(option, data, cli_inputs, tmp_path, capsys):
    value = data.draw(_SHOW[option])
    out = tmp_path / ("f.gif" if option == "--fps" else "f.png")
    kind = "anim" if option == "--fps" else ("epi" if option in ("--row", "--col") else "grid")
    _run(["show", str(cli_inputs["result"]), "--lightfield", str(cli_inputs["scene"]),
          "--kind", kind, "--out", str(out), f"{option}={value}"], out, capsys)
    out.unlink(missing_ok=True)


_SEGMENT = {
    "--t-sim": _number(-2, 2),
    "--t-iou": _number(-2, 2),
    "--point": st.one_of(_GARBAGE, _pair(-30, 30, ",")),
    "--box": st.one_of(
        _GARBAGE,
        st.lists(st.integers(-5, 30), min_size=4, max_size=4).map(lambda v: ",".join(map(str, v))),
    ),
    "--objects-per-pass": _number(-2, 3),
}


@pytest.mark.parametrize("option", sorted(_SEGMENT))
@settings(FEW, max_examples=DEEP // 8 or 4)
@given(data=st.data())
def test_segment_number_options(option, data, cli_inputs, tmp_path, capsys):
    value = data.draw(_SEGMENT[option])
    out = tmp_path / "o.npz"
    prompt = [] if option in ("--point", "--box") else ["--auto"]
    method = ["--method", "video-baseline"] if option == "--objects-per-pass" else []
    _run(["segment", str(cli_inputs["scene"]), "--model", "oracle", "--disparity", "gt",
          "--quiet", *prompt, *method, f"{option}={value}", "--out", str(out)], out, capsys)
    out.unlink(missing_ok=True)


@settings(FEW, max_examples=DEEP // 8 or 4)
@given(value=_pair(-6, 6, ","))
def test_disparity_range_option(value, cli_inputs, tmp_path, capsys):
    out = tmp_path / "d.npy"
    _run(["disparity", str(cli_inputs["scene"]), f"--range={value}", "--out", str(out)],
         out, capsys)
    out.unlink(missing_ok=True)


def test_value_range_option_rejects_other_numbers(cli_inputs, capsys):
    with pytest.raises(SystemExit) as info:
        main(["info", str(cli_inputs["scene"]), "--value-range", "100"])
    assert info.value.code == 2 and "invalid choice" in capsys.readouterr().err


def test_scene_description_with_a_bad_grid(cli_inputs, tmp_path):
    scene = tmp_path / "scene"
    scene.mkdir()
    for path in cli_inputs["scene"].iterdir():
        (scene / path.name).write_bytes(path.read_bytes())
    marker = scene / "lfsam_scene.json"
    description = json.loads(marker.read_text())
    for grid in ([0, 3], [-1, 3], [3], "3x3", [3, 3, 3], [1e9, 1]):
        marker.write_text(json.dumps({**description, "grid": grid}))
        assert _read_or_clear(scene) is None
