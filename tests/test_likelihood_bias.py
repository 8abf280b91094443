"""``crlam diagnose likelihood-bias``: sign conventions, achirality and the command's files."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from crlam.cli import main
from crlam.cli.diagnose import reference_pose_scans
from crlam.errors import ConfigError
from crlam.eval.likelihood_bias import LineSearchGrid, likelihood_bias
from crlam.experiments.known_poses import KnownPoseScan
from crlam.mapping import MappingConfig
from crlam.sim.simulate import SimulationConfig, simulate, write_simulation

GRID = LineSearchGrid(xy_half=0.1, xy_step=0.01, heading_half=math.radians(1.0), heading_step=math.radians(0.1))
MAP = MappingConfig(resolution=0.05, max_range=8.0)


@pytest.fixture(scope="module")
def office(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("office")
    write_simulation(simulate(SimulationConfig(world="office", n_scans=80, seed=4)), d)
    return d


@pytest.fixture(scope="module")
def scans(office: Path) -> list[KnownPoseScan]:
    out, missing = reference_pose_scans(str(office / "log.clf"), str(office / "groundtruth.tum"), tolerance=1e-6)
    assert missing == 0 and len(out) == 80
    return out


def _displaced(scans: list[KnownPoseScan], offset: tuple[float, float, float]) -> list[KnownPoseScan]:
    # Displace the evaluated scans' reference poses by (forward, left, ccw) in their own frame.
    out = []
    for k, s in enumerate(scans):
        p = s.pose.copy()
        if k >= 20 and (k - 20) % 10 == 0:
            c, sn = math.cos(p[2]), math.sin(p[2])
            p += np.array([offset[0] * c - offset[1] * sn, offset[0] * sn + offset[1] * c, offset[2]])
        out.append(KnownPoseScan(p, s.angles, s.ranges, s.timestamp))
    return out


@pytest.mark.parametrize(
    ("offset", "axis", "lo", "hi"),
    [
        ((0.05, 0.0, 0.0), "along", -0.06, -0.03),
        ((0.0, -0.04, 0.0), "lateral", 0.02, 0.05),
        ((0.0, 0.0, math.radians(0.5)), "heading", math.radians(-0.7), math.radians(-0.3)),
    ],
)
def test_a_displaced_reference_is_found_back_with_the_opposite_sign(scans, offset, axis, lo, hi) -> None:
    # Exact simulated scans at a fine grid: the likelihood peaks at the true pose, so a reference
    # displaced forward (left, counter-clockwise) shows its argmax behind (right, clockwise).
    res = likelihood_bias(_displaced(scans, offset), MAP, every=10, warmup=20, grid=GRID)
    assert len(res) == 6 and res.n_scans == 80
    assert lo <= float(np.median(res.offsets[axis])) <= hi, res.offsets[axis]


def test_the_offsets_of_a_mirrored_log_are_mirrored(scans) -> None:
    # The map, the traversal and the likelihood have no handedness: mirroring the world (y -> -y)
    # keeps the along-track offsets and negates the lateral and heading ones. A handed offset in a
    # real result therefore comes from the world and the path, not from the code.
    mirrored = [
        KnownPoseScan(np.array([s.pose[0], -s.pose[1], -s.pose[2]]), -s.angles[::-1], s.ranges[::-1], s.timestamp) for s in scans
    ]
    cfg = MappingConfig(resolution=0.2, max_range=8.0)
    a = likelihood_bias(scans, cfg, every=10, warmup=20, grid=GRID)
    b = likelihood_bias(mirrored, cfg, every=10, warmup=20, grid=GRID)
    np.testing.assert_allclose(b.offsets["along"], a.offsets["along"], atol=1e-12)
    np.testing.assert_allclose(b.offsets["lateral"], -a.offsets["lateral"], atol=1e-12)
    np.testing.assert_allclose(b.offsets["heading"], -a.offsets["heading"], atol=1e-12)
    assert np.any(a.offsets["heading"] != 0) or np.any(a.offsets["lateral"] != 0)


def test_bad_search_settings_are_config_errors(scans) -> None:
    with pytest.raises(ConfigError, match="every"):
        likelihood_bias(scans, MAP, every=0)
    with pytest.raises(ConfigError, match="heading"):
        likelihood_bias(scans, MAP, grid=LineSearchGrid(heading_step=0.0))


def test_the_command_writes_its_files_and_counts_scans_without_a_reference(office: Path, tmp_path: Path, capsys) -> None:
    lines = (office / "groundtruth.tum").read_text().splitlines(keepends=True)
    gt = tmp_path / "gt.tum"
    body = [ln for ln in lines if not ln.startswith("#")]
    gt.write_text("".join(body[:30] + body[31:]))  # one scan without a reference pose
    out = tmp_path / "bias"
    argv = ["diagnose", "likelihood-bias", str(office / "log.clf"), "--reference", str(gt), "--out", str(out)]
    assert main([*argv, "--resolution", "0.1", "--every", "10", "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "1 scans had no reference pose" in printed and "heading mean" in printed
    summary = json.loads((out / "summary.json").read_text())
    assert summary["summary"]["n_evaluated"] == 6 and summary["settings"]["scans_without_reference"] == 1
    assert summary["mapping"]["resolution"] == 0.1
    assert len((out / "samples.csv").read_text().splitlines()) == 7
    assert (out / "histograms.png").stat().st_size > 10_000
    # The log's own pose fields (a corrected log's) as the reference.
    assert (
        main(["diagnose", "likelihood-bias", str(office / "log.clf"), "--log-poses", "--out", str(tmp_path / "own"), "--quiet"])
        == 0
    )
    assert json.loads((tmp_path / "own" / "summary.json").read_text())["summary"]["n_evaluated"] == 12
    # Exactly one source of reference poses.
    assert main(["diagnose", "likelihood-bias", str(office / "log.clf"), "--out", str(out)]) == 2
