"""Real-lidar readings: the no-return policy, body beams and the laser mount (crlam.io.readings,
crlam.preflight.body_mask, crlam.preflight.laser_mount, crlam.preflight.lidar_check)."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from crlam.cli import main
from crlam.io.carmen import read_scans
from crlam.io.carmen_types import LaserScan
from crlam.io.readings import ReadingFilter
from crlam.io.rosbag import RosbagReader
from crlam.io.rosbag_writer import McapBagWriter
from crlam.mapping import ConfidenceRichMap, MappingConfig
from crlam.preflight.lidar_check import LidarSetup, check_lidar
from crlam.slam import SlamConfig


@pytest.fixture(scope="module")
def sim(tmp_path_factory: pytest.TempPathFactory) -> list[LaserScan]:
    """A simulated log's scans (office world, SICK-like laser, 600 scans at 10 Hz)."""
    out = tmp_path_factory.mktemp("sim")
    argv = ["simulate", "--scans", "600", "--world", "office", "--sensor", "sick", "--out", str(out), "--quiet", "--seed", "3"]
    assert main(argv) == 0
    return list(read_scans(out / "log.clf"))


# -- the no-return policy ------------------------------------------------------------------------


def _bag_with_every_kind(path: Path) -> Path:
    """A bag of one scan: a hit, +inf, NaN, 0, a reading below range_min, one at range_max and
    one above it, then a hit (range_min 0.1 m, range_max 10 m)."""
    ranges = np.array([2.0, np.inf, np.nan, 0.0, 0.05, 10.0, 12.0, 3.0], dtype=np.float32)
    with McapBagWriter(path) as w:
        T = w.types
        w.write(
            "/tf_static", "tf2_msgs/msg/TFMessage", 0, w.tf([w.transform(0.0, "base_link", "laser", [0, 0, 0])]), latched=True
        )
        for k, t in enumerate((1.0, 1.1)):
            w.write("/odom", "nav_msgs/msg/Odometry", int(t * 1e9), w.odometry(t, "odom", "base_link", [0.0, 0.0, 0.0]))
            if k == 0:
                msg = T["sensor_msgs/msg/LaserScan"](
                    header=w.header(1.05, "laser"),
                    angle_min=-0.35,
                    angle_max=0.35,
                    angle_increment=0.1,
                    time_increment=0.0,
                    scan_time=0.0,
                    range_min=0.1,
                    range_max=10.0,
                    ranges=ranges,
                    intensities=np.zeros(0, dtype=np.float32),
                )
                w.write("/scan", "sensor_msgs/msg/LaserScan", int(1.05e9), msg)
    return path


def test_every_kind_of_non_reading_follows_the_policy(tmp_path: Path) -> None:
    bag = _bag_with_every_kind(tmp_path / "kinds")
    reader = RosbagReader(bag)
    scan = next(r for r in reader if isinstance(r, LaserScan))
    st = reader.stats
    assert (st.n_inf_ranges, st.n_nan_ranges, st.n_nonpositive_ranges, st.n_below_min_ranges, st.n_above_max_ranges) == (
        1,
        1,
        1,
        1,
        1,
    )
    # drop (robust): only the two hits reach the filter, at their bearings.
    drop = ReadingFilter("drop", 8.0)
    angles, ranges = drop.apply(scan.angles, scan.ranges, scan.max_range)
    np.testing.assert_allclose(ranges, [2.0, 3.0])
    np.testing.assert_allclose(angles, [-0.35, 0.35], atol=1e-6)
    assert drop.stats.n_no_return == drop.stats.n_no_return_dropped == 6
    # z_max (paper): every non-reading is the z_max atom (inf for the filter), none left out.
    zmax = ReadingFilter("z_max", 8.0)
    angles, ranges = zmax.apply(scan.angles, scan.ranges, scan.max_range)
    assert len(ranges) == 8 and np.isinf(ranges[1:7]).all() and ranges[0] == 2.0 and ranges[7] == 3.0
    assert zmax.stats.n_no_return_z_max == 6


def test_carmen_non_readings_and_fixed_no_return_value() -> None:
    f = ReadingFilter("drop", 8.0)
    angles = np.radians([-10.0, 0.0, 10.0, 20.0, 30.0])
    # NaN and 0 (the CARMEN reader turns them into max_range too), 81 m, a 50 m laser maximum
    # (the log's largest reading so far: its fixed "nothing seen" value), a real 12 m return.
    a, r = f.apply(angles, np.array([np.nan, 0.0, 81.0, 50.0, 2.0]), 81.0)
    np.testing.assert_allclose(r, [2.0])
    a, r = f.apply(angles, np.array([50.0, 12.0, 3.0, 50.02, 81.5]), 81.0)
    np.testing.assert_allclose(r, [12.0, 3.0])  # 12 m returned: kept (it clears to z_max)
    np.testing.assert_allclose(a, np.radians([0.0, 10.0]))
    assert f.stats.n_fixed_value_no_return == 3


def test_returns_beyond_z_max_stay_in_both_policies() -> None:
    for policy in ("drop", "z_max"):
        f = ReadingFilter(policy, 8.0)
        f.apply(np.zeros(1), np.array([30.0]), 81.0)  # the log's largest so far
        _, r = f.apply(np.zeros(2), np.array([12.0, 4.0]), 81.0)
        np.testing.assert_allclose(r, [12.0, 4.0])


def test_presets_state_the_policy() -> None:
    assert SlamConfig.from_preset("robust").no_return == "drop"
    assert SlamConfig.from_preset("robust").body_mask == "auto"
    assert SlamConfig.from_preset("paper").no_return == "z_max"
    assert SlamConfig.from_preset("paper").body_mask == "off"
    with pytest.raises(Exception, match="no_return"):
        SlamConfig(no_return="clear")


def _wall_map(policy: str) -> tuple[ConfidenceRichMap, list[tuple[int, int]]]:
    """A wall at x = 3 m mapped from hits (30 scans), then 60 scans from other places whose
    every beam is a no-return through it, filtered by ``policy``."""
    m = ConfidenceRichMap(MappingConfig(resolution=0.1, max_range=8.0, hits_first=True))
    angles = np.radians(np.linspace(-30.0, 30.0, 61))
    for k in range(30):
        pose = np.array([0.0, 0.02 * (k % 5), 0.0])
        m.update(pose, angles, 3.0 / np.cos(angles))
    cells = sorted({tuple(int(v) for v in m.native.cell_of(3.05, y)) for y in np.linspace(-1.0, 1.0, 11)})
    f = ReadingFilter(policy, 8.0)
    for k in range(60):
        pose = np.array([0.5 + 0.03 * (k % 10), -0.3 + 0.01 * k, 0.05 * math.sin(k)])
        a, r = f.apply(angles, np.full(angles.size, np.inf), 8.0)
        if len(r):
            m.update(pose, a, r)
    return m, cells


def test_no_returns_never_clear_a_mapped_wall() -> None:
    m, cells = _wall_map("drop")
    means = [m.native.mean_at(ix, iy) for ix, iy in cells]
    assert min(means) > 0.5, means
    # The paper's policy clears them (the test can fail).
    m, cells = _wall_map("z_max")
    assert max(m.native.mean_at(ix, iy) for ix, iy in cells) < 0.5


# -- body beams ----------------------------------------------------------------------------------


def _with_body(scans: list[LaserScan], beams: np.ndarray, seed: int = 0) -> list[LaserScan]:
    rng = np.random.default_rng(seed)
    out = []
    for s in scans:
        r = s.ranges.copy()
        r[beams] = 0.155 + rng.uniform(-0.005, 0.005, beams.size)
        out.append(replace(s, ranges=r))
    return out


def test_body_beams_are_found_and_masked(sim: list[LaserScan]) -> None:
    beams = np.r_[0:5, 88:92, 175:180]
    setup = check_lidar(_with_body(sim, beams), "data", "auto", warn=False)
    assert setup.body is not None and setup.body.decided
    np.testing.assert_array_equal(np.flatnonzero(setup.body.mask), beams)
    np.testing.assert_allclose(setup.body.ranges, 0.155, atol=0.01)
    rec = setup.record()["body_mask"]
    assert rec["n_masked"] == beams.size and rec["beams"] == beams.tolist()
    mask = setup.body_mask_for_scans()
    f = ReadingFilter("drop", 8.0, mask)
    s = _with_body(sim, beams)[0]
    _, r = f.apply(s.angles, s.ranges, s.max_range)
    assert f.stats.n_body_masked == beams.size and not np.any(np.abs(r - 0.155) < 0.011)


def test_no_body_mask_on_clean_scans_or_without_motion(sim: list[LaserScan]) -> None:
    setup = check_lidar(sim, "data", "auto", warn=False)
    assert setup.body is not None and setup.body.decided and setup.body.n_masked == 0
    still = [replace(s, odom=sim[0].odom.copy()) for s in _with_body(sim, np.arange(3))[:100]]
    setup = check_lidar(still, "data", "auto", warn=False)
    assert setup.body is not None and not setup.body.decided and setup.body.n_masked == 0


# -- the laser mount -----------------------------------------------------------------------------


def _mounted(scans: list[LaserScan], yaw: float, flip: bool) -> list[LaserScan]:
    """The scans as a laser turned by ``yaw`` (and upside down) would read them, with the data
    stating no mount (offset 0)."""
    out = []
    for s in scans:
        base_bearings = s.angles
        read = (base_bearings - yaw) * (-1.0 if flip else 1.0)
        order = np.argsort(read)
        read, ranges = read[order], s.ranges[order]
        amin = math.remainder(float(read[0]), math.tau)
        out.append(replace(s, ranges=ranges, angle_min=amin, laser_offset=np.zeros(3)))
    return out


@pytest.mark.slow
@pytest.mark.parametrize(("yaw_deg", "flip"), [(0.0, False), (180.0, True), (90.0, False), (270.0, True), (30.0, False)])
def test_mount_detected_on_simulated_scans(sim: list[LaserScan], yaw_deg: float, flip: bool) -> None:
    scans = _mounted(sim, math.radians(yaw_deg), flip)
    setup = check_lidar(scans, "auto", "off", warn=False)
    est = setup.mount
    assert est is not None and est.decided, est
    assert est.flip is flip
    assert est.yaw is not None and abs(math.remainder(est.yaw - math.radians(yaw_deg), math.tau)) < math.radians(3.0)
    if yaw_deg == 0.0 and not flip:
        assert setup.correction is None
        return
    assert setup.correction is not None
    # The corrected scans' beams point where the original ones did (base frame), with their ranges.
    fixed = setup.correct(scans[10])
    base = fixed.angles + fixed.laser_offset[2]
    for j in (20, 45, 90, 150):
        gap = np.abs(np.angle(np.exp(1j * (base - sim[10].angles[j]))))
        i = int(np.argmin(gap))
        assert gap[i] < math.radians(3.5)
        assert abs(fixed.ranges[i] - sim[10].ranges[j]) < 0.3


def test_mount_undecided_without_motion_says_so(sim: list[LaserScan], capsys: Any) -> None:
    still = [replace(s, odom=sim[0].odom.copy()) for s in sim[:50]]
    setup = check_lidar(still, "auto", "off", data_states_mount=False)
    assert setup.mount is not None and not setup.mount.decided and setup.correction is None
    assert "UNCHECKED" in capsys.readouterr().err
    assert any("UNCHECKED" in n for n in setup.record()["notes"])


def test_lidar_setup_without_checks_changes_nothing(sim: list[LaserScan]) -> None:
    setup = LidarSetup(mount_mode="given")
    assert setup.correct(sim[0]) is sim[0] and setup.body_mask_for_scans() is None


# -- end to end: crlam slam on a bag whose laser is upside down, not said in the bag ------------


def _flipped_bag(scans: list[LaserScan], path: Path) -> Path:
    """The scans mirrored (upside down) with 3 body beams, their odometry on /odom, no mount."""
    with McapBagWriter(path) as w:
        for s in scans:
            t = 100.0 + s.timestamp
            w.write("/odom", "nav_msgs/msg/Odometry", round(t * 1e9), w.odometry(t, "odom", "base_link", s.odom))
            r = s.ranges[::-1].copy()
            r[[60, 61, 62]] = 0.2
            amin = -(s.angle_min + s.angle_increment * (s.n_beams - 1))
            msg = w.laser_scan(t + 1e-4, "laser", r, amin, s.angle_increment, s.max_range)
            w.write("/scan", "sensor_msgs/msg/LaserScan", round((t + 1e-4) * 1e9), msg)
        t_end = 100.0 + scans[-1].timestamp + 0.05
        w.write("/odom", "nav_msgs/msg/Odometry", round(t_end * 1e9), w.odometry(t_end, "odom", "base_link", scans[-1].odom))
    return path


@pytest.mark.slow
def test_slam_reports_and_corrects_a_hidden_flip(sim: list[LaserScan], tmp_path: Path, capsys: Any) -> None:
    bag = _flipped_bag(sim[:400], tmp_path / "flipped")
    out = tmp_path / "run"
    argv = ["slam", str(bag), "--out", str(out), "--quiet", "--particles", "5"]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "laser mount" in err and "flip yes" in err and "body mask: 3 of 180" in err
    lidar = json.loads((out / "metrics.json").read_text())["input"]["lidar"]
    assert lidar["laser_mount"] == "auto" and lidar["data_states_mount"] is False
    assert lidar["mount_used"]["upside_down_against_data"] is True and abs(lidar["mount_used"]["yaw_deg"]) < 1e-9
    assert lidar["body_mask"]["beams"] == [60, 61, 62]
    assert lidar["readings"]["n_body_masked"] == 3 * 400
    # With the mount given, nothing is checked.
    out2 = tmp_path / "run2"
    assert main([*argv[:3], str(out2), *argv[4:], "--laser-mount", "0", "0", "0", "--upside-down"]) == 0
    lidar = json.loads((out2 / "metrics.json").read_text())["input"]["lidar"]
    assert lidar["laser_mount"] == "given" and lidar["mount_estimate"] is None


# -- real data (skipped without CRLAM_DATA) ------------------------------------------------------


@pytest.mark.realdata
def test_turtlebot4_mount_found_again_when_hidden(data_dir: Path) -> None:
    """The TurtleBot 4 bag's /tf_static mounts its lidar turned by 90 deg; with the mount hidden
    (and with it mirrored) the check finds it again from the scans and the odometry."""
    from crlam.io.logs import open_log

    bag = data_dir / "bags" / "turtlebot4-mac-floor"
    if not bag.is_dir():
        pytest.skip(f"{bag} not found")
    stated = check_lidar(open_log(bag), "auto", "off", warn=False)
    assert stated.correction is None and stated.data_mount is not None
    assert abs(stated.data_mount[2] - math.pi / 2) < 1e-6
    for upside_down in (False, True):
        setup = check_lidar(open_log(bag, laser_mount=[0.0, 0.0, 0.0], upside_down=upside_down), "auto", "off", warn=False)
        assert setup.correction is not None
        flip, yaw, _, _ = setup.correction
        assert flip is upside_down and abs(math.remainder(yaw - math.pi / 2, math.tau)) < 1e-9


def test_crlam_map_takes_the_policy(tmp_path: Path) -> None:
    bag = _bag_with_every_kind(tmp_path / "kinds")
    for policy, dropped in (("drop", 6), ("z_max", 0)):
        out = tmp_path / policy
        assert main(["map", str(bag), "--out", str(out), "--quiet", "--no-return", policy]) == 0
        record = json.loads((out / "mapping.json").read_text())
        assert record["no_return"] == policy
        assert record["readings"]["n_no_return"] == 6 and record["readings"]["n_no_return_dropped"] == dropped


@pytest.mark.slow
def test_mount_offset_recovered_on_simulated_scans(sim: list[LaserScan]) -> None:
    """A laser 0.2 m ahead and 0.1 m left of the base, turned by 90 deg and upside down, none of it
    in the data: the base's odometry is the laser's pose composed with the mount's inverse."""
    from crlam.pose import compose

    mount = np.array([0.2, 0.1, math.pi / 2])
    c, s = math.cos(mount[2]), math.sin(mount[2])
    inverse = np.array([-(c * mount[0] + s * mount[1]), -(-s * mount[0] + c * mount[1]), -mount[2]])
    scans = [
        replace(x, odom=np.asarray(compose(compose(x.odom, [0.0, 0.0, mount[2]]), inverse)))
        for x in _mounted(sim, float(mount[2]), True)
    ]
    setup = check_lidar(scans, "auto", "off", warn=False)
    assert setup.correction is not None
    flip, yaw, x, y = setup.correction
    assert flip and abs(math.remainder(yaw - mount[2], math.tau)) < 1e-9
    assert math.hypot(x - mount[0], y - mount[1]) < 0.05


def test_laser_mount_option_values() -> None:
    import argparse

    from crlam.cli.options import bag_options, laser_mount_mode
    from crlam.errors import ConfigError

    def ns(**kw: Any) -> argparse.Namespace:
        return argparse.Namespace(**{"laser_mount": None, "upside_down": False, **kw})

    assert laser_mount_mode(ns()) == "auto" and "laser_mount" not in bag_options(ns())
    assert laser_mount_mode(ns(laser_mount=["auto"])) == "auto" and "laser_mount" not in bag_options(ns(laser_mount=["auto"]))
    assert laser_mount_mode(ns(laser_mount=["data"])) == "data"
    assert laser_mount_mode(ns(laser_mount=["0.2", "0", "3.14"])) == "given"
    assert bag_options(ns(laser_mount=["0.2", "0", "3.14"]))["laser_mount"] == [0.2, 0.0, 3.14]
    assert laser_mount_mode(ns(upside_down=True)) == "given"
    with pytest.raises(ConfigError, match="--laser-mount"):
        bag_options(ns(laser_mount=["0.2", "0"]))
    with pytest.raises(ConfigError, match="--laser-mount"):
        laser_mount_mode(ns(laser_mount=["sideways"]))
