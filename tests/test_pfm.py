"""PFM reading and writing: header variants, byte order and bottom-to-top row order."""

from __future__ import annotations

import numpy as np
import pytest

from lfsam.errors import LfsamError
from lfsam.io.pfm import read_pfm, write_pfm


def _raw_pfm(path, image: np.ndarray, little_endian: bool = True) -> None:
    """Write a PFM by hand, independently of write_pfm: rows bottom-to-top."""
    magic = b"PF" if image.ndim == 3 else b"Pf"
    scale = b"-1.0" if little_endian else b"1.0"
    dtype = "<f4" if little_endian else ">f4"
    height, width = image.shape[:2]
    with open(path, "wb") as handle:
        handle.write(magic + b"\n" + f"{width} {height}".encode() + b"\n" + scale + b"\n")
        handle.write(np.ascontiguousarray(image[::-1], dtype=dtype).tobytes())


@pytest.mark.parametrize("little_endian", [True, False])
def test_read_flips_rows_and_honours_byte_order(tmp_path, little_endian):
    image = np.arange(5 * 7, dtype=np.float32).reshape(5, 7) - 10.5  # row 0 is the top row
    path = tmp_path / "a.pfm"
    _raw_pfm(path, image, little_endian)
    out = read_pfm(path)
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out, image)
    assert out[0, 0] == -10.5  # top-left sample comes from the last row stored in the file


def test_read_colour_pfm(tmp_path):
    image = np.random.default_rng(0).normal(size=(4, 6, 3)).astype(np.float32)
    _raw_pfm(tmp_path / "c.pfm", image)
    np.testing.assert_array_equal(read_pfm(tmp_path / "c.pfm"), image)


def test_write_is_bottom_to_top_little_endian(tmp_path):
    image = np.array([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]], dtype=np.float32)
    path = tmp_path / "w.pfm"
    write_pfm(path, image)
    data = path.read_bytes()
    assert data.startswith(b"Pf\n2 3\n-1\n")
    body = np.frombuffer(data[len(b"Pf\n2 3\n-1\n") :], dtype="<f4")
    np.testing.assert_array_equal(body, [5.0, 6.0, 3.0, 4.0, 1.0, 2.0])
    np.testing.assert_array_equal(read_pfm(path), image)


def test_roundtrip_with_nan_and_inf(tmp_path):
    image = np.array([[np.nan, np.inf], [-np.inf, 0.25]], dtype=np.float32)
    write_pfm(tmp_path / "n.pfm", image)
    np.testing.assert_array_equal(read_pfm(tmp_path / "n.pfm"), image)


def test_bad_files_raise_one_line_errors(tmp_path):
    with pytest.raises(LfsamError, match="not found"):
        read_pfm(tmp_path / "missing.pfm")
    (tmp_path / "bad.pfm").write_bytes(b"P6\n2 2\n255\n")
    with pytest.raises(LfsamError, match="not a PFM"):
        read_pfm(tmp_path / "bad.pfm")
    (tmp_path / "short.pfm").write_bytes(b"Pf\n4 4\n-1\n" + b"\0" * 12)
    with pytest.raises(LfsamError, match="truncated"):
        read_pfm(tmp_path / "short.pfm")
    with pytest.raises(LfsamError, match="PFM images must be"):
        write_pfm(tmp_path / "x.pfm", np.zeros((2, 2, 2)))
