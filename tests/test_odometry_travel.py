"""The estimate's travel against the wheel odometry's (``metrics.json``: ``odometry_travel``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import crlam.experiments.slam_outputs as slam_outputs
from crlam.cli import main
from crlam.eval.odometry_travel import MIN_TOTAL_M, TRAVEL_TOLERANCE, OdometryTravel, odometry_travel
from crlam.pose import compose


def _drive(n: int, step: float, turn: float = 0.0, start: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """n poses, each ``step`` m forward of the last and turned by ``turn`` rad."""
    poses = [np.asarray(start, dtype=float)]
    for _ in range(n - 1):
        poses.append(np.asarray(compose(poses[-1], [step, 0.0, turn])))
    return np.array(poses)


def test_an_estimate_that_moves_with_the_odometry_agrees_in_any_frame() -> None:
    odometry = _drive(600, 0.1, turn=0.002)
    estimate = _drive(600, 0.1, turn=0.002, start=(5.0, -3.0, 1.2))
    travel = odometry_travel(estimate, odometry)
    assert travel.ratio == pytest.approx(1.0)
    assert travel.agrees is True and travel.warning() is None
    # Eleven whole windows of 50 steps of 0.1 m (the last, incomplete one is left out).
    assert travel.n_windows == 11 and travel.odometry_m == pytest.approx(55.0, rel=0.01)
    assert travel.to_dict()["tolerance"] == TRAVEL_TOLERANCE


def test_a_compressed_estimate_disagrees_and_says_so() -> None:
    odometry = _drive(600, 0.1)
    estimate = _drive(600, 0.05)
    travel = odometry_travel(estimate, odometry)
    assert travel.ratio == pytest.approx(0.5)
    assert travel.agrees is False
    warning = travel.warning()
    assert warning is not None and "50% less" in warning and "compressed" in warning
    stretched = odometry_travel(_drive(600, 0.13), odometry)
    assert stretched.agrees is False and "stretched" in (stretched.warning() or "")
    # Within the tolerance: agreement.
    assert odometry_travel(_drive(600, 0.1 * (1 - TRAVEL_TOLERANCE / 2)), odometry).agrees is True


def test_backwards_driving_counts_and_turns_in_place_do_not() -> None:
    backwards = _drive(600, -0.1)
    assert odometry_travel(backwards, backwards).ratio == pytest.approx(1.0)
    assert odometry_travel(_drive(600, 0.1), backwards).ratio == pytest.approx(-1.0)
    spinning = _drive(600, 0.0, turn=0.1)
    travel = odometry_travel(spinning, spinning)
    assert (travel.ratio, travel.n_windows, travel.agrees) == (None, 0, None)
    # Too little straight travel for a verdict, though there is a ratio.
    short = _drive(120, 0.1)
    assert odometry_travel(short, short).odometry_m < MIN_TOTAL_M
    assert odometry_travel(short, short).agrees is None


def test_the_poses_must_pair_up() -> None:
    with pytest.raises(ValueError, match="odometry poses"):
        odometry_travel(np.zeros((10, 3)), np.zeros((11, 3)))
    with pytest.raises(ValueError, match="window"):
        odometry_travel(np.zeros((10, 3)), np.zeros((10, 3)), window=0)


def test_a_run_reports_the_check_and_warns_when_the_travel_disagrees(
    office_sick: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    flags = ["--particles", "3", "--quiet"]
    assert main(["slam", str(office_sick / "log.clf"), "--out", str(tmp_path / "run"), *flags]) == 0
    record = json.loads((tmp_path / "run" / "metrics.json").read_text())["odometry_travel"]
    assert record["ratio"] == pytest.approx(1.0, abs=TRAVEL_TOLERANCE)
    assert record["agrees"] in (True, None)
    assert "WARNING: the estimate travelled" not in capsys.readouterr().err
    compressed = OdometryTravel(ratio=0.6, odometry_m=80.0, n_windows=20, agrees=False)
    monkeypatch.setattr(slam_outputs, "odometry_travel", lambda estimate, odometry: compressed)
    assert main(["slam", str(office_sick / "log.clf"), "--out", str(tmp_path / "short"), *flags]) == 0
    assert "WARNING: the estimate travelled 40% less than the wheel odometry" in capsys.readouterr().err
    assert json.loads((tmp_path / "short" / "metrics.json").read_text())["odometry_travel"]["agrees"] is False
