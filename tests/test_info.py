"""The information functions through the Python API and ``crlam info`` (crm-spec 5-6, planner-spec 4-5)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from crlam import _native
from crlam.cli import main
from crlam.errors import ConfigError, CrlamError, DataFormatError
from crlam.info import FUNCTION_NAMES, compute_surface, lattice_from_obstacles, load_map_prior, make_function
from crlam.io.nav2 import write_pgm


def small_prior(n: int = 40):
    """A 8 m x 8 m room (0.2 m nodes) with a wall and a pillar."""
    obstacle = np.zeros((n + 1, n + 1), dtype=bool)
    obstacle[0, :] = obstacle[-1, :] = obstacle[:, 0] = obstacle[:, -1] = True
    obstacle[20, 5:25] = True
    obstacle[30:33, 30:33] = True
    return lattice_from_obstacles(obstacle, None, 0.2, (0.0, 0.0))


@pytest.mark.parametrize("name", FUNCTION_NAMES)
def test_every_function_is_pure_batched_and_commits(name: str) -> None:
    prior = small_prior()
    f = make_function(name, n_particles=30)
    state = f.make_state(prior.lattice)
    poses = np.column_stack([prior.node_positions(prior.free)[::97], np.zeros(len(prior.node_positions(prior.free)[::97]))])
    g = f.gains(state, poses, seed=3)
    assert g.shape == (len(poses),) and np.all(np.isfinite(g))
    if name != "ucrmi":  # UCRMI's pose term may be negative (crm-spec 6.3)
        assert np.all(g >= 0.0)
    # The batch equals the serial evaluation with each candidate's stream.
    for i in (0, len(poses) - 1):
        seed = _native.candidate_seed(3, i)
        e = f.evaluate(state, poses[i], belief=None, seed=seed)
        if name == "ucrmi":
            root = f.root_belief(poses[i], seed)
            e = f.evaluate(state, poses[i], belief=root, seed=seed)
        assert e.gain == pytest.approx(g[i], rel=0, abs=0)
    # Evaluate is pure; commit changes the state.
    again = f.gains(state, poses, seed=3)
    np.testing.assert_array_equal(g, again)
    e = f.evaluate(state, poses[0])
    f.commit(state, e)
    after = f.gains(state, poses[:1], seed=3)
    assert after[0] != g[0] or e.update.summary()[0] == 0
    assert f.units == ("bits" if name in ("crmi", "ucrmi") else "nats")


def test_repeat_evaluation_gains_less_for_the_parity_functions() -> None:
    # planner-spec 9.1 item 13 for the functions it names (MI-parity, GPVR, UGPVR).
    prior = small_prior()
    for name in ("iig_mi", "gpvr", "ugpvr"):
        f = make_function(name, mode="reference")
        state = f.make_state(prior.lattice)
        p = np.array([4.1, 2.1, 0.0])
        e1 = f.evaluate(state, p)
        f.commit(state, e1)
        e2 = f.evaluate(state, p)
        assert e2.gain <= e1.gain
        if e1.gain > 0:
            assert e2.gain < e1.gain, name


def test_fsmi_matches_julian_integration_through_the_api() -> None:
    prior = small_prior()
    exact = make_function("fsmi")
    julian = make_function("ogmi", julian_points_per_cell=400)
    poses = prior.node_positions(prior.free)[::53]
    a = exact.gains(exact.make_state(prior.lattice), poses)
    b = julian.gains(julian.make_state(prior.lattice), poses)
    np.testing.assert_allclose(a, b, rtol=1e-4)


def test_crmi_is_orientation_invariant_and_zero_on_a_known_map() -> None:
    prior = small_prior()
    f = make_function("crmi")
    state = f.make_state(prior.lattice)
    p = np.array([3.05, 5.13, 0.4])
    a = f.evaluate(state, p).gain
    b = f.evaluate(state, p + [0.0, 0.0, 2 * math.pi / 10]).gain
    assert a == pytest.approx(b, rel=1e-9)
    known = _native.OccupancyLattice(np.where(prior.obstacle, 1.0, 0.0), prior.lattice.resolution, prior.lattice.origin)
    # Tilted pmfs cannot reach 0/1: clamped means 0.06/0.94 keep a little entropy; one-hot
    # beliefs (the Rust test) give exactly 0. Here the gain must be far below the prior's.
    assert f.evaluate(f.make_state(known), p).gain < 0.5 * a


def test_ucrmi_alpha_extremes_and_belief_propagation() -> None:
    prior = small_prior()
    f1 = make_function("ucrmi", alpha=1.0, n_particles=50)
    f0 = make_function("ucrmi", alpha=0.0, n_particles=50)
    crmi = make_function("crmi")
    state = f1.make_state(prior.lattice)
    root = f1.root_belief([2.0, 2.0, 0.0], seed=1)
    assert root.particles.shape == (50, 3)
    e1 = f1.evaluate(state, [3.0, 2.0], parent=[2.0, 2.0], belief=root, seed=5)
    assert e1.gain == pytest.approx(crmi.evaluate(state, [3.0, 2.0]).gain, abs=1e-12)
    e0 = f0.evaluate(state, [3.0, 2.0], parent=[2.0, 2.0], belief=root, seed=5)
    assert e0.gain == pytest.approx(e0.belief.pose_gain_bits, abs=1e-12)
    cov = np.array(e0.belief.position_covariance())
    assert cov.shape == (2, 2) and cov[0, 0] > 0


def test_ugpvr_carries_a_growing_covariance() -> None:
    prior = small_prior()
    f = make_function("ugpvr", mode="reference")
    state = f.make_state(prior.lattice)
    root = f.root_belief([2.0, 2.0, 0.0])
    e = f.evaluate(state, [4.0, 2.0], parent=[2.0, 2.0], belief=root)
    c = np.asarray(e.belief)
    assert c.shape == (3, 3)
    assert c[0, 0] > np.asarray(root)[0, 0] and c[1, 1] > np.asarray(root)[1, 1]


def test_surface_covers_the_free_cells(tmp_path: Path) -> None:
    prior = small_prior()
    f = make_function("crmi")
    s = compute_surface(f, f.make_state(prior.lattice), prior)
    assert np.all(np.isfinite(s.values[prior.free]))
    assert np.all(np.isnan(s.values[~prior.free]))
    summary = s.summary()
    assert summary["n_poses"] == int(prior.free.sum()) and summary["units"] == "bits"
    assert summary["min"] >= 0 and summary["max"] > summary["min"]


def write_room_pgm(path: Path) -> None:
    img = np.full((30, 40), 255, dtype=np.uint8)
    img[10:12, 5:30] = 0
    img[20:25, 30:33] = 0
    write_pgm(path, img)


@pytest.mark.parametrize("name", ["crmi", "fsmi", "gpvr", "ucrmi"])
def test_cli_info_writes_surface_figure_and_json(tmp_path: Path, name: str) -> None:
    pgm = tmp_path / "room.pgm"
    write_room_pgm(pgm)
    out = tmp_path / name
    args = [str(pgm), "--function", name, "--out", str(out)]
    if name == "ucrmi":
        args += ["--ucrmi-particles", "20"]
    assert main(["info", *args]) == 0
    surface = np.load(out / "surface.npy")
    info = json.loads((out / "info.json").read_text())
    assert info["function"] == name and info["n_poses"] == int(np.isfinite(surface).sum())
    assert (out / "surface.png").stat().st_size > 10_000
    # The lattice is the map plus its border walls and a 1 m margin: 30 + 1 + 10 rows.
    assert surface.shape == (41, 51)


def test_cli_info_from_a_belief(tmp_path: Path) -> None:
    from crlam.io.belief import save_belief
    from crlam.mapping import ConfidenceRichMap, MappingConfig

    crm = ConfidenceRichMap(MappingConfig(resolution=0.2, max_range=5.0, extent=(0.0, 0.0, 8.0, 8.0)))
    angles = np.linspace(-np.pi, np.pi, 180, endpoint=False)
    for _ in range(5):
        crm.update([4.0, 4.0, 0.0], angles, np.full(180, 3.0))
    save_belief(tmp_path / "belief.npz", crm.to_archive())
    for name in ("crmi", "fsmi"):
        assert main(["info", "--belief", str(tmp_path / "belief.npz"), "--function", name, "--out", str(tmp_path / name)]) == 0
        s = np.load(tmp_path / name / "surface.npy")
        assert np.isfinite(s).sum() > 100


def test_cli_info_refuses_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", str(tmp_path / "missing.pgm"), "--function", "crmi", "--out", str(tmp_path / "o")]) == 2
    assert "missing.pgm: no such file or folder, and not a dataset name" in capsys.readouterr().err
    (tmp_path / "bad.txt").write_text("x")
    assert main(["info", str(tmp_path / "bad.txt"), "--function", "crmi", "--out", str(tmp_path / "o")]) == 2
    assert main(["info", "--function", "crmi", "--out", str(tmp_path / "o")]) == 2
    with pytest.raises(DataFormatError):
        load_map_prior(tmp_path / "bad.txt")


def test_bad_settings_raise_config_errors() -> None:
    with pytest.raises(ConfigError):
        make_function("nope")
    with pytest.raises(CrlamError):
        make_function("ucrmi", alpha=2.0)
    with pytest.raises(CrlamError):
        make_function("crmi", lambda_z=-1.0)
    f = make_function("crmi")
    with pytest.raises(ConfigError):
        f.gains(f.make_state(small_prior().lattice), np.zeros((3, 4)))
    with pytest.raises(TypeError):
        f.gains(_native.OccupancyLattice(np.full((5, 5), 0.3), 0.2), np.zeros((3, 3)))


def test_cave_prior_matches_the_planner_lattice(data_dir: Path) -> None:
    prior = load_map_prior(data_dir / "maps" / "cave.pgm")
    assert prior.lattice.shape == (111, 111)
    assert prior.lattice.origin == pytest.approx((-1.1, -1.1))
    p = prior.lattice.probabilities()
    assert set(np.unique(p)) == {0.3, 0.85}
    # 2,356 obstacle pixels (planner-spec 8) plus the 400 border points, minus the pixels of the
    # left column and bottom row, whose lower-left corners are border points already.
    from crlam.io.nav2 import read_pgm

    img = read_pgm(data_dir / "maps" / "cave.pgm") < 128
    assert int(img.sum()) == 2356
    on_border = int(img[:, 0].sum() + img[-1, :].sum() - img[-1, 0])
    assert int((p == 0.85).sum()) == 2356 + 400 - on_border
    # Every pixel of the border walls and nothing in the 1 m margin.
    assert np.all(p[:5] == 0.3) and np.all(p[5, 5:106] == 0.85)


@pytest.mark.parametrize("variant", ["ml_scan_binary", "r1_map"])
def test_authors_crmi_variants_run_through_the_api(variant: str) -> None:
    prior = small_prior()
    f = make_function("crmi", crmi_variant=variant)
    assert f.settings["variant"] == variant and f.units == "bits"
    state = f.make_state(prior.lattice)
    poses = prior.node_positions(prior.free)[::41]
    g = f.gains(state, poses)
    assert np.all(np.isfinite(g)) and g.max() > 0
    e = f.evaluate(state, poses[0])
    assert e.update.kind == "virtual_scan"
    with pytest.raises(CrlamError):
        make_function("crmi", crmi_variant="nope")
