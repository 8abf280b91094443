"""Golden-file regression of whole SLAM runs: both filters on a short simulated log must give the
trajectories stored in ``tests/golden/``.

The runs are deterministic (seeded simulator, per-particle random streams), so any change to the
numbers of the map update, the likelihoods, the motion models, the proposals or resampling shows
here. A change that is meant to alter results regenerates the files, and the commit says why::

    python tests/test_golden.py

The tolerance (1e-6 m / rad) absorbs last-bit differences between libm implementations; a
change in behaviour moves poses by far more.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from crlam.experiments.slam_run import run_slam_log
from crlam.io.tum import read_tum, write_tum
from crlam.sim.simulate import SimulationConfig, simulate, write_simulation
from crlam.slam import SlamConfig

GOLDEN = Path(__file__).resolve().parent / "golden"
METHODS = ("clam", "ogm")


def _golden_run(method: str, work: Path) -> tuple[np.ndarray, np.ndarray]:
    """(stamps, poses N x 3) of the fixed run of `method` on a 150-scan office log."""
    log_dir = work / "office"
    if not (log_dir / "log.clf").exists():
        write_simulation(simulate(SimulationConfig(world="office", n_scans=150, seed=4)), log_dir)
    out = work / method
    run_slam_log(log_dir / "log.clf", out, SlamConfig(method=method, particles=8, seed=3), progress=False, figures=False)
    traj = read_tum(out / "trajectory.tum")
    return traj.timestamps, traj.poses


@pytest.mark.parametrize("method", METHODS)
def test_slam_run_matches_the_golden_trajectory(method: str, tmp_path: Path) -> None:
    want = read_tum(GOLDEN / f"slam_office_{method}.tum")
    stamps, poses = _golden_run(method, tmp_path)
    np.testing.assert_array_equal(stamps, want.timestamps)
    assert poses.shape == want.poses.shape
    np.testing.assert_allclose(poses[:, :2], want.poses[:, :2], rtol=0, atol=1e-6)
    dtheta = np.angle(np.exp(1j * (poses[:, 2] - want.poses[:, 2])))
    np.testing.assert_allclose(dtheta, 0.0, rtol=0, atol=1e-6)
    # The runs must actually move: a golden file of a stuck filter would prove nothing.
    assert np.ptp(poses[:, 0]) + np.ptp(poses[:, 1]) > 1.0


def _regenerate() -> None:
    import tempfile

    GOLDEN.mkdir(exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        for method in METHODS:
            stamps, poses = _golden_run(method, Path(tmp))
            path = GOLDEN / f"slam_office_{method}.tum"
            write_tum(path, stamps, poses, header=f"golden run: office 150 scans seed 4, {method}, 8 particles, seed 3")
            print(f"wrote {path} ({len(stamps)} poses)", file=sys.stderr)


if __name__ == "__main__":
    _regenerate()
