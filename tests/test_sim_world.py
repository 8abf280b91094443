"""Worlds: grid algorithms, image / Nav2 loading, and the procedural museum and office."""

from __future__ import annotations

from collections import deque
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crlam.errors import ConfigError, DataFormatError
from crlam.sim import (
    World,
    get_world,
    museum_layout,
    museum_world,
    office_layout,
    office_world,
    read_pgm,
)
from crlam.sim.grid_ops import ClearanceField, distance_map, label_components
from crlam.sim.shapes import Disc
from crlam.sim.world import write_pgm


def _bfs_labels(mask: np.ndarray, connectivity: int) -> np.ndarray:
    """Reference component labelling by breadth-first search, numbered in row-major order."""
    ny, nx = mask.shape
    out = np.zeros(mask.shape, dtype=int)
    nbrs = [(1, 0), (-1, 0), (0, 1), (0, -1)]
    if connectivity == 8:
        nbrs += [(1, 1), (1, -1), (-1, 1), (-1, -1)]
    k = 0
    for y in range(ny):
        for x in range(nx):
            if mask[y, x] and not out[y, x]:
                k += 1
                out[y, x] = k
                todo = deque([(y, x)])
                while todo:
                    cy, cx = todo.popleft()
                    for dy, dx in nbrs:
                        yy, xx = cy + dy, cx + dx
                        if 0 <= yy < ny and 0 <= xx < nx and mask[yy, xx] and not out[yy, xx]:
                            out[yy, xx] = k
                            todo.append((yy, xx))
    return out


def _brute_clearance(occ: np.ndarray, res: float, origin: np.ndarray, pts: np.ndarray, cap: float) -> np.ndarray:
    """Distance from points to the nearest occupied square, by checking every occupied cell."""
    ys, xs = np.nonzero(occ)
    x0 = origin[0] + xs * res
    y0 = origin[1] + ys * res
    ex = np.maximum(np.maximum(x0[None] - pts[:, :1], pts[:, :1] - (x0[None] + res)), 0.0)
    ey = np.maximum(np.maximum(y0[None] - pts[:, 1:], pts[:, 1:] - (y0[None] + res)), 0.0)
    d = np.hypot(ex, ey).min(axis=1) if len(xs) else np.full(len(pts), np.inf)
    return np.minimum(d, cap)


# ------------------------------------------------------------------------------ grid ops
@settings(max_examples=60, deadline=None)
@given(
    ny=st.integers(1, 20),
    nx=st.integers(1, 20),
    density=st.floats(0.05, 0.9),
    seed=st.integers(0, 2**31),
    connectivity=st.sampled_from([4, 8]),
)
def test_label_components_matches_bfs(ny: int, nx: int, density: float, seed: int, connectivity: int) -> None:
    mask = np.random.default_rng(seed).random((ny, nx)) < density
    labels, sizes = label_components(mask, connectivity)
    np.testing.assert_array_equal(labels, _bfs_labels(mask, connectivity))
    assert sizes.sum() == mask.size
    assert sizes[0] == (~mask).sum()


@settings(max_examples=40, deadline=None)
@given(ny=st.integers(1, 16), nx=st.integers(1, 16), seed=st.integers(0, 2**31), res=st.sampled_from([0.05, 0.2, 1.0]))
def test_distance_map_and_clearance_field_are_exact(ny: int, nx: int, seed: int, res: float) -> None:
    rng = np.random.default_rng(seed)
    occ = rng.random((ny, nx)) < 0.12
    origin = rng.uniform(-3, 3, 2)
    cap = 6 * res
    iy, ix = np.mgrid[0:ny, 0:nx]
    centres = np.stack([origin[0] + (ix.ravel() + 0.5) * res, origin[1] + (iy.ravel() + 0.5) * res], axis=1)
    ref = _brute_clearance(occ, res, origin, centres, cap).reshape(ny, nx)
    np.testing.assert_allclose(distance_map(occ, res, cap), ref, atol=1e-9)
    np.testing.assert_allclose(ClearanceField(occ, res, origin, cap).at_cells(iy, ix), ref, atol=1e-9)
    # Arbitrary points: the field gives a lower bound, World.clearance the exact value.
    pts = origin + rng.uniform(0, 1, (50, 2)) * np.array([nx, ny]) * res
    exact = _brute_clearance(occ, res, origin, pts, cap)
    world = World(occ, res, origin)
    np.testing.assert_allclose(world.clearance(pts, cap), exact, atol=1e-9)
    assert np.all(ClearanceField(occ, res, origin, cap).at_points(pts) <= exact + 1e-9)


def test_inflated_cells_are_safe_for_a_disc() -> None:
    rng = np.random.default_rng(3)
    world = World(rng.random((40, 50)) < 0.03, 0.1, np.array([1.0, -2.0]))
    radius = 0.33
    infl = world.inflated(radius)
    assert (infl | ~world.occupied).all() and infl.sum() > world.occupied.sum()
    iy, ix = np.nonzero(~infl)
    assert np.all(world.clearance(world.cell_centers(ix, iy), 1.0) > radius)
    iy, ix = np.nonzero(infl & ~world.occupied)
    assert np.all(world.clearance(world.cell_centers(ix, iy), 1.0) <= radius + 1e-12)


def test_world_geometry_helpers() -> None:
    occ = np.zeros((4, 6), dtype=bool)
    occ[1, 2] = True  # the cell covering x in [1.0, 1.5), y in [0.5, 1.0) with the origin below
    world = World(occ, 0.5, np.array([0.0, 0.0]), "tiny")
    assert world.shape == (4, 6) and world.width == 3.0 and world.height == 2.0
    assert world.extent == (0.0, 3.0, 0.0, 2.0)
    pts = np.array([[1.2, 0.7], [0.2, 0.2], [-0.1, 0.5], [3.0, 1.0]])
    np.testing.assert_array_equal(world.is_free(pts), [False, True, False, False])
    np.testing.assert_allclose(world.cell_centers(2, 1), [1.25, 0.75])
    with pytest.raises(ConfigError):
        World(np.zeros((0, 3), dtype=bool), 0.1)
    with pytest.raises(ConfigError):
        World(np.zeros((3, 3), dtype=bool), -1.0)


# ------------------------------------------------------------------------------ file loading
def test_pgm_p5_p2_and_16bit(tmp_path: Path) -> None:
    grey = np.array([[0, 100, 200], [255, 127, 128]], dtype=np.uint8)
    write_pgm(tmp_path / "a.pgm", grey)
    np.testing.assert_array_equal(read_pgm(tmp_path / "a.pgm"), grey)
    (tmp_path / "b.pgm").write_text("P2\n# comment\n3 2\n# another\n255\n0 100 200\n255 127 128\n")
    np.testing.assert_array_equal(read_pgm(tmp_path / "b.pgm"), grey)
    wide = (grey.astype(">u2") * 257).tobytes()
    (tmp_path / "c.pgm").write_bytes(b"P5 3 2 65535\n" + wide)
    np.testing.assert_array_equal(read_pgm(tmp_path / "c.pgm"), grey)
    (tmp_path / "d.pgm").write_bytes(b"P5\n3 2\n255\n\x00\x01")
    with pytest.raises(DataFormatError, match="raster"):
        read_pgm(tmp_path / "d.pgm")
    world = World.from_image(tmp_path / "a.pgm", resolution=0.5, origin=(1.0, 2.0))
    # Image row 0 is the top (maximum y): it becomes grid row ny - 1.
    np.testing.assert_array_equal(world.occupied, [[False, True, False], [True, True, False]])
    np.testing.assert_allclose(world.origin, [1.0, 2.0])


def test_png_and_nav2_yaml(tmp_path: Path) -> None:
    from PIL import Image

    grey = np.full((5, 7), 254, dtype=np.uint8)
    grey[0, :] = 0  # top wall
    grey[2, 3] = 205  # unknown in Nav2 trinary terms
    Image.fromarray(grey).save(tmp_path / "m.png")
    w_png = World.from_image(tmp_path / "m.png", resolution=0.1)
    assert w_png.occupied[-1].all() and not w_png.occupied[2, 3]  # 205 >= 128: free for from_image
    (tmp_path / "m.yaml").write_text(
        "image: m.png\nresolution: 0.1\norigin: [-1.0, 2.5, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    w = World.from_nav2_yaml(tmp_path / "m.yaml")
    np.testing.assert_allclose(w.origin, [-1.0, 2.5])
    assert w.occupied[-1].all() and w.occupied[2, 3]  # unknown counts as an obstacle
    assert w.occupied.sum() == 8
    # Round trip through the writer.
    (tmp_path / "out").mkdir()
    w.to_nav2_yaml(tmp_path / "out" / "world.yaml")
    back = World.from_nav2_yaml(tmp_path / "out" / "world.yaml")
    np.testing.assert_array_equal(back.occupied, w.occupied)
    assert back.resolution == w.resolution
    np.testing.assert_allclose(back.origin, w.origin)
    assert get_world(tmp_path / "m.png").occupied[2, 3]  # the sidecar YAML wins for a bare image
    assert get_world(tmp_path / "out" / "world.pgm").occupied[2, 3]  # world.yaml is its sidecar
    (tmp_path / "bare.pgm").write_bytes((tmp_path / "out" / "world.pgm").read_bytes())
    with pytest.raises(ConfigError, match="resolution"):
        get_world(tmp_path / "bare.pgm")  # no YAML beside it: the resolution is required
    assert get_world(tmp_path / "bare.pgm", resolution=0.1).shape == (5, 7)
    with pytest.raises(ConfigError):
        get_world("no-such-world")


def test_cave_map_loads(data_dir: Path) -> None:
    path = data_dir / "maps" / "cave.pgm"
    world = World.from_image(path, resolution=0.2)
    assert world.shape == (100, 100)
    assert world.extent == (0.0, 20.0, 0.0, 20.0)
    assert 0.5 < world.free_fraction < 0.95
    raw = read_pgm(path)
    np.testing.assert_array_equal(world.occupied, np.flipud(raw < 128))


# ------------------------------------------------------------------------------ procedural
def _check_connected(world: World, robot_radius: float = 0.3, tolerance: float = 0.005) -> None:
    _, sizes = label_components(~world.occupied, 4)
    assert len(sizes) == 2, f"free space has {len(sizes) - 1} components"
    reach = world.distance_map(robot_radius + 0.2) > robot_radius + 0.5 * world.resolution
    _, rs = label_components(reach, 4)
    assert rs[1:].max() >= (1.0 - tolerance) * rs[1:].sum()


def test_museum_world() -> None:
    world = museum_world(0)
    assert world.shape == (1800, 1800) and world.resolution == 0.05
    assert world.extent == (0.0, 90.0, 0.0, 90.0)
    _check_connected(world)
    # Cluttered, not just walls: enough occupied area and many separate obstacles.
    assert 0.05 < world.occupied.mean() < 0.25
    _, obstacles = label_components(world.occupied, 8)
    assert len(obstacles) - 1 > 200
    # The boundary is closed.
    assert world.occupied[0].all() and world.occupied[-1].all()
    assert world.occupied[:, 0].all() and world.occupied[:, -1].all()
    np.testing.assert_array_equal(world.occupied, museum_world(0).occupied)


def test_museum_layout_has_halls_rooms_doors_pillars() -> None:
    layout = museum_layout(0)
    kinds = {r.kind for r in layout.rooms}
    assert {"hall", "gallery", "cabinet"} <= kinds
    assert len(layout.rooms) >= 15
    assert len(layout.doors) >= len(layout.rooms) - 1  # one door per BSP wall at least
    assert min(d.width for d in layout.doors) >= 1.2
    assert sum(isinstance(s, Disc) for s in layout.furniture.shapes) >= 20
    assert len(layout.furniture.groups) >= 200


def test_museum_other_seed_and_resolution() -> None:
    coarse = museum_world(1, resolution=0.2)
    assert coarse.shape == (450, 450)
    _check_connected(coarse, tolerance=0.01)
    assert not np.array_equal(coarse.occupied, museum_world(0, resolution=0.2).occupied)


def test_office_world() -> None:
    world = office_world(0)
    assert world.shape == (300, 400) and world.extent == (0.0, 20.0, 0.0, 15.0)
    _check_connected(world)
    layout = office_layout(0)
    assert sum(r.kind == "corridor" for r in layout.rooms) == 1 and len(layout.rooms) == 8
    assert min(d.width for d in layout.doors) >= 1.2
    assert world.occupied.mean() > 0.08  # walls and furniture
    np.testing.assert_array_equal(get_world("office", 0).occupied, world.occupied)
    with pytest.raises(ConfigError):
        office_world(-1)
