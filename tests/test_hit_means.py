"""``hit_means``: RBPF-CLAM's endpoint matcher reads where in its cells each wall was seen."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from crlam.cli import main
from crlam.errors import ConfigError
from crlam.io.tum import read_tum
from crlam.slam import SlamConfig, presets

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib


def test_presets_and_values() -> None:
    assert SlamConfig().hit_means is False
    assert SlamConfig.from_preset("robust").hit_means is False
    assert SlamConfig(hit_means=True).hit_means is True
    for bad in (1, 0, "yes", None):
        with pytest.raises(ConfigError, match="hit_means"):
            SlamConfig(hit_means=bad)  # type: ignore[arg-type]


def test_a_config_file_needs_a_boolean(tmp_path: Path) -> None:
    path = tmp_path / "config.toml"
    path.write_text("[slam]\nhit_means = 1\n")
    with pytest.raises(ConfigError, match="hit_means: expected true or false"):
        presets.load_config_file(path)


def test_the_setting_round_trips_and_changes_the_matches(office_sick: Path, tmp_path: Path) -> None:
    log = str(office_sick / "log.clf")
    flags = ["--particles", "3", "--seed", "2", "--linear-update", "0.2", "--quiet"]
    runs = {}
    for flag, value in (("--no-hit-means", False), ("--hit-means", True)):
        out = tmp_path / flag
        assert main(["slam", log, "--out", str(out), *flags, flag]) == 0
        assert tomllib.loads((out / "config.toml").read_text())["slam"]["hit_means"] is value
        deviations = json.loads((out / "metrics.json").read_text())["deviations_from_paper"]
        assert [d for d in deviations if d.startswith("hit_means")] == (["hit_means = True (paper: False)"] if value else [])
        runs[value] = read_tum(out / "trajectory.tum").poses
        again = tmp_path / f"{flag}_again"
        assert main(["slam", log, "--out", str(again), "--config", str(out / "config.toml"), "--quiet"]) == 0
        np.testing.assert_array_equal(read_tum(again / "trajectory.tum").poses, runs[value])
    # Sub-cell wall positions move the matches: the trajectories differ, and both track the truth.
    assert not np.array_equal(runs[False], runs[True])
    truth = read_tum(office_sick / "groundtruth.tum").poses
    for poses in runs.values():
        assert np.sqrt(np.mean(np.sum((poses[:, :2] - truth[: len(poses), :2]) ** 2, axis=1))) < 0.3


def test_the_sweeps_take_the_flag(tmp_path: Path) -> None:
    argv = ["experiment", "table1", "--out", str(tmp_path), "--runs", "1", "--scans", "20", "--particles", "2"]
    argv += ["--methods", "clam", "--preset", "robust", "--hit-means", "--workers", "1", "--quiet"]
    assert main(argv) == 0
    config = tomllib.loads((tmp_path / "runs" / "clam_run00" / "config.toml").read_text())
    assert config["slam"]["hit_means"] is True
    assert "hit_means = True (paper: False)" in (tmp_path / "table.md").read_text()
