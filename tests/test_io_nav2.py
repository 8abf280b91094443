"""Tests of Nav2 maps and PGM images (crlam.io.nav2)."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from PIL import Image

from crlam.errors import ConfigError, DataFormatError
from crlam.io import (
    DATASETS,
    Nav2Map,
    data_root,
    read_image,
    read_nav2_map,
    read_pgm,
    write_nav2_map,
    write_pgm,
)


def test_row_flip_single_occupied_cell(tmp_path: Path) -> None:
    occ = np.zeros((4, 6))
    occ[0, 0] = 1.0
    occ[3, 5] = np.nan
    yaml_path = write_nav2_map(tmp_path / "m.pgm", occ, resolution=0.05, origin=(-1.0, 2.5, 0.1))
    img = read_pgm(tmp_path / "m.pgm")
    assert img.shape == (4, 6) and img.dtype == np.uint8
    # [iy=0, ix=0] is at the minimum y: the last image row, first column.
    assert img[-1, 0] == 0 and img[0, -1] == 205
    assert np.count_nonzero(img == 254) == 22
    assert (tmp_path / "m.pgm").read_bytes().startswith(b"P5\n6 4\n255\n")
    doc = yaml.safe_load(yaml_path.read_text())
    assert doc == {
        "image": "m.pgm",
        "mode": "trinary",
        "resolution": 0.05,
        "origin": [-1.0, 2.5, 0.1],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    m = read_nav2_map(yaml_path)
    assert isinstance(m, Nav2Map)
    np.testing.assert_array_equal(m.occupancy, occ)
    assert m.resolution == 0.05 and m.image_path == tmp_path / "m.pgm"
    np.testing.assert_array_equal(m.origin, [-1.0, 2.5, 0.1])


CELL = st.one_of(st.floats(0.0, 1.0), st.just(np.nan), st.sampled_from([0.0, 1.0, 0.65, 0.196]))


@settings(max_examples=60, deadline=None)
@given(
    occ=arrays(np.float64, st.tuples(st.integers(1, 12), st.integers(1, 12)), elements=CELL),
    negate=st.sampled_from([0, 1]),
    thresholds=st.sampled_from([(0.65, 0.196), (0.65, 0.25), (0.9, 0.1), (0.55, 0.45)]),
    resolution=st.floats(1e-3, 10.0),
    ox=st.floats(-1e3, 1e3),
)
def test_round_trip(occ: np.ndarray, negate: int, thresholds: tuple[float, float], resolution: float, ox: float) -> None:
    occ_t, free_t = thresholds
    with tempfile.TemporaryDirectory() as d:
        y = write_nav2_map(
            Path(d) / "map.pgm",
            occ,
            resolution=resolution,
            origin=(ox, -ox),
            occupied_thresh=occ_t,
            free_thresh=free_t,
            negate=negate,
        )
        m = read_nav2_map(y)
    expected = np.where(occ > occ_t, 1.0, np.where(occ < free_t, 0.0, np.nan))
    np.testing.assert_array_equal(m.occupancy, expected)
    assert m.resolution == resolution and m.negate == negate
    np.testing.assert_array_equal(m.origin, [ox, -ox, 0.0])
    assert (m.occupied_thresh, m.free_thresh) == thresholds


def test_writer_validation(tmp_path: Path) -> None:
    p = tmp_path / "m.pgm"
    with pytest.raises(DataFormatError, match="occupancy"):
        write_nav2_map(p, np.full((2, 2), 1.5), resolution=0.1, origin=(0, 0))
    with pytest.raises(ConfigError):
        write_nav2_map(p, np.zeros((2, 2)), resolution=0.0, origin=(0, 0))
    with pytest.raises(ConfigError):
        write_nav2_map(p, np.zeros((2, 2)), resolution=0.1, origin=(0, 0), occupied_thresh=0.2, free_thresh=0.3)


def test_read_pgm_variants(tmp_path: Path) -> None:
    p2 = tmp_path / "a.pgm"
    p2.write_text("P2\n# a comment\n3 2 # trailing\n# another\n15\n0 1 2\n3 4 15\n")
    # Pillow scales maxval 15 to the full 8-bit range: 17 per step.
    np.testing.assert_array_equal(read_pgm(p2), np.array([[0, 1, 2], [3, 4, 15]]) * 17)
    np.testing.assert_allclose(read_image(p2), np.array([[0, 1, 2], [3, 4, 15]]) / 15)
    wide = np.array([[0, 300], [65535, 7]], dtype=np.uint16)
    write_pgm(tmp_path / "w.pgm", wide)
    back = read_pgm(tmp_path / "w.pgm")
    assert back.dtype == np.uint16
    np.testing.assert_array_equal(back, wide)
    narrow = np.arange(12, dtype=np.uint8).reshape(3, 4)
    write_pgm(tmp_path / "n.pgm", narrow)
    np.testing.assert_array_equal(read_pgm(tmp_path / "n.pgm"), narrow)
    # Pillow agrees with our reader and writer.
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "n.pgm")), narrow)


@pytest.mark.parametrize(
    ("content", "field"),
    [
        (b"P6\n1 1\n255\n\x00\x00\x00", "magic"),
        (b"P5\n2 2\n255\n\x00\x00", "raster"),
        (b"P5\nx 2\n255\n\x00\x00", "header"),
        (b"P5\n2 2\n0\n\x00\x00\x00\x00", "header"),
        (b"P2\n2 1\n10\n3 11\n", "raster"),
    ],
)
def test_read_pgm_errors(tmp_path: Path, content: bytes, field: str) -> None:
    p = tmp_path / "bad.pgm"
    p.write_bytes(content)
    with pytest.raises(DataFormatError) as info:
        read_pgm(p)
    assert info.value.field == field and str(p) in str(info.value)


def test_png_with_alpha_follows_nav2(tmp_path: Path) -> None:
    # Row 0 of the image (max y): opaque white, opaque black, transparent white.
    rgba = np.array([[[255, 255, 255, 255], [0, 0, 0, 255], [255, 255, 255, 0]]], np.uint8)
    Image.fromarray(rgba, "RGBA").save(tmp_path / "m.png")
    (tmp_path / "m.yaml").write_text(
        "image: m.png\nresolution: 0.5\norigin: [0, 0, 0]\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    m = read_nav2_map(tmp_path / "m.yaml")
    # Trinary averages alpha in: transparent white is shade 0.75 -> occ 0.25 -> unknown.
    np.testing.assert_array_equal(m.occupancy, [[0.0, 1.0, np.nan]])
    (tmp_path / "m.yaml").write_text(
        "image: m.png\nmode: scale\nresolution: 0.5\norigin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    m = read_nav2_map(tmp_path / "m.yaml")
    np.testing.assert_array_equal(m.occupancy, [[0.0, 1.0, np.nan]])
    assert m.mode == "scale"


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ("image: m.pgm\norigin: [0, 0, 0]\n", "resolution"),
        ("image: m.pgm\nresolution: abc\norigin: [0, 0, 0]\n", "resolution"),
        ("image: m.pgm\nresolution: 0.1\norigin: 5\n", "origin"),
        ("image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nmode: fancy\n", "mode"),
        ("image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 2\n", "negate"),
        ("image: gone.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n", "image"),
        ("resolution: 0.1\norigin: [0, 0, 0]\n", "image"),
    ],
)
def test_yaml_errors(tmp_path: Path, text: str, field: str) -> None:
    write_pgm(tmp_path / "m.pgm", np.zeros((2, 2), np.uint8))
    (tmp_path / "m.yaml").write_text(text)
    with pytest.raises(DataFormatError) as info:
        read_nav2_map(tmp_path / "m.yaml")
    assert info.value.field == field and str(tmp_path / "m.yaml") in str(info.value)


def test_invalid_yaml_reports_line(tmp_path: Path) -> None:
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: [0.1\n")
    with pytest.raises(DataFormatError) as info:
        read_nav2_map(tmp_path / "m.yaml")
    assert info.value.line is not None


@pytest.mark.realdata
def test_cave_map(tmp_path: Path) -> None:
    root = data_root()
    if root is None or not (root / DATASETS["cave-map"].relative_path).exists():
        pytest.skip("real datasets not found: set CRLAM_DATA to the data folder")
    pgm = root / DATASETS["cave-map"].relative_path
    img = read_pgm(pgm)
    assert img.shape == (100, 100) and img.dtype == np.uint8
    free = img >= 128
    assert 0 < free.sum() < free.size
    (tmp_path / "cave.yaml").write_text(
        f"image: {pgm}\nresolution: 0.2\norigin: [0, 0, 0]\noccupied_thresh: 0.5\nfree_thresh: 0.5\n"
    )
    m = read_nav2_map(tmp_path / "cave.yaml")
    assert m.occupancy.shape == (100, 100)
    np.testing.assert_array_equal(m.occupancy[::-1] == 0.0, img > 127.5)
