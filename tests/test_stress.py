"""Stress variants of a log and ``crlam experiment stress`` on a short simulated log."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from crlam.errors import ConfigError
from crlam.experiments.stress_variants import (
    STRESS_VARIANTS,
    StressSettings,
    build_variant,
    load_records,
    reference_headings,
    write_variant,
)
from crlam.io.carmen_types import CarmenRecord, LaserScan, OdometryReading
from crlam.pose import transform_points

N_SCANS = 300


@pytest.fixture(scope="module")
def sim(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A simulated log (office world, SICK-like laser, 300 scans at 10 Hz) and its ground truth."""
    from crlam.sim.simulate import SimulationConfig, simulate, write_simulation

    out = tmp_path_factory.mktemp("sim")
    write_simulation(simulate(SimulationConfig(world="office", n_scans=N_SCANS, sensor="sick", seed=0)), out)
    return out


@pytest.fixture(scope="module")
def records(sim: Path) -> list[CarmenRecord]:
    return load_records(sim / "log.clf")


def _scans(records: list[CarmenRecord]) -> list[LaserScan]:
    return [r for r in records if isinstance(r, LaserScan)]


def _endpoints(scan: LaserScan) -> np.ndarray:
    """Hit endpoints (k, 2) in the robot frame."""
    hit = scan.ranges < scan.max_range
    a, r = scan.angles[hit], scan.ranges[hit]
    pts = np.stack([r * np.cos(a), r * np.sin(a)], axis=1)
    return transform_points(scan.laser_offset, pts)


def test_every_variant_keeps_the_scans_and_their_stamps(records: list[CarmenRecord], tmp_path: Path) -> None:
    original = _scans(records)
    for v in ("none", *STRESS_VARIANTS):
        out = build_variant(records, v)
        scans = _scans(out)
        assert [s.timestamp for s in scans] == [s.timestamp for s in original], v
        assert sum(isinstance(r, OdometryReading) for r in out) == len(scans), v
        # Written and read back: the same scans (CARMEN's 0.1 mm / 1e-6 rad precision).
        back = _scans(load_records(write_variant(out, tmp_path / f"{v}.clf.gz", v)))
        assert len(back) == len(scans)
        assert np.allclose(back[7].ranges, scans[7].ranges, atol=1e-4)
        assert np.allclose(back[7].angles, scans[7].angles, atol=1e-6)
        assert np.allclose(back[7].odom, scans[7].odom, atol=1e-4)


def test_half_beams_and_no_returns(records: list[CarmenRecord]) -> None:
    original = _scans(records)
    half = _scans(build_variant(records, "half_beams"))
    assert half[0].n_beams == original[0].n_beams // 2
    assert np.allclose(half[0].angles, original[0].angles[::2])
    assert np.array_equal(half[0].ranges, original[0].ranges[::2])
    nr = _scans(build_variant(records, "no_returns", StressSettings(no_return_fraction=0.1, seed=3)))
    made = sum(int(np.sum((b.ranges >= b.max_range) & (a.ranges < a.max_range))) for a, b in zip(original, nr, strict=True))
    hits = sum(int(np.sum(a.ranges < a.max_range)) for a in original)
    assert 0.08 < made / hits < 0.12
    assert all(np.all((b.ranges == a.ranges) | (b.ranges >= b.max_range)) for a, b in zip(original, nr, strict=True))


def test_mount_variants_turn_and_mirror_the_endpoints(records: list[CarmenRecord]) -> None:
    scan = _scans(records)[10]
    yaw = _scans(build_variant(records, "mount_yaw"))[10]
    flip = _scans(build_variant(records, "mount_flip"))[10]
    p = _endpoints(scan)
    # A laser turned by pi, read as if it faced forward: every endpoint turned by pi about the laser.
    assert np.allclose(_endpoints(yaw), -p, atol=1e-9)
    # Upside down: every endpoint mirrored about the laser's forward axis.
    assert np.allclose(_endpoints(flip)[::-1], p * np.array([1.0, -1.0]), atol=1e-9)
    assert np.array_equal(yaw.laser_offset, scan.laser_offset) and np.array_equal(flip.laser_offset, scan.laser_offset)


def test_odom_shift_attaches_the_earlier_odometry(records: list[CarmenRecord]) -> None:
    from crlam.experiments.stress_variants import odometry_series
    from crlam.slam.time_offset import interpolate_pose

    original = _scans(records)
    out = build_variant(records, "odom_shift", StressSettings(odom_shift_s=0.15))
    odo = [r for r in out if isinstance(r, OdometryReading)]
    scans = _scans(out)
    t, p = odometry_series(original)
    k = 50
    assert odo[k].timestamp == pytest.approx(original[k].timestamp + 0.15)
    assert np.allclose(odo[k].pose, original[k].odom)
    assert np.allclose(scans[k].odom, interpolate_pose(t, p, original[k].timestamp - 0.15))


def test_turn_heading_triples_the_heading_error_in_turns(records: list[CarmenRecord]) -> None:
    original = _scans(records)
    out = _scans(build_variant(records, "turn_heading"))
    ref = reference_headings(original)
    turning = straight = 0
    for k in range(1, len(original)):
        d_old = math.remainder(original[k].odom[2] - original[k - 1].odom[2], 2 * math.pi)
        d_new = math.remainder(out[k].odom[2] - out[k - 1].odom[2], 2 * math.pi)
        d_ref = ref[k] - ref[k - 1]
        dt = original[k].timestamp - original[k - 1].timestamp
        if abs(d_ref) / dt > 0.2:
            turning += 1
            assert d_new - d_ref == pytest.approx(3.0 * (d_old - d_ref), abs=1e-9)
        else:
            straight += 1
            assert d_new == pytest.approx(d_old, abs=1e-9)
    assert turning > 10 and straight > 10


def test_unknown_variant_and_bad_settings() -> None:
    with pytest.raises(ConfigError, match="unknown stress variant"):
        build_variant([], "sideways")
    with pytest.raises(ConfigError):
        StressSettings(no_return_fraction=1.5)


def test_stress_experiment_runs_resumes_and_tables(sim: Path, tmp_path: Path) -> None:
    from crlam.experiments.stress import run_stress
    from crlam.slam import SlamConfig

    base = SlamConfig.from_preset(particles=4)
    out = tmp_path / "stress"
    kwargs = dict(reference=sim / "groundtruth.tum", seeds=1, base=base, max_scans=120, workers=1, progress=False)
    res = run_stress(sim / "log.clf", out, **kwargs)  # type: ignore[arg-type]
    assert not res.errors
    assert [r["variant"] for r in res.rows] == ["none", *STRESS_VARIANTS]
    for r in res.rows:
        assert r["seeds_done"] == 1 and np.isfinite(r["mean_m"])
        assert (r["passes"] is None) == (r["variant"] == "none")
        assert r["passes"] == (r["variant"] == "none" or r["worst_m"] <= 1.5 * res.rows[0]["mean_m"]) or r["passes"] is None
    table = (out / "table.md").read_text()
    assert "| odom_shift |" in table and "| mount_flip |" in table
    assert (out / "COMPLETE").is_file()
    metrics = json.loads((out / "runs" / "odom_shift_seed0" / "metrics.json").read_text())
    assert metrics["n_scans"] == 120 and "time_offset" in metrics
    # Resumed: nothing is run again (the finished runs' files are untouched), the table is the same.
    before = (out / "runs" / "none_seed0" / "metrics.json").stat().st_mtime_ns
    again = run_stress(sim / "log.clf", out, **kwargs)  # type: ignore[arg-type]
    assert (out / "runs" / "none_seed0" / "metrics.json").stat().st_mtime_ns == before
    assert [r["errors_m"] for r in again.rows] == [r["errors_m"] for r in res.rows]
    # Other settings in the same folder are refused.
    with pytest.raises(ConfigError, match="other settings"):
        run_stress(sim / "log.clf", out, **{**kwargs, "settings": StressSettings(odom_shift_s=0.3)})  # type: ignore[arg-type]
