"""``match_climb``: what RBPF-CLAM's scan-match proposal climbs before its lattice."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from crlam.cli import main
from crlam.errors import ConfigError
from crlam.io.tum import read_tum
from crlam.slam import MATCH_CLIMBS, SlamConfig, presets

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib


def test_values_and_presets() -> None:
    assert MATCH_CLIMBS == ("score", "posterior")
    assert SlamConfig().match_climb == "score"
    assert SlamConfig.from_preset("paper").match_climb == "score"
    assert SlamConfig.from_preset("robust").match_climb == "score"
    assert SlamConfig(match_climb="posterior").match_climb == "posterior"
    for bad in ("Posterior", "", None, 1):
        with pytest.raises(ConfigError, match="match_climb"):
            SlamConfig(match_climb=bad)  # type: ignore[arg-type]


def test_a_config_file_is_checked(tmp_path: Path) -> None:
    path = tmp_path / "config.toml"
    path.write_text('[slam]\nmatch_climb = "uphill"\n')
    with pytest.raises(ConfigError, match="match_climb"):
        presets.load_config_file(path)


def test_the_flag_round_trips_and_changes_the_matches(office_sick: Path, tmp_path: Path) -> None:
    log = str(office_sick / "log.clf")
    flags = ["--particles", "3", "--seed", "2", "--linear-update", "0.2", "--quiet"]
    runs = {}
    for climb in MATCH_CLIMBS:
        out = tmp_path / climb
        assert main(["slam", log, "--out", str(out), *flags, "--match-climb", climb]) == 0
        assert tomllib.loads((out / "config.toml").read_text())["slam"]["match_climb"] == climb
        deviations = json.loads((out / "metrics.json").read_text())["deviations_from_paper"]
        expected = ["match_climb = 'posterior' (paper: 'score')"] if climb == "posterior" else []
        assert [d for d in deviations if d.startswith("match_climb")] == expected
        runs[climb] = read_tum(out / "trajectory.tum").poses
        again = tmp_path / f"{climb}_again"
        assert main(["slam", log, "--out", str(again), "--config", str(out / "config.toml"), "--quiet"]) == 0
        np.testing.assert_array_equal(read_tum(again / "trajectory.tum").poses, runs[climb])
    # The climbs end elsewhere, so the trajectories differ; both track the truth.
    assert not np.array_equal(runs["score"], runs["posterior"])
    truth = read_tum(office_sick / "groundtruth.tum").poses
    for poses in runs.values():
        assert np.sqrt(np.mean(np.sum((poses[:, :2] - truth[: len(poses), :2]) ** 2, axis=1))) < 0.3


def test_the_flag_is_checked(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["slam", "intel", "--out", str(tmp_path / "x"), "--match-climb", "downhill"])
    assert "--match-climb" in capsys.readouterr().err


def test_the_sweeps_take_the_flag(tmp_path: Path) -> None:
    argv = ["experiment", "table1", "--out", str(tmp_path), "--runs", "1", "--scans", "20", "--particles", "2"]
    argv += ["--methods", "clam", "--preset", "robust", "--match-climb", "posterior", "--workers", "1", "--quiet"]
    assert main(argv) == 0
    config = tomllib.loads((tmp_path / "runs" / "clam_run00" / "config.toml").read_text())
    assert config["slam"]["match_climb"] == "posterior"
