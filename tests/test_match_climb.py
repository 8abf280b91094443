"""``match_climb``: what RBPF-CLAM's scan-match proposal climbs before its lattice."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from crlam.cli import main
from crlam.io.tum import read_tum
from crlam.slam import MATCH_CLIMBS

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib


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
