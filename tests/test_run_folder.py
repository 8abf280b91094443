"""The layout of a ``crlam slam`` run folder: the default trajectory sorted by time, the other
estimates under ``estimates/`` and a README.txt naming every file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from crlam.experiments.slam_run import ESTIMATES, run_slam_log
from crlam.io.tum import read_tum
from crlam.sim.simulate import SimulationConfig, simulate, write_simulation
from crlam.slam import SlamConfig


@pytest.fixture(scope="module")
def shuffled_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A simulated log whose 11th and 12th scans carry swapped timestamps (file order != time order)."""
    d = tmp_path_factory.mktemp("shuffled")
    write_simulation(simulate(SimulationConfig(world="office", n_scans=40, seed=3)), d)
    lines = (d / "log.clf").read_text().splitlines()
    scans = [i for i, ln in enumerate(lines) if ln.startswith("ROBOTLASER1")]
    a, b = scans[10], scans[11]
    ta, tb = lines[a].split(), lines[b].split()
    ta[-3], tb[-3] = tb[-3], ta[-3]  # the ipc timestamp
    lines[a], lines[b] = " ".join(ta), " ".join(tb)
    (d / "log.clf").write_text("\n".join(lines) + "\n")
    return d / "log.clf"


def test_every_trajectory_is_sorted_by_time_and_holds_the_filter_estimate(shuffled_log: Path, tmp_path: Path) -> None:
    cfg = SlamConfig(particles=4, seed=0, proposal="likelihood_mode", linear_update=0.2, angular_update=0.1)
    res = run_slam_log(shuffled_log, tmp_path, cfg, progress=False, figures=False)
    stamps, poses = res.run.trajectory()
    assert not np.all(np.diff(stamps) >= 0), "the fixture must have a stamp out of order"
    traj = read_tum(tmp_path / "trajectory.tum")
    assert np.all(np.diff(traj.timestamps) > 0)
    order = np.argsort(stamps, kind="stable")
    np.testing.assert_allclose(traj.timestamps, stamps[order], atol=1e-9)
    np.testing.assert_allclose(traj.poses[:, :2], poses[order, :2], atol=1e-8)
    for rel in ("estimates/best_path.tum", "estimates/max_weight.tum", "estimates/mode.tum", "estimates/smoothed.tum"):
        est = read_tum(tmp_path / rel)
        np.testing.assert_array_equal(est.timestamps, traj.timestamps)
    # The proposal is fitted: the best path's proposal means are recorded too.
    assert (tmp_path / "estimates" / "best_path_means.tum").is_file()
    assert sorted(p.name for p in tmp_path.glob("trajectory*")) == ["trajectory.tum"]


def test_the_readme_names_every_file_of_the_run_folder(shuffled_log: Path, tmp_path: Path) -> None:
    run_slam_log(shuffled_log, tmp_path, SlamConfig(particles=3, seed=1), progress=False, max_scans=20)
    readme = (tmp_path / "README.txt").read_text()
    files = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.is_file() and p.name != "README.txt")
    named = {tok.rstrip(",") for line in readme.splitlines() for tok in line.split()[:2]}
    assert set(files) <= named, set(files) - named
    # One line per trajectory file, and the default is the one to use.
    for rel in files:
        if rel.endswith(".tum"):
            assert rel in ESTIMATES
    assert "use this one" in next(line for line in readme.splitlines() if line.startswith("trajectory.tum"))


@pytest.mark.parametrize("method", ["clam", "ogm"])
def test_a_finished_command_frees_the_particle_maps_before_its_figures(shuffled_log: Path, tmp_path: Path, method: str) -> None:
    """``run_slam_log`` ends the run: once the map files are written the particles' maps are
    freed (the figures then do not stack on the filter's memory), the trajectories stay readable
    and the filter refuses further scans with a clear error."""
    from crlam.errors import ConfigError

    cfg = SlamConfig(method=method, particles=3, seed=1, loop_closing="off")
    res = run_slam_log(shuffled_log, tmp_path, cfg, progress=False, max_scans=20, figures=False)
    assert (tmp_path / "map.pgm").is_file()
    filt = res.run.filter
    assert filt is not None and filt.maps_released
    assert filt.map_memory()[0] == 0
    assert res.run.trajectory()[1].shape == (20, 3)
    assert res.run.best_path_trajectory()[1].shape == (20, 3)
    with pytest.raises(ConfigError, match="released"):
        res.run.best_map()
    z = np.ones(8)
    with pytest.raises(ConfigError, match="released"):
        filt.process(np.zeros(3), np.linspace(-1, 1, 8), z, np.zeros(3))


def test_saving_a_run_that_goes_on_keeps_its_maps(shuffled_log: Path, tmp_path: Path) -> None:
    """The live node's save path (``write_slam_outputs``) writes the folder and keeps mapping."""
    from crlam.experiments.slam_outputs import write_slam_outputs
    from crlam.io.carmen_types import LaserScan
    from crlam.io.logs import open_log
    from crlam.slam import SlamRun

    run = SlamRun(SlamConfig(particles=3, seed=1, loop_closing="off"))
    scans = [r for r in open_log(shuffled_log) if isinstance(r, LaserScan)]
    for rec in scans[:15]:
        run.step(rec.odom, rec.angles, np.minimum(rec.ranges, 7.9), rec.laser_offset, rec.timestamp)
    write_slam_outputs(run, 1.0, tmp_path, source="test", input_info={}, figures=False)
    assert (tmp_path / "metrics.json").is_file()
    assert run.filter is not None and not run.filter.maps_released
    rec = scans[15]
    run.step(rec.odom, rec.angles, np.minimum(rec.ranges, 7.9), rec.laser_offset, rec.timestamp)
    assert run.n_scans == 16
