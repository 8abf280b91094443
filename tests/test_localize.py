"""Monte Carlo localization on a fixed map: global convergence, tracking, kidnapping, the KLD
bounds, the run folder and the command line, on a small simulated world (and on the real data
when CRLAM_DATA is set)."""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import NDArray

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from crlam.cli import main
from crlam.errors import ConfigError, DataFormatError
from crlam.io.belief import save_belief
from crlam.io.carmen import LaserScan, read_scans
from crlam.io.tum import read_tum
from crlam.localize import LocalizeConfig, Localizer, converged_at
from crlam.localize.map import LocalizationMap, Nav2Prior, load_localization_map
from crlam.mapping import ConfidenceRichMap, MappingConfig
from crlam.pose import between, compose
from crlam.sim.lookalike import INTEL_SCALE, lookalike_world
from crlam.sim.simulate import SimulationConfig, simulate, write_simulation
from crlam.sim.world import World

RES = 0.05


def _world() -> World:
    """A 9 m x 6 m floor: an outer wall, an inner wall with a door, and boxes placed without
    symmetry, so that every pose looks different from every other."""
    nx, ny = int(9 / RES), int(6 / RES)
    occ = np.zeros((ny, nx), dtype=bool)
    occ[:3, :] = occ[-3:, :] = True
    occ[:, :3] = occ[:, -3:] = True

    def box(x0: float, y0: float, x1: float, y1: float) -> None:
        occ[int(y0 / RES) : int(y1 / RES), int(x0 / RES) : int(x1 / RES)] = True

    box(5.5, 0.0, 5.7, 2.2)  # inner wall, door between y = 2.2 and 3.4
    box(5.5, 3.4, 5.7, 6.0)
    box(1.0, 4.0, 2.2, 4.6)
    box(3.2, 1.0, 3.6, 1.8)
    box(7.0, 4.2, 8.2, 4.5)
    box(6.6, 1.0, 6.9, 1.3)
    return World(occ, RES, name="asymmetric")


@dataclass(frozen=True)
class Sim:
    folder: Path
    scans: list[LaserScan]
    truth: NDArray[np.float64]


@pytest.fixture(scope="module")
def sim(tmp_path_factory: pytest.TempPathFactory) -> Sim:
    d = tmp_path_factory.mktemp("locsim")
    _world().to_nav2_yaml(d / "floor.yaml")
    write_simulation(simulate(SimulationConfig(world=str(d / "floor.yaml"), n_scans=320, seed=3, sensor="sick")), d)
    scans = list(read_scans(d / "log.clf"))
    return Sim(d, scans, read_tum(d / "groundtruth.tum").poses)


N = 160
"""Most tests use the first 160 scans (4 m of travel); the kidnapping, all 320."""


@pytest.fixture(scope="module")
def mapped(sim: Sim) -> Path:
    """A CRM of the simulated log mapped at the true poses, saved as belief.npz."""
    crm = ConfidenceRichMap(MappingConfig(resolution=RES, max_range=10.0))
    for s, p in zip(sim.scans, sim.truth):
        r = np.where(s.ranges >= s.max_range, np.inf, s.ranges)
        crm.update(compose(p, s.laser_offset), s.angles, r)
    save_belief(sim.folder / "belief.npz", crm.to_archive())
    return sim.folder / "belief.npz"


# spread_particles 0: a global start draws max_particles (the fast tests' count; the larger
# spread set has a test of its own).
FAST = {"max_beams": 45, "max_particles": 2000, "min_particles": 100, "spread_particles": 0, "seed": 1}


def _run(loc: Localizer, scans: list[LaserScan], odoms: list[NDArray[np.float64]] | None = None) -> None:
    for i, s in enumerate(scans):
        r = np.where(s.ranges >= s.max_range, np.inf, s.ranges)
        loc.step(s.odom if odoms is None else odoms[i], s.angles, r, s.laser_offset, s.timestamp)


def _errors(est: NDArray[np.float64], truth: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    d = between(truth, est)
    return np.hypot(d[:, 0], d[:, 1]), np.abs(d[:, 2])


def test_global_localization_converges_from_a_uniform_start(sim: Sim) -> None:
    m = load_localization_map(sim.folder / "floor.yaml")
    loc = Localizer(m, LocalizeConfig(**FAST))
    assert loc.filter is not None and loc.filter.n_particles == 2000
    _run(loc, sim.scans[:N])
    conv = loc.convergence
    assert conv is not None, "never converged"
    _, est = loc.trajectory()
    dxy, dth = _errors(est, sim.truth[:N])
    # From convergence on (a heaviest cluster of at most 0.5 m spread) the estimate stays with the
    # truth, and settles on it.
    assert dxy[conv.scan_index :].max() < 0.5 and dth[conv.scan_index :].max() < 0.2, (dxy.max(), conv)
    assert np.median(dxy[-40:]) < 0.08
    # KLD has cut the count far below the global start.
    assert loc.steps[-1].n_after < 1000


def test_tracks_a_saved_crm_from_a_known_pose(sim: Sim, mapped: Path) -> None:
    m = load_localization_map(mapped)
    assert m.kind == "belief"
    loc = Localizer(m, LocalizeConfig(**FAST), initial_pose=sim.truth[0], initial_cov=[0.04, 0.04, 0.01])
    _run(loc, sim.scans[:N])
    _, est = loc.trajectory()
    dxy, dth = _errors(est, sim.truth[:N])
    assert dxy[5:].max() < 0.15 and np.median(dxy) < 0.05 and dth[5:].max() < 0.1, (dxy.max(), dth.max())
    assert loc.convergence is not None and loc.convergence.scan_index < 10


def test_a_kidnapped_robot_is_found_again(sim: Sim, mapped: Path) -> None:
    """Scans 0..59, then the robot is carried to where scan 160 was taken (2.8 m away): the scans
    jump, the odometry goes on from its pose as if nothing happened; 4 m of travel follow."""
    m = load_localization_map(mapped)
    cfg = LocalizeConfig(**FAST | {"alpha_fast": 0.2})
    loc = Localizer(m, cfg, initial_pose=sim.truth[0], initial_cov=[0.01, 0.01, 0.005])
    scans = sim.scans[:60] + sim.scans[160:]
    truth = np.vstack([sim.truth[:60], sim.truth[160:]])
    odoms = [s.odom for s in sim.scans[:60]]
    for k in range(160, len(sim.scans)):
        step = np.zeros(3) if k == 160 else between(sim.scans[k - 1].odom, sim.scans[k].odom)
        odoms.append(compose(odoms[-1], step))
    _run(loc, scans, odoms)
    _, est = loc.trajectory()
    dxy, _ = _errors(est, truth)
    assert dxy[59] < 0.1 and dxy[60] > 1.0, (dxy[59], dxy[60])
    assert sum(s.n_injected for s in loc.steps[60:]) > 0, "recovery never drew random particles"
    assert np.median(dxy[-15:]) < 0.1, dxy[-15:]


def test_particle_count_stays_within_the_kld_bounds(sim: Sim) -> None:
    m = load_localization_map(sim.folder / "floor.yaml")
    cfg = LocalizeConfig(**FAST | {"min_particles": 150, "max_particles": 1500})
    loc = Localizer(m, cfg)
    _run(loc, sim.scans[:N])
    processed = [s for s in loc.steps if s.processed]
    assert processed[0].n_particles == 1500
    for s in processed:
        assert 150 <= s.n_after <= 1500 + s.n_injected, s
        assert 150 <= s.n_particles
    # Gathered: the count falls to the bound of the few bins the set occupies.
    assert min(s.n_after for s in processed) < 600


def test_a_spread_set_may_hold_spread_particles(sim: Sim) -> None:
    """A global start draws spread_particles; KLD keeps at most that many while the set is
    spread, and at most max_particles once it has gathered."""
    m = load_localization_map(sim.folder / "floor.yaml")
    cfg = LocalizeConfig(**FAST | {"max_particles": 1000, "spread_particles": 4000})
    loc = Localizer(m, cfg)
    _run(loc, sim.scans[:N])
    processed = [s for s in loc.steps if s.processed]
    assert processed[0].n_particles == 4000
    assert max(s.n_after for s in processed) <= 4000 + max(s.n_injected for s in processed)
    # Gathered by the end: max_particles bounds the set again.
    assert loc.convergence is not None
    assert all(s.n_after <= 1000 + s.n_injected for s in processed[-10:]), [s.n_after for s in processed[-10:]]


def test_the_climb_puts_spread_particles_on_the_true_pose(sim: Sim) -> None:
    """With spread_climb, the particles of a global start that fall in the true pose's basin
    climb onto it at the first scan; without it, hardly any lies that near."""
    m = load_localization_map(sim.folder / "floor.yaml")

    def near_truth(climb: bool) -> int:
        loc = Localizer(m, LocalizeConfig(**FAST | {"spread_climb": climb}))
        _run(loc, sim.scans[:1])
        assert loc.filter is not None
        p = loc.filter.particle_poses()
        d = between(np.broadcast_to(sim.truth[0], p.shape), p)
        return int(np.sum((np.hypot(d[:, 0], d[:, 1]) < 0.1) & (np.abs(d[:, 2]) < 0.05)))

    plain, climbed = near_truth(False), near_truth(True)
    assert plain <= 3 and climbed >= 20, (plain, climbed)


def test_no_free_cell_means_no_global_start(tmp_path: Path) -> None:
    crm = ConfidenceRichMap(MappingConfig(resolution=0.1))
    m = LocalizationMap(crm=crm, rect=(0, 0, 10, 10), source="prior", kind="belief")
    with pytest.raises(ConfigError, match="no free cell"):
        Localizer(m, LocalizeConfig())


def test_config_is_checked() -> None:
    with pytest.raises(ConfigError, match="min_particles"):
        LocalizeConfig(min_particles=10, max_particles=5)
    with pytest.raises(ConfigError, match="tempering"):
        LocalizeConfig(tempering=0.0)
    with pytest.raises(ConfigError, match="min_neff"):
        LocalizeConfig(min_neff=1.0)
    with pytest.raises(ConfigError, match="motion"):
        LocalizeConfig(motion="teleport")
    with pytest.raises(ConfigError, match="min_cluster"):
        LocalizeConfig(min_cluster=-1)
    with pytest.raises(ConfigError, match="keep_ratio"):
        LocalizeConfig(keep_ratio=0.0)
    with pytest.raises(ConfigError, match="min_bin"):
        LocalizeConfig(min_bin=-1)
    with pytest.raises(ConfigError, match="spread_particles"):
        LocalizeConfig(spread_particles=-5)
    with pytest.raises(ConfigError, match="place_xy"):
        LocalizeConfig(place_xy=-1.0)
    with pytest.raises(ConfigError, match="place_theta"):
        LocalizeConfig(place_theta=0.0)
    with pytest.raises(ConfigError, match="convergence_odds"):
        LocalizeConfig(convergence_odds=0.5)
    with pytest.raises(ConfigError, match="spread_climb"):
        LocalizeConfig(spread_climb=1)  # type: ignore[arg-type]


def test_convergence_needs_the_odds_over_the_second_cluster() -> None:
    c = LocalizeConfig(convergence_odds=100.0)
    assert converged_at(c, 0.995, 0.004, 0.1, 0.05)
    # As heavy and compact, but a look-alike place holds 1/50 of its weight: not yet.
    assert not converged_at(c, 0.97, 0.97 / 50, 0.1, 0.05)
    assert not converged_at(c, 0.995, 0.0, 0.6, 0.05)  # not compact
    assert not converged_at(c, 0.995, 0.0, 0.1, 0.3)
    assert not converged_at(c, 0.85, 0.0, 0.1, 0.05)  # not heavy enough
    # Odds 1: the heaviest cluster's weight and spread alone (the rule before the odds).
    assert converged_at(LocalizeConfig(convergence_odds=1.0), 0.9, 0.1, 0.5, 0.2)


def test_nav2_prior_states_its_classes(sim: Sim) -> None:
    prior = Nav2Prior(occupied_mean=0.8, free_mean=0.02)
    m = load_localization_map(sim.folder / "floor.yaml", nav2_prior=prior)
    mean = m.expected_occupancy()
    occ = _world().occupied
    assert mean.values.shape == occ.shape
    assert np.allclose(mean.values[occ], 0.8, atol=1e-6) and np.allclose(mean.values[~occ], 0.02, atol=1e-6)
    conf = m.description["confidence"]
    assert conf["occupied"]["mean"] == pytest.approx(0.8) and conf["free"]["std"] > 0
    assert m.description["cells"]["occupied"] == int(occ.sum())
    with pytest.raises(ConfigError):
        Nav2Prior(free_mean=0.9, occupied_mean=0.5)


def test_cli_writes_the_run_folder(sim: Sim, tmp_path: Path) -> None:
    out = tmp_path / "run"
    t0 = sim.truth[0]
    args = ["localize", str(sim.folder / "log.clf"), "--map", str(sim.folder / "floor.yaml"), "--out", str(out)]
    args += ["--initial-pose", *(str(v) for v in t0), "--initial-cov", "0.01", "0.01", "0.005"]
    args += ["--max-beams", "45", "--kld-max-particles", "1000", "--reference", str(sim.folder / "groundtruth.tum"), "--quiet"]
    args += ["--max-scans", str(N)]
    assert main(args) == 0
    for name in ("config.toml", "trajectory.tum", "particles.csv", "metrics.json", "localization.png"):
        assert (out / name).stat().st_size > 0, name
    m = json.loads((out / "metrics.json").read_text())
    assert m["n_scans"] == N and m["mode"] == "initial pose"
    assert m["reference"]["rmse_position_m"] < 0.1
    assert m["endpoints_within_0.1m"]["after_convergence"] > 0.9
    assert m["map"]["kind"] == "nav2" and "confidence" in m["map"]
    with open(out / "particles.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == m["n_processed"] and all(int(r["n_particles"]) >= 100 for r in rows)
    assert read_tum(out / "trajectory.tum").poses.shape == (N, 3)
    assert "[localize]" in (out / "config.toml").read_text()
    assert tomllib.loads((out / "config.toml").read_text())["localize"]["spread_climb"] is True


def test_cli_global_trials(sim: Sim, tmp_path: Path) -> None:
    out = tmp_path / "trials"
    args = ["localize", str(sim.folder / "log.clf"), "--map", str(sim.folder / "floor.yaml"), "--out", str(out), "--quiet"]
    args += ["--trials", "2", "--trial-travel", "3", "--target-travel", "3", "--max-beams", "45", "--kld-max-particles", "2000"]
    args += ["--reference", str(sim.folder / "groundtruth.tum")]
    assert main(args) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["n_trials"] == 2 and m["judged_against_reference"]
    with open(out / "trials.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 2 and (out / "trials.png").stat().st_size > 0
    assert m["n_within_target"] == sum(1 for r in rows if r["correct"] == "1" and float(r["distance_m"]) <= 3.0)
    assert (out / "COMPLETE").is_file() and (out / "experiment.json").is_file()
    # An existing folder is refused; --resume keeps its finished trials (their rows, wall times
    # included, come back unchanged) and refuses other settings.
    assert main(args) == 2
    (out / "trials.csv").write_text((out / "trials.csv").read_text().rsplit("\n", 2)[0] + "\n")  # trial 1 lost
    assert main(args + ["--resume"]) == 0
    with open(out / "trials.csv") as fh:
        again = list(csv.DictReader(fh))
    assert again[0] == rows[0] and len(again) == 2
    assert main(args + ["--resume", "--tempering", "20"]) == 2


def test_cli_run_folder_is_staged(sim: Sim, tmp_path: Path) -> None:
    out = tmp_path / "run"
    args = ["localize", str(sim.folder / "log.clf"), "--map", str(sim.folder / "floor.yaml"), "--out", str(out), "--quiet"]
    args += ["--initial-pose", *(str(v) for v in sim.truth[0]), "--max-beams", "45", "--max-scans", "20"]
    assert main(args) == 0
    assert (out / "COMPLETE").is_file() and not (tmp_path / "run.incomplete").exists()
    first = (out / "trajectory.tum").read_bytes()
    assert main(args) == 2  # refused: it exists
    assert main(args + ["--force", "--seed", "3"]) == 0
    assert (out / "trajectory.tum").read_bytes() != first
    assert main(args + ["--force", "--no-spread-climb"]) == 0
    assert tomllib.loads((out / "config.toml").read_text())["localize"]["spread_climb"] is False


def test_cli_refuses_contradictory_starts(sim: Sim, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    base = ["localize", str(sim.folder / "log.clf"), "--map", str(sim.folder / "floor.yaml"), "--out", str(tmp_path / "x")]
    assert main(base + ["--global", "--initial-pose", "1", "1", "0"]) == 2
    assert main(base + ["--initial-cov", "0.1", "0.1", "0.1"]) == 2
    assert main(base + ["--initial-pose", "1", "1", "0", "--initial-cov", "1", "2"]) == 2
    assert "initial-cov" in capsys.readouterr().err


def test_map_loading_errors(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError):
        load_localization_map(tmp_path / "missing.npz")
    (tmp_path / "empty").mkdir()
    with pytest.raises(DataFormatError, match="belief.npz"):
        load_localization_map(tmp_path / "empty")
    (tmp_path / "map.txt").write_text("x")
    with pytest.raises(DataFormatError):
        load_localization_map(tmp_path / "map.txt")


@pytest.mark.realdata
@pytest.mark.slow
def test_turtlebot_bag_tracks_on_its_floor_map(data_dir: Path, tmp_path: Path) -> None:
    """The TurtleBot 4 bag from its odometry's first pose (its odometry frame is close to the
    floor map's): the scans land on the map's walls."""
    bag = data_dir / "bags" / "turtlebot4-mac-floor"
    if not bag.is_dir():
        pytest.skip("the TurtleBot 4 bag is not in CRLAM_DATA")
    args = ["localize", str(bag), "--map", str(bag / "mac_1st_floor_final.yaml"), "--out", str(tmp_path), "--quiet"]
    args += ["--initial-pose", "6.54", "-8.86", "1.705", "--initial-cov", "0.25", "0.25", "0.03"]
    args += ["--nav2-free-thresh", "0.196", "--skip-no-returns", "--max-beams", "90"]
    assert main(args) == 0
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["endpoints_within_0.1m"]["after_convergence"] > 0.8
    assert math.isfinite(m["distance_m"]) and m["distance_m"] > 7.0


def test_the_lookalike_floor_of_intels_scale() -> None:
    """Ten 5 m x 5 m rooms each side of a 3 m corridor: 627 m² of free space (Intel's map about
    765 m²), against 150 m² for the default floor; sizes too small for a door and desk are refused."""
    res = 0.05
    big, small = lookalike_world(**INTEL_SCALE), lookalike_world()
    assert math.isclose((~big.occupied).sum() * res**2, 627, abs_tol=15), (~big.occupied).sum() * res**2
    assert (~big.occupied).sum() > 4 * (~small.occupied).sum()
    with pytest.raises(ValueError, match="room_w"):
        lookalike_world(room_w=3.0)


@pytest.fixture(scope="module")
def lookalike(tmp_path_factory: pytest.TempPathFactory) -> Sim:
    """300 scans on a floor of three look-alike rooms each side of a corridor
    (:func:`crlam.sim.lookalike.lookalike_world`)."""
    d = tmp_path_factory.mktemp("lookalike")
    lookalike_world(3).to_nav2_yaml(d / "floor.yaml")
    write_simulation(simulate(SimulationConfig(world=str(d / "floor.yaml"), n_scans=300, seed=1, sensor="sick")), d)
    return Sim(d, list(read_scans(d / "log.clf")), read_tum(d / "groundtruth.tum").poses)


def _converged_error(loc: Localizer, truth: NDArray[np.float64]) -> float:
    assert loc.convergence is not None
    k = loc.convergence.scan_index
    dxy, _ = _errors(loc.steps[k].estimate[None, :], truth[k][None, :])
    return float(dxy[0])


def test_lookalike_rooms_are_kept_until_the_scans_tell_them_apart(lookalike: Sim) -> None:
    """AMCL's resampling and convergence rule settle two rooms (8 m) from the truth; with the
    competing clusters kept (the defaults) the filter waits until the scans tell the places
    apart, and converges at the truth."""
    m = load_localization_map(lookalike.folder / "floor.yaml")
    fast = FAST | {"seed": 2}
    old = Localizer(m, LocalizeConfig(**fast | {"min_cluster": 0, "convergence_odds": 1.0}))
    _run(old, lookalike.scans)
    assert old.convergence is not None and _converged_error(old, lookalike.truth) > 3.0
    new = Localizer(m, LocalizeConfig(**fast))
    _run(new, lookalike.scans)
    assert new.convergence is not None and _converged_error(new, lookalike.truth) < 0.3
    assert new.convergence.distance_m > old.convergence.distance_m
    # Competing places were kept (and weighed as a spread set) before it converged.
    before = [s for s in new.steps[: new.convergence.scan_index] if s.processed]
    assert max(s.n_kept for s in before) >= 2 and max(s.second_weight for s in before) > 1e-3
