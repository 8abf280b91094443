"""The localizer's measurement models: AMCL's likelihood field and beam model against values
worked out by hand, the CRM likelihood within its stated error of the exact one on random maps
and scans, global localization on the look-alike floor with each model, and ``--model`` on the
command line."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from crlam.cli import main
from crlam.errors import ConfigError
from crlam.io.belief import save_belief
from crlam.io.carmen import read_scans
from crlam.io.nav2 import write_nav2_map
from crlam.io.tum import read_tum
from crlam.localize import LocalizeConfig, Localizer
from crlam.localize.map import Nav2Prior, load_localization_map
from crlam.mapping import ConfidenceRichMap, MappingConfig
from crlam.pose import between
from crlam.sim.lookalike import lookalike_world
from crlam.sim.simulate import SimulationConfig, simulate, write_simulation
from crlam.sim.world import World

NO_OFFSET = np.zeros(3)


@pytest.fixture(scope="module")
def room(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 4 m x 4 m Nav2 map at 0.1 m: its border cells occupied (m̂ 0.9 as a CRM prior), the
    rest free (m̂ 0.01)."""
    occ = np.zeros((40, 40), dtype=bool)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    d = tmp_path_factory.mktemp("room")
    return World(occ, 0.1, name="room").to_nav2_yaml(d / "room.yaml")


def _fit(room: Path, model: str, ranges: list[float], angles: list[float] | None = None) -> tuple[float, float, int]:
    m = load_localization_map(room, max_range=10.0)
    cfg = LocalizeConfig(model=model, max_range=10.0, max_beams=0, spread_particles=0, max_particles=100, min_particles=10)
    loc = Localizer(m, cfg, initial_pose=[2.05, 2.05, 0.0], initial_cov=[0.01, 0.01, 0.01])
    assert loc.filter is not None
    a = np.zeros(len(ranges)) if angles is None else np.array(angles)
    return loc.filter.scan_fit(np.array([2.05, 2.05, 0.0]), a, np.array(ranges, dtype=np.float64), NO_OFFSET)


def test_likelihood_field_matches_hand_values(room: Path) -> None:
    # From (2.05, 2.05) along +x the wall's cells have centres at x = 3.95. Reading 1.9 m ends in
    # a wall cell (d = 0); 1.7 m two cells before it (d = 0.2 m); 0.5 m at (2.55, 2.05), 14 cells
    # from the nearest wall (d = 1.4 m); a no-return is left out. z_hit 0.95, z_rand 0.05 over
    # z_max 10 m, σ 0.2 m: p = 0.95 exp(−d² / 0.08) + 0.005.
    ll, explained, n = _fit(room, "likelihood_field", [1.9, 1.7, 0.5, math.inf])
    p = [0.95 * math.exp(-(d**2) / 0.08) + 0.005 for d in (0.0, 0.2, 1.4)]
    assert n == 3
    assert ll == pytest.approx(sum(math.log(v) for v in p), abs=1e-5)
    assert explained == pytest.approx(sum((v - 0.005) / v for v in p), abs=1e-5)
    # Capped at max_dist: a reading ending off the map reads d = 2 m.
    ll_off, _, _ = _fit(room, "likelihood_field", [5.0])
    assert ll_off == pytest.approx(math.log(0.95 * math.exp(-4.0 / 0.08) + 0.005), abs=1e-9)


def test_beam_model_matches_hand_values(room: Path) -> None:
    # Along +x the ray enters the wall cell at x = 3.9: expected range r* = 1.85 m. With
    # z_hit 0.5, z_short 0.05, z_max 0.05, z_rand 0.5 over 10 m, σ 0.2 m, λ 0.1:
    # 1.9 m (e = 0.05): 0.5 exp(−0.0025 / 0.08) + 0.05;
    # 1.45 m (e = −0.4, short): 0.5 exp(−2) + 0.05 · 0.1 exp(−0.145) + 0.05;
    # no return (z = z_max = 10, e = 8.15): 0.5 exp(−66.4225 / 0.08) + 0.05 (the max term);
    # 2.25 m (e = 0.4): 0.5 exp(−2) + 0.05.
    ll, _, n = _fit(room, "beam", [1.9, 1.45, math.inf, 2.25])
    p = [
        0.5 * math.exp(-0.0025 / 0.08) + 0.05,
        0.5 * math.exp(-2.0) + 0.005 * math.exp(-0.145) + 0.05,
        0.5 * math.exp(-66.4225 / 0.08) + 0.05,
        0.5 * math.exp(-2.0) + 0.05,
    ]
    assert n == 4
    assert ll == pytest.approx(sum(math.log(v) for v in p), abs=1e-9)
    # Along +y (θ = π/2) the same room gives the same expected range.
    ll_y, _, _ = _fit(room, "beam", [1.9], angles=[math.pi / 2])
    assert ll_y == pytest.approx(math.log(p[0]), abs=1e-9)


def test_model_parameters_are_checked(room: Path) -> None:
    with pytest.raises(ConfigError, match="model"):
        LocalizeConfig(model="amcl")
    with pytest.raises(ConfigError, match="lambda_short"):
        LocalizeConfig(model="likelihood_field", model_params=(("lambda_short", 0.1),))
    with pytest.raises(ConfigError, match="z_hit"):
        LocalizeConfig(model="crm", model_params=(("z_hit", 0.5),))
    m = load_localization_map(room, max_range=10.0)
    with pytest.raises(ConfigError, match="z_rand"):
        Localizer(m, LocalizeConfig(model="likelihood_field", model_params=(("z_rand", 0.0),)))
    # An override reaches the model: σ = 0.1 m instead of 0.2 m at d = 0.2 m.
    loc = Localizer(
        m,
        LocalizeConfig(model="likelihood_field", model_params=(("sigma_hit", 0.1),), max_range=10.0),
        initial_pose=[2.05, 2.05, 0.0],
        initial_cov=[0.01, 0.01, 0.01],
    )
    assert loc.filter is not None
    ll, _, _ = loc.filter.scan_fit(np.array([2.05, 2.05, 0.0]), np.zeros(1), np.array([1.7]), NO_OFFSET)
    assert ll == pytest.approx(math.log(0.95 * math.exp(-0.04 / 0.02) + 0.005), abs=1e-6)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_crm_likelihood_is_within_its_stated_error_of_the_exact_one(tmp_path: Path, seed: int) -> None:
    """A random map (a CRM updated with random scans from random poses: m̂ of every kind) and
    random scans (in range, short, no-returns) from random poses: the default model's log-likelihood
    is low by at most n_beams x tail_tolerance against crm-exact's, never high."""
    rng = np.random.default_rng(seed)
    crm = ConfidenceRichMap(MappingConfig(resolution=0.1, max_range=6.0))
    angles = np.linspace(-math.pi, math.pi, 90, endpoint=False)
    for _ in range(15):
        pose = np.array([rng.uniform(1, 5), rng.uniform(1, 4), rng.uniform(-math.pi, math.pi)])
        crm.update(pose, angles, np.where(rng.random(90) < 0.1, np.inf, rng.uniform(0.3, 5.0, 90)))
    save_belief(tmp_path / "belief.npz", crm.to_archive())
    m = load_localization_map(tmp_path / "belief.npz")
    start = {"initial_pose": [3.0, 2.5, 0.0], "initial_cov": [0.01, 0.01, 0.01]}
    exact = Localizer(m, LocalizeConfig(model="crm-exact", max_particles=10, min_particles=10), **start)
    tols = (1e-3, 1e-6)
    fast = [
        Localizer(m, LocalizeConfig(max_beams=0, tail_tolerance=t, max_particles=10, min_particles=10), **start) for t in tols
    ]
    assert exact.filter is not None
    for _ in range(20):
        sensor = np.array([rng.uniform(0, 6), rng.uniform(0, 5), rng.uniform(-math.pi, math.pi)])
        n = int(rng.integers(1, 120))
        a = np.sort(rng.uniform(-math.pi, math.pi, n))
        r = np.where(rng.random(n) < 0.15, np.inf, rng.uniform(0.05, 6.5, n))
        want, _, n_exact = exact.filter.scan_fit(sensor, a, r, NO_OFFSET)
        for t, loc in zip(tols, fast):
            assert loc.filter is not None
            got, _, n_fast = loc.filter.scan_fit(sensor, a, r, NO_OFFSET)
            assert n_fast == n_exact
            err = want - got
            assert -1e-9 < err <= n_fast * t + 1e-9, (t, err, n_fast)


@pytest.fixture(scope="module")
def lookalike(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """300 scans on a floor of three look-alike rooms each side of a corridor."""
    d = tmp_path_factory.mktemp("lookalike_models")
    lookalike_world(3).to_nav2_yaml(d / "floor.yaml")
    write_simulation(simulate(SimulationConfig(world=str(d / "floor.yaml"), n_scans=300, seed=1, sensor="sick")), d)
    return d


@pytest.mark.parametrize("model", ["crm", "likelihood_field", "beam"])
def test_global_localization_on_the_lookalike_floor_with_each_model(lookalike: Path, model: str) -> None:
    scans = list(read_scans(lookalike / "log.clf"))
    truth = read_tum(lookalike / "groundtruth.tum").poses
    m = load_localization_map(lookalike / "floor.yaml")
    cfg = LocalizeConfig(model=model, max_beams=45, max_particles=2000, min_particles=100, spread_particles=0, seed=2)
    loc = Localizer(m, cfg)
    for s in scans:
        loc.step(s.odom, s.angles, np.where(s.ranges >= s.max_range, np.inf, s.ranges), s.laser_offset, s.timestamp)
    conv = loc.convergence
    assert conv is not None, f"{model} never converged"
    _, est = loc.trajectory()
    d = between(truth, est)
    err = np.hypot(d[:, 0], d[:, 1])
    # Converged at the true room (the look-alike rooms are 4 m apart), and tracked it since.
    assert err[conv.scan_index] < 0.3 and err[conv.scan_index :].max() < 0.5, (model, conv, err.max())
    assert np.median(err[-40:]) < 0.1


def test_cli_model_flags(lookalike: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    truth = read_tum(lookalike / "groundtruth.tum").poses
    out = tmp_path / "run"
    args = ["localize", str(lookalike / "log.clf"), "--map", str(lookalike / "floor.yaml"), "--out", str(out), "--quiet"]
    args += ["--initial-pose", *(str(v) for v in truth[0]), "--max-scans", "20"]
    assert main(args + ["--model", "beam", "--model-param", "sigma_hit=0.1"]) == 0
    config = tomllib.loads((out / "config.toml").read_text())["localize"]
    assert config["model"] == "beam" and [list(p) for p in config["model_params"]] == [["sigma_hit", 0.1]]
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["measurement_model"] == "beam" and "AMCL" in metrics["likelihood_error"]
    assert main(args + ["--force", "--model", "crm-exact"]) == 0
    assert "to rounding" in json.loads((out / "metrics.json").read_text())["likelihood_error"]
    assert main(args + ["--force", "--model", "beam", "--model-param", "max_dist=1"]) == 2
    assert "max_dist" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(args + ["--force", "--model-param", "sigma_hit"])


@pytest.mark.parametrize("negate", [0, 1])
def test_a_nav2_maps_unknown_cells_take_the_confidence_the_user_sets(tmp_path: Path, negate: int) -> None:
    """The room with an unknown block 1 m east of the sensor: unknown cells read m̂ = 0.5 by
    default, which stops AMCL's beam model's ray (as AMCL's unknown cells do); with
    ``unknown_mean`` 0.3 (``--nav2-unknown 0.3``) the ray passes them and meets the wall."""
    occ = np.zeros((40, 40))
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = 1.0
    occ[15:25, 30:33] = np.nan
    yaml = write_nav2_map(tmp_path / "room.pgm", occ, resolution=0.1, origin=(0.0, 0.0), negate=negate)
    cfg = LocalizeConfig(model="beam", max_range=10.0, max_beams=0, max_particles=10, min_particles=10)
    fits = []
    for unknown in (0.5, 0.3):
        m = load_localization_map(yaml, nav2_prior=Nav2Prior(unknown_mean=unknown), max_range=10.0)
        loc = Localizer(m, cfg, initial_pose=[2.05, 2.05, 0.0], initial_cov=[0.01, 0.01, 0.01])
        assert loc.filter is not None
        fits.append(loc.filter.scan_fit(np.array([2.05, 2.05, 0.0]), np.zeros(1), np.array([1.0]), NO_OFFSET)[0])
    # The reading 1.0 m lies 0.05 m past the unknown block's entry at x = 3.0 (r* = 0.95 m) with
    # 0.5, and 0.85 m short of the wall (r* = 1.85 m) with 0.3.
    assert fits[0] == pytest.approx(math.log(0.5 * math.exp(-0.0025 / 0.08) + 0.05), abs=1e-6)
    short = 0.5 * math.exp(-(0.85**2) / 0.08) + 0.005 * math.exp(-0.1) + 0.05
    assert fits[1] == pytest.approx(math.log(short), abs=1e-6)


def test_bench_measures_each_model_in_the_same_run() -> None:
    """The speed figures of the four models and the CRM's ratio over each, per CPU second (the
    figures themselves are not judged here: speed belongs to the benchmark)."""
    from crlam.bench import run_benchmarks

    names = [
        "mcl_scans_per_s_1000p",
        "mcl_crm_exact_scans_per_s_1000p",
        "mcl_likelihood_field_scans_per_s_1000p",
        "mcl_beam_scans_per_s_1000p",
    ]
    r = run_benchmarks(names, quick=True, repeats=1)
    figures, details = r["figures"], r["details"]
    for other, label in zip(names[1:], ("crm_exact", "likelihood_field", "beam")):
        crm, base = details[names[0]], details[other]
        want = crm.get("per_cpu_second", figures[names[0]]) / base.get("per_cpu_second", figures[other])
        assert figures[f"mcl_crm_over_{label}"] == pytest.approx(want, rel=0.01, abs=0.001)
    assert "60 of 180 beams" in details[names[0]]["unit"] and "all 180 beams" in details[names[1]]["unit"]
