"""``degeneracy``: what RBPF-CLAM's scan-match proposal does along a direction the scan leaves free."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from PIL import Image

from crlam.cli import main
from crlam.io.tum import read_tum
from crlam.pose import between
from crlam.slam import DEGENERACIES

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib


def _corridor_world(out: Path, length: float = 40.0, width: float = 2.5, resolution: float = 0.05) -> Path:
    """A straight corridor closed at both ends (Nav2 PGM + YAML): nothing along it tells one
    stretch from another within the simulated 8 m lidar's reach."""
    out.mkdir(parents=True, exist_ok=True)
    wall = 10
    nx, ny = round(length / resolution) + 2 * wall, round(width / resolution) + 2 * wall
    image = np.full((ny, nx), 254, dtype=np.uint8)
    image[:wall, :] = image[-wall:, :] = 0
    image[:, :wall] = image[:, -wall:] = 0
    Image.fromarray(image).save(out / "corridor.pgm")
    (out / "corridor.yaml").write_text(
        f"image: corridor.pgm\nresolution: {resolution}\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\nmode: trinary\n"
    )
    return out / "corridor.yaml"


def _forward_scale_error(estimate: np.ndarray, truth: np.ndarray, window: int = 50) -> float:
    """The estimate's forward travel over windows of ``window`` scans against the truth's,
    summed: (estimate − truth) / truth; negative when the corridor comes out short."""
    n = min(len(estimate), len(truth))
    seen = sum(between(estimate[k], estimate[k + window])[0] for k in range(0, n - window, window))
    moved = sum(between(truth[k], truth[k + window])[0] for k in range(0, n - window, window))
    return float((seen - moved) / abs(moved))


def test_remapping_keeps_a_featureless_corridor_its_length(tmp_path: Path) -> None:
    """In a featureless corridor the default climb and the CRM weight pull the particles back
    towards what they have mapped, so the corridor comes out short; with solution remapping the
    estimate travels as far as the robot did. Fails without the remapping (``off`` is the
    control: the same log and seed)."""
    world = _corridor_world(tmp_path / "world")
    log = tmp_path / "log"
    argv = ["simulate", "--world", str(world), "--sensor", "paper", "--scans", "300", "--seed", "0", "-o", str(log)]
    assert main([*argv, "--quiet"]) == 0
    truth = read_tum(log / "groundtruth.tum").poses
    errors = {}
    for mode in DEGENERACIES:
        out = tmp_path / mode
        argv = ["slam", str(log / "log.clf"), "--out", str(out), "--seed", "0", "--degeneracy", mode, "--quiet"]
        assert main(argv) == 0
        assert tomllib.loads((out / "config.toml").read_text())["slam"]["degeneracy"] == mode
        metrics = json.loads((out / "metrics.json").read_text())
        expected = ["degeneracy = 'remap' (paper: 'off')"] if mode == "remap" else []
        assert [d for d in metrics["deviations_from_paper"] if d.startswith("degeneracy")] == expected
        # Most of the corridor's scans leave its axis free; `off` does not look for them.
        record = metrics["degeneracy"]
        assert record["mode"] == mode
        assert (record["degenerate_scans"] > metrics["n_processed"] // 2) == (mode == "remap"), record
        errors[mode] = _forward_scale_error(read_tum(out / "trajectory.tum").poses, truth)
    assert abs(errors["remap"]) < 0.1, errors
    assert errors["off"] < -0.15, errors
