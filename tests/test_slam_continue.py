"""Mapping that continues a saved run: belief.npz format 2 (the final estimate), its version
checks, and ``crlam slam LOG --continue DIR`` end to end on a simulated log cut in two."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from crlam.cli import main
from crlam.errors import ConfigError, DataFormatError
from crlam.io.belief import FORMAT_VERSION, BeliefArchive, load_belief, save_belief
from crlam.io.tum import read_tum
from crlam.sim.simulate import SimulationConfig, simulate, write_simulation
from crlam.slam.prior import load_slam_prior, pose_covariance


def _archive(**extra: object) -> BeliefArchive:
    rng = np.random.default_rng(0)
    b = rng.random((4, 5, 10)).astype(np.float32)
    b /= b.sum(axis=2, keepdims=True)
    return BeliefArchive(b, (np.arange(10) + 0.5) / 10, np.array([-1.0, 2.0]), 0.1, {"k": 1}, **extra)  # type: ignore[arg-type]


def test_estimate_round_trips(tmp_path: Path) -> None:
    cov = np.array([[0.01, 0.002, 0.0], [0.002, 0.02, 0.001], [0.0, 0.001, 0.003]])
    save_belief(tmp_path / "b.npz", _archive(estimate=np.array([1.0, -2.0, 0.5]), estimate_cov=cov))
    a = load_belief(tmp_path / "b.npz")
    assert a.estimate is not None and a.estimate_cov is not None
    assert np.array_equal(a.estimate, [1.0, -2.0, 0.5]) and np.array_equal(a.estimate_cov, cov)
    with np.load(tmp_path / "b.npz") as z:
        assert int(z["format_version"]) == FORMAT_VERSION == 2


def test_invalid_estimates_are_not_written(tmp_path: Path) -> None:
    with pytest.raises(DataFormatError, match="estimate"):
        save_belief(tmp_path / "a.npz", _archive(estimate=np.zeros(3)))
    with pytest.raises(DataFormatError, match="estimate_cov"):
        save_belief(tmp_path / "b.npz", _archive(estimate=np.zeros(3), estimate_cov=-np.eye(3)))
    with pytest.raises(DataFormatError, match="estimate"):
        save_belief(tmp_path / "c.npz", _archive(estimate=np.array([0.0, np.nan, 0.0]), estimate_cov=np.eye(3)))


def _rewrite(src: Path, dst: Path, **changes: object) -> None:
    with np.load(src) as z:
        arrays = {k: z[k] for k in z.files}
    arrays.update(changes)
    arrays = {k: v for k, v in arrays.items() if v is not None}
    with open(dst, "wb") as fh:
        np.savez_compressed(fh, **arrays)  # type: ignore[arg-type]


def test_version_1_reads_without_an_estimate_and_cannot_be_continued(tmp_path: Path) -> None:
    save_belief(tmp_path / "v2.npz", _archive())
    _rewrite(tmp_path / "v2.npz", tmp_path / "belief.npz", format_version=np.array(1, dtype=np.int64))
    (tmp_path / "COMPLETE").write_text("")
    a = load_belief(tmp_path / "belief.npz")
    assert a.estimate is None and a.estimate_cov is None
    with pytest.raises(DataFormatError, match="version 1") as e:
        load_slam_prior(tmp_path)
    assert "field estimate" in str(e.value)


def test_a_newer_version_is_refused_with_both_versions(tmp_path: Path) -> None:
    save_belief(tmp_path / "v2.npz", _archive())
    _rewrite(tmp_path / "v2.npz", tmp_path / "v3.npz", format_version=np.array(3, dtype=np.int64))
    with pytest.raises(DataFormatError, match=r"format version 3 was written by a newer crlam.*reads versions 1\.\.2"):
        load_belief(tmp_path / "v3.npz")


def test_pose_covariance_wraps_headings() -> None:
    poses = np.array([[0.0, 0.0, 3.1], [0.2, 0.0, -3.1]])
    cov = pose_covariance(poses, np.array([0.5, 0.5]), np.array([0.1, 0.0, np.pi]))
    assert cov[0, 0] == pytest.approx(0.01) and cov[2, 2] == pytest.approx((np.pi - 3.1) ** 2)
    assert np.allclose(cov, cov.T)


@pytest.fixture(scope="module")
def halves(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A simulated office log and its two halves, cut between two scans."""
    d = tmp_path_factory.mktemp("halves")
    write_simulation(simulate(SimulationConfig(world="office", n_scans=240, seed=4, sensor="sick")), d)
    lines = (d / "log.clf").read_text().splitlines(keepends=True)
    scans = [i for i, line in enumerate(lines) if line.startswith("FLASER")]
    cut = scans[120]
    (d / "first.clf").write_text("".join(lines[:cut]))
    (d / "second.clf").write_text("".join(lines[cut:]))
    return d


def _digest(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.rglob("*")) if p.is_file()
    }


def test_continue_maps_on_from_the_saved_run(halves: Path, tmp_path: Path) -> None:
    first, second = tmp_path / "first", tmp_path / "second"
    common = ["--particles", "10", "--quiet", "--seed", "2"]
    assert main(["slam", str(halves / "first.clf"), "--out", str(first), *common]) == 0
    saved = load_belief(first / "belief.npz")
    assert saved.estimate is not None and saved.estimate_cov is not None
    before = _digest(first)
    assert main(["slam", str(halves / "second.clf"), "--out", str(second), "--continue", str(first), "--quiet"]) == 0
    assert _digest(first) == before, "the saved run changed"
    m = json.loads((second / "metrics.json").read_text())
    assert m["continued_from"]["path"] == str(first)
    assert m["particles"] == 10, "the saved run's settings carry over"
    assert f'continue = "{first}"' in (second / "config.toml").read_text()
    # The continued trajectory is in the saved map's frame: its first pose is the saved estimate
    # (to the covariance's spread), and it tracks the truth about as well as the first half did.
    gt = read_tum(halves / "groundtruth.tum")
    a, b = read_tum(first / "trajectory.tum"), read_tum(second / "trajectory.tum")
    assert b.poses.shape[0] == gt.poses.shape[0] - a.poses.shape[0]
    assert np.hypot(*(b.poses[0, :2] - saved.estimate[:2])) < 0.3
    err_a = np.hypot(*(a.poses[:, :2] - gt.poses[: len(a.poses), :2]).T)
    err_b = np.hypot(*(b.poses[:, :2] - gt.poses[len(a.poses) :, :2]).T)
    assert np.mean(err_b) < max(0.3, 3 * np.mean(err_a)), (np.mean(err_a), np.mean(err_b))


def test_continue_refuses_to_write_into_the_saved_run(halves: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    first = tmp_path / "first"
    assert main(["slam", str(halves / "first.clf"), "--out", str(first), "--particles", "5", "--quiet", "--max-scans", "30"]) == 0
    before = _digest(first)
    assert main(["slam", str(halves / "second.clf"), "--out", str(first), "--continue", str(first), "--quiet"]) == 2
    assert "new folder" in capsys.readouterr().err
    # not even with --force, which replaces an existing output
    assert main(["slam", str(halves / "second.clf"), "--out", str(first), "--continue", str(first), "--quiet", "--force"]) == 2
    assert "new folder" in capsys.readouterr().err
    assert _digest(first) == before
    with pytest.raises(ConfigError, match="RBPF-CLAM"):
        from crlam.experiments.slam_run import run_slam_log
        from crlam.slam import SlamConfig

        run_slam_log(
            halves / "second.clf", tmp_path / "ogm", SlamConfig(method="ogm"), prior=load_slam_prior(first), progress=False
        )
    assert (
        main(["slam", str(halves / "second.clf"), "--out", str(tmp_path / "r"), "--continue", str(tmp_path / "none"), "--quiet"])
        == 2
    )
