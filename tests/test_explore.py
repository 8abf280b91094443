"""Greedy exploration with known poses (issue 6, first part): stop rules, safety, coverage, determinism;
the native geodesic against the pure-Python reference, and the decision window against the whole map."""

from __future__ import annotations

import heapq
import json
import math
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

from crlam import _native
from crlam.cli import main
from crlam.errors import ConfigError, MapBoundsError
from crlam.experiments.explore import ExploreConfig, default_start, explore, geodesic, truth_grid
from crlam.experiments.explore_window import decision_maps, map_window
from crlam.sim.world import World


def small_room() -> World:
    """A closed 6 m x 4 m room (0.05 m cells) with a 1 m box in it."""
    occ = np.zeros((80, 120), dtype=bool)
    occ[:2, :] = occ[-2:, :] = occ[:, :2] = occ[:, -2:] = True
    occ[30:50, 70:90] = True
    return World(occ, 0.05, name="room")


START = (1.0, 1.0, 0.0)


def test_stop_rules() -> None:
    w = small_room()
    assert explore(w, START, ExploreConfig(threshold=1e9)).stop == "threshold"
    r = explore(w, START, ExploreConfig(budget_m=3.0, threshold=0.0))
    assert r.stop == "budget" and 3.0 <= r.distance < 3.0 + 0.3
    assert explore(w, START, ExploreConfig(max_decisions=2, threshold=0.0)).stop == "max_decisions"
    f = explore(w, START, ExploreConfig(function="frontier", budget_m=500.0))
    assert f.stop == "no_candidates"


def test_blocked_stop_rule_with_a_lost_filter() -> None:
    # One particle and 0.2 rad of heading noise per step: the estimate is soon wrong, the paths
    # planned on it run into walls, and three decisions in a row that bump end the run. The
    # robot never enters a wall (explore raises if it does).
    cfg = ExploreConfig(slam=True, slam_particles=1, odometry_sigma=(0.02, 0.02, 0.2), budget_m=60.0, threshold=0.0, seed=1)
    r = explore(small_room(), START, cfg)
    assert r.stop == "blocked"
    assert r.bumps >= 3 and r.distance < cfg.budget_m


@pytest.mark.parametrize("function", ["crmi", "frontier", "fsmi"])
def test_paths_stay_in_free_space_and_cover_a_closed_world(function: str) -> None:
    w = small_room()
    cfg = ExploreConfig(function=function, threshold=0.0, budget_m=60.0, max_decisions=60)
    r = explore(w, START, cfg)
    # Every point of the driven path (checked every 2 cm) is in a free cell of the true world.
    p = r.poses[:, :2]
    for a, b in zip(p[:-1], p[1:], strict=True):
        n = max(2, int(np.hypot(*(b - a)) / 0.02) + 1)
        for q in np.linspace(a, b, n):
            iy, ix = int(q[1] / w.resolution), int(q[0] / w.resolution)
            assert not w.occupied[iy, ix], f"{function}: path crosses an occupied cell at {q}"
    # Every free cell of the room is observed by the end (the box's interior cannot be).
    truth = truth_grid(w, cfg.resolution)
    ent = r.crm.entropy((0.0, 0.0, 6.0, 4.0)).values
    observed = ent < np.log2(10.0) - 1e-3
    free = ~truth
    assert observed[free].mean() > 0.95, observed[free].mean()


def test_same_seed_same_run() -> None:
    w = small_room()
    cfg = ExploreConfig(budget_m=15.0, threshold=0.0, seed=3)
    a, b = explore(w, START, cfg), explore(w, START, cfg)
    np.testing.assert_array_equal(a.poses, b.poses)
    assert [d["best_gain"] for d in a.decisions] == [d["best_gain"] for d in b.decisions]


def test_ucrmi_explores_with_a_pose_term() -> None:
    r = explore(small_room(), START, ExploreConfig(function="ucrmi", particles=15, budget_m=8.0, threshold=-1e9))
    assert r.stop == "budget" and len(r.decisions) >= 1


def test_bad_settings() -> None:
    with pytest.raises(ConfigError):
        ExploreConfig(function="random")
    with pytest.raises(ConfigError):
        ExploreConfig(budget_m=0.0)
    full = World(np.ones((20, 20), dtype=bool), 0.05)
    with pytest.raises(ConfigError):
        default_start(full)


def test_cli_explore_writes_the_run_folder(tmp_path: Path) -> None:
    out = tmp_path / "run"
    assert main(["explore", "--world", "office", "--budget", "12", "--out", str(out), "--quiet"]) == 0
    for name in ("trajectory.tum", "groundtruth.tum", "map.pgm", "map.yaml", "belief.npz", "progress.csv", "exploration.gif"):
        assert (out / name).stat().st_size > 0, name
    for name in ("exploration.png", "progress.png"):
        assert (out / name).stat().st_size > 20_000
    m = json.loads((out / "metrics.json").read_text())
    assert m["stop_reason"] == "budget" and m["explored_m2"] > 10 and m["n_scans"] > 10
    assert main(["explore", "--world", "nowhere.pgm", "--out", str(tmp_path / "x")]) == 2


@pytest.mark.parametrize("function", ["crmi", "ucrmi"])
def test_slam_mode_tracks_the_pose(function: str) -> None:
    w = small_room()
    cfg = ExploreConfig(function=function, slam=True, slam_particles=20, budget_m=12.0, threshold=0.0, seed=2)
    r = explore(w, START, cfg)
    assert r.stop in ("budget", "threshold") and len(r.poses) == len(r.estimates) > 10
    err = np.hypot(*(r.poses[:, :2] - r.estimates[:, :2]).T)
    assert err.max() < 0.3, err.max()
    # The estimate is not simply the truth: odometry noise is really there.
    assert err.max() > 0.0
    again = explore(w, START, cfg)
    np.testing.assert_array_equal(r.estimates, again.estimates)


def test_cli_explore_slam(tmp_path: Path) -> None:
    out = tmp_path / "slam"
    assert main(["explore", "--world", "office", "--budget", "8", "--slam", "--no-gif", "--out", str(out), "--quiet"]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["mode"] == "RBPF-CLAM" and 0.0 < m["pose_error_max_m"] < 0.5


def test_explore_experiment_resumes(tmp_path: Path) -> None:
    from crlam.experiments.explore_sweep import run_explore_experiment
    from crlam.io.nav2 import write_nav2_map

    room = small_room()
    world_yaml = tmp_path / "room.pgm"
    write_nav2_map(world_yaml, room.occupied.astype(float), resolution=room.resolution, origin=(0.0, 0.0, 0.0))
    out = tmp_path / "sweep"
    kw = {
        "worlds": [str(tmp_path / "room.yaml")],
        "functions": ["crmi", "ucrmi", "frontier"],
        "alphas": [0.0, 1.0],
        "runs": 1,
        "budget": 6.0,
        "workers": 1,
        "progress": False,
    }
    res = run_explore_experiment(out, **kw)
    assert len(res.rows) == 4 and not res.errors
    assert {r["variant"] for r in res.rows} == {"crmi", "frontier", "ucrmi a=0", "ucrmi a=1"}
    assert (out / "coverage.png").stat().st_size > 20_000 and "Exploration comparison" in (out / "report.md").read_text()
    stamp = (out / "runs" / "room-crmi-s00" / "metrics.json").stat().st_mtime_ns
    again = run_explore_experiment(out, **kw)
    assert len(again.rows) == 4
    assert (out / "runs" / "room-crmi-s00" / "metrics.json").stat().st_mtime_ns == stamp
    with pytest.raises(ConfigError):
        run_explore_experiment(out, **{**kw, "alphas": [2.0]})


def test_default_start_keeps_room_from_the_map_edge() -> None:
    open_world = World(np.zeros((80, 80), dtype=bool), 0.05, name="open")  # 4 m x 4 m, no walls
    x, y, _ = default_start(open_world)
    assert min(x, y, 4.0 - x, 4.0 - y) >= 1.0 - 1e-9


def geodesic_reference(
    traversable: NDArray[np.bool_], start: tuple[int, int], res: float
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The pure-Python Dijkstra that ``explore.geodesic`` replaced (heapq of (d, u) tuples)."""
    ny, nx = traversable.shape
    dist = np.full(ny * nx, np.inf)
    pred = np.full(ny * nx, -1, dtype=np.int64)
    s = start[0] * nx + start[1]
    dist[s] = 0.0
    heap = [(0.0, s)]
    sqrt2 = math.sqrt(2.0)
    steps = [(-1, 0, 1.0), (1, 0, 1.0), (0, -1, 1.0), (0, 1, 1.0), (-1, -1, sqrt2), (-1, 1, sqrt2), (1, -1, sqrt2), (1, 1, sqrt2)]
    trav = traversable.ravel()
    while heap:
        d, u = heapq.heappop(heap)
        if d > dist[u]:
            continue
        y, x = divmod(u, nx)
        for dy, dx, c in steps:
            yy, xx = y + dy, x + dx
            if not (0 <= yy < ny and 0 <= xx < nx):
                continue
            v = yy * nx + xx
            if not trav[v] or (dy and dx and not (trav[y * nx + xx] and trav[yy * nx + x])):
                continue
            nd = d + c * res
            if nd < dist[v]:
                dist[v] = nd
                pred[v] = u
                heapq.heappush(heap, (nd, v))
    return dist.reshape(ny, nx), pred


def test_native_geodesic_equals_the_python_reference() -> None:
    rng = np.random.default_rng(11)
    for trial in range(120):
        ny, nx = (int(v) for v in rng.integers(1, 40, 2))
        trav = rng.random((ny, nx)) < rng.uniform(0.45, 1.0)
        start = (int(rng.integers(ny)), int(rng.integers(nx)))
        res = float(rng.choice([0.2, 0.05, 0.3, 1.0]))
        dist, pred = geodesic(trav, start, res)
        ref_dist, ref_pred = geodesic_reference(trav, start, res)
        # Bit for bit: same float operations and the same tie-breaking (pop order).
        np.testing.assert_array_equal(dist, ref_dist, err_msg=f"trial {trial}")
        np.testing.assert_array_equal(pred, ref_pred, err_msg=f"trial {trial}")
        assert dist.shape == (ny, nx) and pred.shape == (ny * nx,) and pred.dtype == np.int64
    # An open grid has many equal-length paths: the predecessors still agree.
    trav = np.ones((30, 30), dtype=bool)
    for got, want in zip(geodesic(trav, (7, 19), 0.2), geodesic_reference(trav, (7, 19), 0.2), strict=True):
        np.testing.assert_array_equal(got, want)
    # uint8 masks are accepted (nonzero = traversable); bad starts are refused.
    np.testing.assert_array_equal(geodesic(trav.astype(np.uint8), (0, 0), 0.2)[1], geodesic(trav, (0, 0), 0.2)[1])
    with pytest.raises(MapBoundsError):
        geodesic(trav, (30, 0), 0.2)
    with pytest.raises(ConfigError):
        geodesic(trav, (0, 0), 0.0)


def test_map_window_pads_clips_and_contains_the_robot() -> None:
    grid = (10, 20, 100, 80)  # map cells of grid cell (0, 0); 100 x 80 cells
    assert map_window((42, 36, 32, 32), grid, (30, 40), 6) == (10, 26, 44, 44)
    # Clipped to the grid at the low and high ends.
    assert map_window((0, 0, 128, 128), grid, (30, 40), 6) == (0, 0, 80, 100)
    # Grown to the robot's cell; nothing written or written only outside the grid: its cell only.
    assert map_window((42, 36, 32, 32), grid, (70, 90), 6) == (10, 26, 61, 65)
    assert map_window(None, grid, (3, 4), 6) == (3, 4, 1, 1)
    assert map_window((500, 500, 32, 32), grid, (3, 4), 6) == (3, 4, 1, 1)


def _explored_maps() -> list[tuple[str, _native.CrmMap, tuple[int, int, int, int], tuple[int, int]]]:
    """Map states after short explorations: the office partly explored (the window ends inside the
    map), the room explored to its walls (the window meets the map edge), and a SLAM run (the best
    particle's map, which has no fixed extent)."""
    from crlam.sim.worlds import get_world

    out = []
    office = get_world("office", seed=0)
    for name, w, start, cfg in (
        ("office", office, default_start(office), ExploreConfig(budget_m=8.0, threshold=0.0)),
        ("room", small_room(), START, ExploreConfig(function="frontier", budget_m=500.0)),
        ("room slam", small_room(), START, ExploreConfig(slam=True, slam_particles=10, budget_m=4.0, threshold=0.0)),
    ):
        r = explore(w, start, cfg)
        res = cfg.resolution
        ny, nx = r.truth.shape
        est = r.estimates[-1]
        here = (min(int(est[1] / res), ny - 1), min(int(est[0] / res), nx - 1))
        rect = r.crm.region((0.0, 0.0, nx * res, ny * res))
        out.append((name, r.crm.native, rect, here))
    return out


def test_decision_window_equals_the_whole_map() -> None:
    for name, native, rect, here in _explored_maps():
        win, whole = (
            decision_maps(native, rect, here, resolution=0.2, free_threshold=0.35, robot_radius=0.3, whole_map=w)
            for w in (False, True)
        )
        assert whole.mean.shape == whole.shape == (rect[3], rect[2])
        if name == "office":
            assert win.mean.size < 0.8 * whole.mean.size, (name, win.mean.shape, whole.shape)
        w = win.window
        outside = np.ones(whole.shape, dtype=bool)
        outside[w] = False
        for field in ("mean", "entropy", "observed", "free", "traversable", "to_unknown"):
            np.testing.assert_array_equal(getattr(win, field), getattr(whole, field)[w], err_msg=f"{name}: {field}")
        # Outside the window the whole map holds the prior: unknown, never free or traversable.
        assert (whole.mean[outside] == win.prior_mean).all() and (whole.entropy[outside] == win.prior_entropy).all()
        assert not (whole.observed | whole.traversable)[outside].any(), name
        assert win.entropy_sum() == whole.entropy_sum() == float(whole.entropy.sum()), name
        np.testing.assert_array_equal(win.mean_uint8(), np.round(255 * whole.mean).astype(np.uint8))
        np.testing.assert_array_equal(win.whole(win.mean, win.prior_mean), whole.mean)
        # The path search on the window: the same distances and predecessors, in window indices.
        dist_w, pred_w = geodesic(win.traversable, (here[0] - win.iy0, here[1] - win.ix0), 0.2)
        dist, pred = geodesic(whole.traversable, here, 0.2)
        np.testing.assert_array_equal(dist_w, dist[w], err_msg=name)
        assert np.isinf(dist[outside]).all()
        wny, wnx = win.mean.shape
        to_whole = ((np.arange(wny)[:, None] + win.iy0) * whole.shape[1] + np.arange(wnx)[None, :] + win.ix0).ravel()
        mapped = np.where(pred_w >= 0, to_whole[np.maximum(pred_w, 0)], -1)
        np.testing.assert_array_equal(mapped, pred.reshape(whole.shape)[w].ravel(), err_msg=name)
