"""The dominant wall direction of a scan (crlam.slam.grid_alignment)."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crlam.cli import main
from crlam.errors import DataFormatError
from crlam.experiments.slam_run import run_slam_log
from crlam.io.tum import read_tum
from crlam.pose import compose
from crlam.sim.simulate import SimulatedLog, SimulationConfig, simulate, write_simulation
from crlam.slam import SlamConfig, SlamRun
from crlam.slam.grid_alignment import (
    MIN_CONCENTRATION,
    frame_from_record,
    from_map_frame,
    into_map_frame,
    map_frame,
    wall_direction,
    walls_found,
)


def _room_scan(turn: float, *, n: int = 361) -> tuple[np.ndarray, np.ndarray]:
    """Bearings and exact ranges of a 360-deg laser inside an 8 m x 5 m rectangular room, off its
    centre, whose walls run at ``turn`` (rad) to the laser's axes."""
    angles = np.linspace(-math.pi, math.pi, n, endpoint=False)
    # The room is turned by `turn` against the laser: a beam at bearing a runs at a - turn in it.
    d = np.stack([np.cos(angles - turn), np.sin(angles - turn)], axis=1)
    (hx, hy), (cx, cy) = (4.0, 2.5), (0.6, -0.4)
    with np.errstate(divide="ignore"):
        tx = np.where(d[:, 0] > 0, (hx - cx) / d[:, 0], (-hx - cx) / d[:, 0])
        ty = np.where(d[:, 1] > 0, (hy - cy) / d[:, 1], (-hy - cy) / d[:, 1])
    return angles, np.minimum(np.abs(tx), np.abs(ty))


def _fold(a: float) -> float:
    return (a + math.pi / 4) % (math.pi / 2) - math.pi / 4


@settings(max_examples=40, deadline=None)
@given(turn=st.floats(-math.pi, math.pi), offset_heading=st.floats(-0.5, 0.5))
def test_rectangular_room_gives_its_wall_direction_modulo_90_deg(turn: float, offset_heading: float) -> None:
    angles, ranges = _room_scan(turn)
    # A laser turned on the robot by offset_heading sees the room turned by as much less.
    wd = wall_direction(angles, ranges, (0.1, 0.0, offset_heading), max_range=20.0)
    assert abs(_fold(wd.angle - (turn + offset_heading))) < math.radians(0.3)
    assert -math.pi / 4 <= wd.angle < math.pi / 4
    assert wd.concentration > 0.95
    assert wd.wall_length > 10.0


def test_noise_and_clutter_do_not_move_the_estimate() -> None:
    rng = np.random.default_rng(3)
    turn = math.radians(17.0)
    angles, ranges = _room_scan(turn)
    ranges = ranges + rng.normal(0.0, 0.01, ranges.shape)
    # A diagonal shelf in front of a fifth of the beams.
    ranges[40:110] = np.linspace(1.0, 2.2, 70)
    wd = wall_direction(angles, ranges, max_range=20.0)
    assert abs(_fold(wd.angle - turn)) < math.radians(1.0)
    assert 0.5 < wd.concentration < 1.0


def test_no_straight_wall_gives_no_direction() -> None:
    angles = np.linspace(-math.pi / 2, math.pi / 2, 181)
    # A round room seen from its centre, and every reading beyond max_range.
    circle = wall_direction(angles, np.full(181, 3.0), max_range=8.0)
    far = wall_direction(angles, np.full(181, 50.0), max_range=8.0)
    assert circle.wall_length == 0.0 or circle.concentration < 0.5
    assert far == type(far)(0.0, 0.0, 0.0)
    # Neither lays the grid on walls, so sub_cell = "unaligned" turns the sub-cell geometry on.
    assert not walls_found(circle) and not walls_found(far)
    assert walls_found(wall_direction(*_room_scan(0.3)))


@pytest.mark.parametrize(
    ("sub_cell", "method", "on_walls", "expected"),
    [
        ("unaligned", "clam", True, False),
        ("unaligned", "clam", False, True),
        ("on", "clam", True, True),
        ("off", "clam", False, False),
        ("on", "ogm", False, False),
    ],
)
def test_the_sub_cell_geometry_is_chord_causes_and_hit_means_where_asked(
    sub_cell: str, method: str, on_walls: bool, expected: bool
) -> None:
    config = SlamConfig.from_preset("robust", sub_cell=sub_cell, method=method)
    assert (config.cause_kernel, config.hit_means) == ("midpoint", False)
    used = config.filter_settings(on_walls)
    if expected:
        assert (used.cause_kernel, used.hit_means) == ("chord", True)
        assert dataclasses.replace(used, cause_kernel="midpoint", hit_means=False) == config
    else:
        assert used is config


def test_bad_shapes_are_errors() -> None:
    with pytest.raises(DataFormatError, match="bearings"):
        wall_direction(np.zeros(5), np.zeros(4))
    with pytest.raises(DataFormatError, match="laser_offset"):
        wall_direction(np.zeros(5), np.zeros(5), (0.0, 0.0))


# --- The map's frame in a SLAM run -----------------------------------------------------------

TURN = math.radians(20.0)


@pytest.fixture(scope="module")
def turned_office(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, SimulatedLog]:
    """A short office log whose odometry frame is turned by 20 deg against the world's walls
    (ground truth and odometry turned alike about the first pose), written as a CARMEN log."""
    log = simulate(SimulationConfig(world="office", n_scans=150, seed=4))
    frame = map_frame(TURN, log.poses[0, :2])
    turned = dataclasses.replace(log, poses=compose(frame, log.poses), odometry=compose(frame, log.odometry))
    d = tmp_path_factory.mktemp("turned_office")
    write_simulation(turned, d)
    return d, turned


def _rmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((a[:, :2] - b[:, :2]) ** 2, axis=1))))


def _run(log: SimulatedLog, alignment: str, **settings: object) -> SlamRun:
    run = SlamRun(SlamConfig.from_preset("robust", particles=10, seed=2, grid_alignment=alignment, **settings))
    ranges = np.where(log.ranges >= log.sensor.max_range, np.inf, log.ranges)
    for k in range(log.n_scans):
        run.step(log.odometry[k], log.sensor.angles, ranges[k], np.zeros(3), float(log.timestamps[k]))
    return run


def test_walls_turn_the_map_back_onto_the_grid_and_poses_turn_back(turned_office: tuple[Path, SimulatedLog]) -> None:
    _, log = turned_office
    run = _run(log, "walls")
    assert run.map_walls is not None and run.map_walls.concentration >= MIN_CONCENTRATION
    # The office's walls are on the world's axes: the map's frame undoes the 20 deg turn.
    assert abs(math.degrees(run.map_turn) + 20.0) < 1.0
    _, poses = run.trajectory()
    back = run.to_odometry_frame(poses)
    # In the map's frame the path is turned against the ground truth; turned back, it matches it
    # far better than the odometry does.
    assert _rmse(back, log.poses) < 0.5 * _rmse(log.odometry, log.poses)
    assert _rmse(poses, log.poses) > 2.0 * _rmse(back, log.poses)
    np.testing.assert_allclose(run.to_odometry_frame(into_map_frame(run.map_frame, log.poses)), log.poses, atol=1e-9)
    record = run.map_frame_record()
    np.testing.assert_allclose(frame_from_record(record), run.map_frame, atol=1e-12)
    assert record["grid_alignment"] == "walls"
    # The grid runs along the walls: sub_cell = "unaligned" leaves the geometry off.
    unaligned = _run(log, "walls", sub_cell="unaligned")
    assert not run.sub_cell and record["sub_cell"] is False and run.filter_config is run.config
    assert not unaligned.sub_cell and unaligned.filter_config is unaligned.config
    np.testing.assert_array_equal(unaligned.trajectory()[1], poses)


def test_no_alignment_keeps_the_odometry_frame(turned_office: tuple[Path, SimulatedLog]) -> None:
    _, log = turned_office
    run = _run(log, "none")
    assert run.map_turn == 0.0 and run.map_walls is None
    _, poses = run.trajectory()
    np.testing.assert_array_equal(run.to_odometry_frame(poses), poses)
    np.testing.assert_allclose(poses[0], log.odometry[0], atol=1e-9)
    assert frame_from_record(run.map_frame_record()).tolist() == [0.0, 0.0, 0.0]


def test_a_grid_off_the_walls_runs_the_sub_cell_geometry(turned_office: tuple[Path, SimulatedLog]) -> None:
    _, log = turned_office
    assert not _run(log, "none").sub_cell  # the preset's sub_cell is "off"
    run = _run(log, "none", sub_cell="unaligned")
    assert run.sub_cell and run.map_frame_record()["sub_cell"] is True
    # The filter is exactly the one with the two settings given, and not the one without them.
    explicit = _run(log, "none", sub_cell="off", cause_kernel="chord", hit_means=True)
    plain = _run(log, "none", sub_cell="off")
    assert explicit.sub_cell and not plain.sub_cell
    _, poses = run.trajectory()
    np.testing.assert_array_equal(poses, explicit.trajectory()[1])
    assert np.abs(poses - plain.trajectory()[1]).max() > 1e-6


def test_run_folder_records_the_turn_and_scores_the_reference_in_its_frame(
    turned_office: tuple[Path, SimulatedLog], tmp_path: Path
) -> None:
    d, log = turned_office
    res = run_slam_log(
        d / "log.clf",
        tmp_path,
        SlamConfig.from_preset("robust", particles=10, seed=2, grid_alignment="walls"),
        reference=d / "groundtruth.tum",
        progress=False,
    )
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert abs(metrics["map_frame"]["turn_deg"] + 20.0) < 1.0
    assert "grid_alignment = 'walls' (paper: 'none')" in metrics["deviations_from_paper"]
    # trajectory.tum is in the map's frame; the reference errors were taken in the odometry's.
    written = read_tum(tmp_path / "trajectory.tum")
    back = from_map_frame(frame_from_record(metrics["map_frame"]), written.poses)
    assert metrics["reference"]["rmse_position_m"] == pytest.approx(_rmse(back, log.poses), rel=1e-6)
    assert metrics["reference"]["rmse_position_m"] < 0.5 * _rmse(log.odometry, log.poses)
    assert res is not None
    # crlam eval finds the run's metrics.json and turns the trajectory back the same way.
    main(["eval", str(tmp_path / "trajectory.tum"), "--reference", str(d / "groundtruth.tum"), "-o", str(tmp_path / "e.json")])
    report = json.loads((tmp_path / "e.json").read_text())
    assert report["map_frame_turn_deg"] == pytest.approx(metrics["map_frame"]["turn_deg"])
    assert report["summary"]["rmse_position_m"] == pytest.approx(metrics["reference"]["rmse_position_m"], rel=1e-6)


def test_run_folder_records_the_sub_cell_geometry_it_ran(turned_office: tuple[Path, SimulatedLog], tmp_path: Path) -> None:
    d, _ = turned_office
    for name, sub_cell, used in (("plain", "off", False), ("sub", "unaligned", True)):
        config = SlamConfig.from_preset("robust", particles=4, seed=2, grid_alignment="none", sub_cell=sub_cell)
        run_slam_log(d / "log.clf", tmp_path / name, config, max_scans=40, progress=False, figures=False)
        metrics = json.loads((tmp_path / name / "metrics.json").read_text())
        assert metrics["map_frame"]["sub_cell"] is used
        sigma = tomllib.loads((tmp_path / name / "config.toml").read_text())["slam"]["sigma_hit_resolved"]
        # The chord kernel's σ_hit is σ_r; the midpoint kernel's adds the cell's quantisation.
        expected = config.sigma_range if used else math.hypot(config.sigma_range, config.resolution / math.sqrt(12.0))
        assert sigma == pytest.approx(expected)
