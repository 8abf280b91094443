"""The map files of a run folder written band by band (crlam.experiments.map_outputs): the same
content as from whole-map arrays, and a memory bound that does not grow with the map's
bounding box (measured with tracemalloc, which is deterministic)."""

from __future__ import annotations

import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from crlam.errors import DataFormatError
from crlam.experiments.known_poses import unknown_mask
from crlam.experiments.map_outputs import FIGURE_CELLS, map_products, write_belief_archive
from crlam.io.belief import BAND_BYTES, load_belief, save_belief, save_belief_bands
from crlam.io.nav2 import nav2_pixels, read_nav2_map, write_nav2_image, write_nav2_map
from crlam.mapping import ConfidenceRichMap, LogOddsOccupancyMap, MappingConfig


def _room_scan(n: int = 180, r: float = 3.0) -> tuple[np.ndarray, np.ndarray]:
    angles = np.linspace(-np.pi, np.pi, n, endpoint=False)
    ranges = np.full(n, r)
    ranges[::7] = np.inf  # some no-returns
    return angles, ranges


def _sparse_map(corners: float, resolution: float = 0.1) -> ConfidenceRichMap:
    """A CRM whose written cells are four rooms at the corners of a ``corners`` m square: a large
    bounding box, most of it never seen (as a campus map's)."""
    crm = ConfidenceRichMap(MappingConfig(resolution=resolution, max_range=8.0))
    angles, ranges = _room_scan()
    for x, y in ((0.0, 0.0), (corners, 0.0), (0.0, corners), (corners, corners), (0.5 * corners, 0.3 * corners)):
        crm.update(np.array([x, y, 0.3]), angles, ranges)
    return crm


def test_streamed_archive_is_the_in_memory_archive(tmp_path: Path) -> None:
    crm = _sparse_map(30.0)
    write_belief_archive(tmp_path / "streamed.npz", crm, estimate=np.array([1.0, 2.0, 0.5]), estimate_cov=np.eye(3) * 0.01)
    save_belief(tmp_path / "whole.npz", crm.to_archive())
    a, b = load_belief(tmp_path / "streamed.npz"), load_belief(tmp_path / "whole.npz")
    assert a.beliefs.shape[0] > 200 and a.beliefs.tobytes() == b.beliefs.tobytes()
    assert a.levels.tobytes() == b.levels.tobytes() and a.origin.tobytes() == b.origin.tobytes()
    assert a.metadata == b.metadata and a.resolution == b.resolution
    assert a.estimate is not None and a.estimate.tolist() == [1.0, 2.0, 0.5]
    assert ConfidenceRichMap.from_archive(a).native.beliefs(crm.region()).tobytes() == crm.native.beliefs(crm.region()).tobytes()


def test_band_writer_refuses_bad_bands_and_leaves_no_file(tmp_path: Path) -> None:
    k, nx = 4, 3
    good = np.full((2, nx, k), 0.25, dtype=np.float32)
    bad = good.copy()
    bad[1, 2] = [0.5, 0.5, 0.5, 0.5]
    head: dict[str, Any] = {"levels": np.linspace(0, 1, k), "origin": np.zeros(2), "resolution": 0.1, "metadata": {}}
    with pytest.raises(DataFormatError, match=r"beliefs\[3,2\]"):
        save_belief_bands(tmp_path / "a.npz", shape=(4, nx), bands=[good, bad], **head)
    assert not (tmp_path / "a.npz").exists()
    with pytest.raises(DataFormatError, match="the bands hold 2 rows, the grid 4"):
        save_belief_bands(tmp_path / "b.npz", shape=(4, nx), bands=[good], **head)
    assert not (tmp_path / "b.npz").exists()
    with pytest.raises(DataFormatError, match="does not fit"):
        save_belief_bands(tmp_path / "c.npz", shape=(3, nx), bands=[good, good], **head)
    assert not (tmp_path / "c.npz").exists()
    save_belief_bands(tmp_path / "d.npz", shape=(4, nx), bands=[good[:1], good, good[:1]], **head)
    assert load_belief(tmp_path / "d.npz").beliefs.shape == (4, nx, k)


def test_products_are_the_whole_map_products(tmp_path: Path) -> None:
    """map.pgm's pixels and the cell counts band by band equal those of the whole-map layers."""
    crm = _sparse_map(40.0)
    products = map_products(crm, grids=True)
    mean, var, ent = crm.layers()
    unknown = unknown_mask(crm, ent)
    occ = np.where(unknown, np.nan, mean.values)
    assert products.shape == mean.shape and products.origin == mean.origin
    assert np.array_equal(products.nav2, nav2_pixels(occ))
    write_nav2_image(tmp_path / "banded.pgm", products.nav2, resolution=products.resolution, origin=products.origin)
    write_nav2_map(tmp_path / "whole.pgm", occ, resolution=mean.resolution, origin=mean.origin)
    assert (tmp_path / "banded.pgm").read_bytes() == (tmp_path / "whole.pgm").read_bytes()
    assert (tmp_path / "banded.yaml").read_text() == (tmp_path / "whole.yaml").read_text().replace("whole", "banded")
    classes = read_nav2_map(tmp_path / "banded.yaml").occupancy
    assert int((classes == 1.0).sum()) == products.n_occupied and int((classes == 0.0).sum()) == products.n_free
    assert products.n_known == int((~unknown).sum())
    assert products.n_occupied == int((~unknown & (mean.values > 0.65)).sum()) > 0
    assert products.n_free == int((~unknown & (mean.values < 0.196)).sum()) > 0
    from crlam.experiments.slam_mcap import occupancy_grid_values

    assert products.grid is not None and products.confidence_grid is not None
    assert np.array_equal(products.grid, occupancy_grid_values(mean.values, unknown))
    std = np.sqrt(np.maximum(var.values, 0.0))
    assert np.array_equal(products.confidence_grid, occupancy_grid_values(std, unknown, scale=200.0))
    # A map within FIGURE_CELLS is drawn cell for cell.
    assert products.figure_stride == 1
    assert np.array_equal(products.figure_unknown, unknown)
    assert np.allclose(products.figure_mean.values[~unknown], mean.values[~unknown], atol=1e-6)


def test_log_odds_products_match_its_layers() -> None:
    ogm = LogOddsOccupancyMap()
    angles, ranges = _room_scan()
    for x in (0.0, 9.0):
        ogm.update(np.array([x, 1.0, 0.0]), angles, ranges)
    products = map_products(ogm)
    p = ogm.probability()
    unknown = ogm.native.log_odds(ogm.region()) == 0.0
    assert np.array_equal(products.nav2, nav2_pixels(np.where(unknown, np.nan, p.values)))
    assert products.figure_variance is None and products.confidence_grid is None


def test_a_large_maps_figure_keeps_thin_walls() -> None:
    """Beyond FIGURE_CELLS cells a side the figure draws blocks of s x s cells with their largest
    known value: a wall one cell thick stays as dark as it is."""
    res = 0.1
    side = (FIGURE_CELLS + 300) * res
    crm = ConfidenceRichMap(MappingConfig(resolution=res, max_range=8.0, extent=(0.0, 0.0, side, 20.0)))
    angles, ranges = _room_scan()
    crm.update(np.array([10.0, 10.0, 0.0]), angles, ranges)
    products = map_products(crm)
    s = products.figure_stride
    ny, nx = products.shape
    assert s == 2 and max(products.figure_mean.shape) <= FIGURE_CELLS
    assert products.figure_mean.shape == (-(-ny // s), -(-nx // s)) and products.figure_mean.resolution == pytest.approx(2 * res)
    mean = crm.expected_occupancy().values
    assert products.figure_mean.values.max() == pytest.approx(mean.max(), abs=1e-6)
    # Unknown blocks are those with no observed cell.
    unknown = unknown_mask(crm, crm.entropy())
    pad = np.ones((-(-ny // s) * s, -(-nx // s) * s), dtype=bool)
    pad[:ny, :nx] = unknown
    assert np.array_equal(products.figure_unknown, pad.reshape(pad.shape[0] // s, s, pad.shape[1] // s, s).all(axis=(1, 3)))


class _BandRecorder:
    """Forwards to a native map and records the bytes of every array it hands out (allocated in
    Rust, so not seen by tracemalloc)."""

    def __init__(self, native: Any) -> None:
        self._native = native
        self.largest = 0

    def __getattr__(self, name: str) -> Any:
        attr = getattr(self._native, name)
        if name not in ("beliefs", "derived_maps"):
            return attr

        def call(*args: Any) -> Any:
            out = attr(*args)
            self.largest = max(self.largest, sum(a.nbytes for a in (out if isinstance(out, tuple) else (out,))))
            return out

        return call


def test_writing_a_large_maps_files_takes_memory_of_one_band_and_a_byte_per_cell(tmp_path: Path) -> None:
    """The bound of issue 46: writing the map's files must not take several times the filter's memory.

    A map whose bounding box is about 2,200 x 2,200 cells (K = 10: 190 MB of pmfs as float32,
    38 MB per float64 layer) though only five rooms in it were seen. The belief archive, map.pgm
    and the figure's layers are written, and tracemalloc's peak (Python's and numpy's allocations;
    deterministic) stays below two bytes per cell, four bands of BAND_BYTES and the figure's two
    float64 layers and mask (17 bytes per figure cell, at most FIGURE_CELLS a side); the native
    arrays handed out (allocated in Rust, not traced) are each at most a band. Written from
    whole-map arrays, as before, the same files traced 113 MB (the pmfs' validation alone K = 10
    bytes per cell), and the native map handed out the whole 190 MB at once."""
    crm = _sparse_map(200.0)
    ny, nx = crm.region()[3], crm.region()[2]
    k = crm.levels.shape[0]
    assert ny * nx >= 4_000_000 and k == 10
    recorder = _BandRecorder(crm.native)
    crm.native = recorder  # type: ignore[assignment]
    tracemalloc.start()
    try:
        write_belief_archive(tmp_path / "belief.npz", crm)
        products = map_products(crm, grids=False)
        write_nav2_image(tmp_path / "map.pgm", products.nav2, resolution=products.resolution, origin=products.origin)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    fy, fx = products.figure_mean.shape
    bound = 2 * ny * nx + 4 * BAND_BYTES + 17 * fy * fx
    assert bound < ny * nx * k  # the bound is tighter than the old way's first temporary
    assert peak < bound, f"traced peak {peak / 2**20:.1f} MB, bound {bound / 2**20:.1f} MB"
    assert 0 < recorder.largest <= BAND_BYTES
    assert load_belief(tmp_path / "belief.npz").beliefs.shape == (ny, nx, k)
