"""Greedy exploration with known poses (issue 6, first part): stop rules, safety, coverage, determinism."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from crlam.cli import main
from crlam.errors import ConfigError
from crlam.experiments.explore import ExploreConfig, default_start, explore, truth_grid
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
