"""The default preset on real data: what a user gets from ``crlam slam LOG --out DIR`` with no flags."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from crlam.cli import main
from crlam.eval.trajectory import relations_error
from crlam.io.carmen import read_scans
from crlam.io.relations import read_relations
from crlam.slam import SlamConfig
from crlam.slam.fill import FILLS, fill_skipped
from crlam.slam.presets import DEFAULT_PRESET


@pytest.mark.realdata
@pytest.mark.slow
def test_the_default_beats_odometry_by_far_on_intels_first_3000_scans(data_dir: Path, tmp_path: Path) -> None:
    log, rel = data_dir / "intel" / "intel.clf.bz2", data_dir / "intel" / "intel.relations"
    out = tmp_path / "run"
    assert main(["slam", str(log), "--out", str(out), "--relations", str(rel), "--max-scans", "3000", "--quiet"]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["preset"] == DEFAULT_PRESET and metrics["n_scans"] == 3000
    filt = metrics["relations"]
    scans = [s for _, s in zip(range(3000), read_scans(log))]
    odo = relations_error(
        np.array([s.timestamp for s in scans]),
        np.array([s.odom for s in scans]),
        read_relations(rel),
        on_missing="skip",
    ).summary()
    assert filt["n"] > 500
    # Odometry is off by 3.3 m on these relations; the default gets about 0.037 m. The paper's
    # settings (`--preset paper`) give 0.89 m here, so the first bound fails for them.
    assert filt["trans_mean_m"] < 0.08, (filt, odo)
    assert filt["trans_mean_m"] < odo["trans_mean_m"] / 20, (filt, odo)

    # The default fill of the skipped scans (interpolate) against the odometry fill, from the
    # same processed estimates: about 0.037 against 0.045 m here.
    rows = np.genfromtxt(out / "steps.csv", delimiter=",", names=True)
    processed = np.zeros(len(scans), dtype=bool)
    processed[rows["scan_index"].astype(int)] = True
    path = np.column_stack([rows["mean_x"], rows["mean_y"], rows["mean_theta"]])
    stamps, odometry = np.array([s.timestamp for s in scans]), np.array([s.odom for s in scans])
    config = SlamConfig.from_preset()
    by_rule = {
        fill: relations_error(
            stamps,
            fill_skipped(path, processed, odometry, stamps, fill, config.linear_update, config.angular_update),
            read_relations(rel),
            on_missing="skip",
        ).summary()["trans_mean_m"]
        for fill in FILLS
    }
    assert by_rule["interpolate"] == pytest.approx(filt["trans_mean_m"], abs=2e-4)
    assert by_rule["interpolate"] < 0.95 * by_rule["odometry"], by_rule
