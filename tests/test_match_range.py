"""``match_range``: the readings the scan-match proposal's endpoint matcher uses (z_max, full, metres)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from crlam.cli import main
from crlam.errors import ConfigError
from crlam.io.tum import read_tum
from crlam.sim import SimulationConfig, simulate, write_simulation
from crlam.slam import SlamConfig, presets

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib


@pytest.fixture(scope="module")
def office(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("office")
    # A log whose far returns (beyond the maps' 8 m) fall on walls mapped from closer by within its
    # first 200 scans, so that matching them changes the trajectory.
    write_simulation(simulate(SimulationConfig(world="office", n_scans=200, seed=1, sensor="sick")), d)
    return d


def test_presets_and_values() -> None:
    assert SlamConfig().match_range == "z_max" == presets.load_preset("paper")["match_range"]
    assert SlamConfig.from_preset("robust").match_range == "full"
    assert SlamConfig(match_range=20).match_range == 20
    for bad in ("far", 0.0, -3.0, float("inf"), float("nan"), True, 1e6):
        with pytest.raises(ConfigError, match="match_range"):
            SlamConfig(match_range=bad)  # type: ignore[arg-type]


def test_the_flag_is_checked(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for bad in ("far", "0", "-2", "inf"):
        with pytest.raises(SystemExit):
            main(["slam", "x.clf", "--out", str(tmp_path / "x"), "--match-range", bad])
        assert "match-range" in capsys.readouterr().err


def test_the_setting_round_trips_and_changes_what_the_matcher_uses(office: Path, tmp_path: Path) -> None:
    log = str(office / "log.clf")
    # The simulated SICK sees up to 81 m, the maps stop at 8 m: the office has returns beyond.
    flags = ["--preset", "robust", "--particles", "3", "--seed", "1", "--linear-update", "0.2", "--max-scans", "200", "--quiet"]
    runs = {}
    for value in ("z_max", "full", "12.5"):
        out = tmp_path / value
        assert main(["slam", log, "--out", str(out), *flags, "--match-range", value]) == 0
        stored = tomllib.loads((out / "config.toml").read_text())["slam"]["match_range"]
        assert stored == (12.5 if value == "12.5" else value)
        deviations = json.loads((out / "metrics.json").read_text())["deviations_from_paper"]
        listed = [d for d in deviations if d.startswith("match_range = ")]
        assert listed == ([] if value == "z_max" else [f"match_range = {stored!r} (paper: 'z_max')"])
        runs[value] = read_tum(out / "trajectory.tum").poses
        # --config re-runs the same configuration: the same trajectory to the bit.
        again = tmp_path / f"{value}_again"
        assert main(["slam", log, "--out", str(again), "--config", str(out / "config.toml"), "--quiet"]) == 0
        assert presets.load_config_file(again / "config.toml").settings["match_range"] == stored
        np.testing.assert_array_equal(read_tum(again / "trajectory.tum").poses, runs[value])
    # The far returns change the matches, so the trajectories differ.
    assert not np.array_equal(runs["z_max"], runs["full"])
    assert not np.array_equal(runs["z_max"], runs["12.5"])
