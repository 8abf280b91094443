"""``crlam eval --align se2|none``: the closed-form SE(2) alignment and evo's APE numbers."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from crlam.cli import main
from crlam.errors import DataFormatError
from crlam.eval.align import Se2Alignment, align_se2, ape_statistics
from crlam.eval.trajectory import reference_errors
from crlam.io.tum import write_tum


def _curve(n: int = 300, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A wiggly planar path: stamps (s) and poses (m, m, rad)."""
    t = np.linspace(0.0, 60.0, n)
    x = 3.0 * np.cos(t / 10.0) + 0.05 * t
    y = 2.0 * np.sin(t / 7.0)
    th = np.arctan2(np.gradient(y), np.gradient(x))
    return 1000.0 + t, np.column_stack([x, y, th])


def _moved(poses: np.ndarray, theta: float, tx: float, ty: float, noise: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    out = Se2Alignment(theta, tx, ty).apply(poses)
    out[:, :2] += rng.normal(0.0, noise, (poses.shape[0], 2))
    return out


def test_noise_free_alignment_recovers_the_motion_exactly() -> None:
    _, ref = _curve()
    est = _moved(ref, -0.7, 4.0, -2.5, 0.0, 0)
    a = align_se2(est[:, :2], ref[:, :2])
    inverse = Se2Alignment(0.7, *(-(np.array([[math.cos(0.7), -math.sin(0.7)], [math.sin(0.7), math.cos(0.7)]]) @ [4.0, -2.5])))
    assert a.theta == pytest.approx(inverse.theta, abs=1e-12)
    assert (a.tx, a.ty) == pytest.approx((inverse.tx, inverse.ty), abs=1e-10)
    np.testing.assert_allclose(a.apply(est)[:, :2], ref[:, :2], atol=1e-10)


def test_the_alignment_is_the_least_squares_minimum() -> None:
    # An independent check of the closed form: the cost rises along every direction around it.
    _, ref = _curve()
    est = _moved(ref, 0.3, -1.0, 2.0, 0.1, 1)
    a = align_se2(est[:, :2], ref[:, :2])

    def cost(theta: float, tx: float, ty: float) -> float:
        return float(np.sum((Se2Alignment(theta, tx, ty).apply(est)[:, :2] - ref[:, :2]) ** 2))

    best = cost(a.theta, a.tx, a.ty)
    for d in np.eye(3) * 1e-4:
        assert cost(a.theta + d[0], a.tx + d[1], a.ty + d[2]) > best
        assert cost(a.theta - d[0], a.tx - d[1], a.ty - d[2]) > best


def test_degenerate_inputs_are_clean_errors() -> None:
    with pytest.raises(DataFormatError):
        align_se2([[1.0, 2.0]], [[0.0, 0.0]])
    with pytest.raises(DataFormatError):
        align_se2([[1.0, 2.0], [1.0, 2.0]], [[0.0, 0.0], [3.0, 3.0]])


def _eval_json(tmp_path: Path, est: Path, ref: Path, align: str) -> dict:
    out = tmp_path / f"eval-{align}.json"
    assert main(["eval", str(est), "--reference", str(ref), "--align", align, "--out", str(out)]) == 0
    return json.loads(out.read_text())


@pytest.fixture
def tum_pair(tmp_path: Path) -> tuple[Path, Path]:
    stamps, ref = _curve()
    est = _moved(ref, 0.25, 1.5, -0.8, 0.05, 2)
    write_tum(tmp_path / "ref.tum", stamps, ref)
    write_tum(tmp_path / "est.tum", stamps[::2], est[::2])  # every other pose, as a filter's subset
    return tmp_path / "est.tum", tmp_path / "ref.tum"


def test_cli_align_reports_the_ape_of_the_aligned_estimate(tmp_path: Path, tum_pair: tuple[Path, Path]) -> None:
    est, ref = tum_pair
    none, se2 = _eval_json(tmp_path, est, ref, "none"), _eval_json(tmp_path, est, ref, "se2")
    assert none["align"] == "none" and "alignment" not in none
    assert se2["alignment"]["theta_rad"] == pytest.approx(-0.25, abs=0.01)
    assert se2["ape"]["ape_rmse_m"] < 0.1 < none["ape"]["ape_rmse_m"]
    # The APE RMSE is the position RMSE of the same errors.
    assert se2["ape"]["ape_rmse_m"] == pytest.approx(se2["summary"]["rmse_position_m"], rel=1e-12)


def test_cli_align_matches_evo_ape(tmp_path: Path, tum_pair: tuple[Path, Path]) -> None:
    pytest.importorskip("evo", reason="evo is not installed (pip install evo)")
    from evo.core import metrics, sync
    from evo.tools import file_interface

    est_path, ref_path = tum_pair
    for align in ("none", "se2"):
        ref = file_interface.read_tum_trajectory_file(str(ref_path))
        est = file_interface.read_tum_trajectory_file(str(est_path))
        ref, est = sync.associate_trajectories(ref, est)
        if align == "se2":
            est.align(ref, correct_scale=False)
        ape = metrics.APE(metrics.PoseRelation.translation_part)
        ape.process_data((ref, est))
        evo_stats = ape.get_all_statistics()
        ours = _eval_json(tmp_path, est_path, ref_path, align)["ape"]
        for key in ("rmse", "mean", "median", "std", "min", "max"):
            assert ours[f"ape_{key}_m"] == pytest.approx(evo_stats[key], abs=1e-9), (align, key)


def test_align_with_relations_is_refused(tmp_path: Path, tum_pair: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    est, _ = tum_pair
    (tmp_path / "r.relations").write_text("1000.0 1001.0 0 0 0 0 0 0\n")
    assert main(["eval", str(est), "--relations", str(tmp_path / "r.relations"), "--align", "se2"]) != 0
    assert "--align applies to --reference" in capsys.readouterr().err


def test_reference_errors_align_and_ape_statistics_agree_with_numpy() -> None:
    stamps, ref = _curve(120)
    est = _moved(ref, -0.1, 0.3, 0.2, 0.02, 3)
    res = reference_errors(stamps, est, stamps, ref, align="se2")
    assert res.alignment is not None
    e = np.hypot(*(res.alignment.apply(est)[:, :2] - ref[:, :2]).T)
    stats = ape_statistics(res.errors[:, :2])
    assert stats["ape_rmse_m"] == pytest.approx(np.sqrt(np.mean(e**2)))
    assert stats["ape_std_m"] == pytest.approx(np.std(e)) and stats["ape_max_m"] == pytest.approx(e.max())
