"""Trajectory metrics: SE(2) identities, the fill rule, and the README oracles on the real logs."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crlam.errors import CrlamError, DataFormatError
from crlam.eval.trajectory import (
    ScanIndex,
    aggregate_runs,
    align_to_raw,
    fill_trajectory,
    index_scans,
    reference_errors,
    relations_error,
)
from crlam.io.relations import Relations, read_relations
from crlam.pose import between, compose, wrap_angle
from crlam.slam.fill import fill_skipped

coord = st.floats(-100.0, 100.0, allow_nan=False)
angle = st.floats(-10.0, 10.0, allow_nan=False)
pose = st.tuples(coord, coord, angle).map(lambda t: np.array(t, dtype=np.float64))
small = st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-3.0, 3.0)).map(lambda t: np.array(t))


def rels(t1: list[float], t2: list[float], delta: object) -> Relations:
    return Relations(
        t1=np.array(t1, dtype=np.float64), t2=np.array(t2, dtype=np.float64), delta=np.array(delta, dtype=np.float64)
    )


def random_walk(n: int, seed: int = 0) -> np.ndarray:
    """A trajectory of ``n`` poses, shape (n, 3), built by composing random increments."""
    rng = np.random.default_rng(seed)
    steps = np.column_stack([rng.uniform(0.0, 0.5, n), rng.normal(0, 0.05, n), rng.normal(0, 0.3, n)])
    out = np.zeros((n, 3))
    for i in range(1, n):
        out[i] = compose(out[i - 1], steps[i])
    return out


def exact_relations(stamps: np.ndarray, poses: np.ndarray, pairs: int = 60, seed: int = 1) -> Relations:
    rng = np.random.default_rng(seed)
    i, j = rng.integers(0, len(stamps), pairs), rng.integers(0, len(stamps), pairs)
    return Relations(t1=stamps[i], t2=stamps[j], delta=between(poses[i], poses[j]))


# ------------------------------------------------------------------------------- identities


def test_exact_relations_give_zero_error() -> None:
    stamps, poses = 100.0 + 0.1 * np.arange(200), random_walk(200)
    errs = relations_error(stamps, poses, exact_relations(stamps, poses))
    assert errs.n == 60 and errs.n_missing == 0
    np.testing.assert_allclose(errs.trans, 0.0, atol=1e-9)
    np.testing.assert_allclose(errs.rot, 0.0, atol=1e-7)


def test_a_rigid_transform_of_the_whole_trajectory_gives_zero_error() -> None:
    stamps, poses = 100.0 + 0.1 * np.arange(200), random_walk(200, seed=4)
    rel = exact_relations(stamps, poses)
    moved = compose(np.array([12.0, -40.0, 2.5]), poses)
    s = relations_error(stamps, moved, rel).summary()
    assert s["trans_mean_m"] < 1e-9 and s["rot_mean_deg"] < 1e-7


def test_trajectory_order_does_not_matter_and_lookup_is_by_value() -> None:
    stamps, poses = 100.0 + 0.1 * np.arange(200), random_walk(200, seed=5)
    rel = exact_relations(stamps, poses)
    noisy = compose(poses, np.random.default_rng(2).normal(0, 0.05, (200, 3)))
    perm = np.random.default_rng(3).permutation(200)
    a = relations_error(stamps, noisy, rel)
    b = relations_error(stamps[perm], noisy[perm], rel)
    np.testing.assert_array_equal(a.trans, b.trans)
    np.testing.assert_array_equal(a.rot, b.rot)


def test_summary_is_mean_and_sample_std_of_errors_and_their_squares() -> None:
    stamps, poses = np.arange(50.0), random_walk(50, seed=6)
    rel = exact_relations(stamps, poses, pairs=30)
    errs = relations_error(stamps, compose(poses, np.random.default_rng(7).normal(0, 0.1, (50, 3))), rel)
    s = errs.summary()
    assert s["n"] == 30
    assert s["trans_std_m"] == pytest.approx(np.std(errs.trans, ddof=1))
    assert s["rot_mean_deg"] == pytest.approx(np.mean(errs.rot))
    assert s["trans2_mean_m2"] == pytest.approx(np.mean(errs.trans**2))
    assert s["rot2_std_deg2"] == pytest.approx(np.std(errs.rot**2, ddof=1))
    # A relation whose rotation error is 0.1 rad reports 5.73 deg (the metric is in degrees).
    one = rels(t1=[0.0], t2=[1.0], delta=[[1.0, 0.0, 0.0]])
    r = relations_error([0.0, 1.0], np.array([[0, 0, 0], [1.0, 0.0, 0.1]]), one)
    assert r.rot[0] == pytest.approx(np.degrees(0.1)) and np.isnan(r.summary()["rot_std_deg"])


@settings(max_examples=200, deadline=None)
@given(pose, pose, pose, small)
def test_relation_error_properties(a: np.ndarray, b: np.ndarray, t: np.ndarray, e: np.ndarray) -> None:
    rel = rels(t1=[1.0], t2=[2.0], delta=between(a, b)[None])
    # Exact relation: zero; invariant under a rigid motion of both poses.
    assert relations_error([1.0, 2.0], np.stack([a, b]), rel).trans[0] < 1e-6
    # Perturbing the second pose on the right by e gives exactly E = e.
    r = relations_error([1.0, 2.0], np.stack([compose(t, a), compose(compose(t, b), e)]), rel)
    assert r.trans[0] == pytest.approx(np.hypot(e[0], e[1]), abs=1e-6)
    assert r.rot[0] == pytest.approx(np.degrees(abs(float(wrap_angle(e[2])))), abs=1e-5)


def test_missing_stamps_raise_by_default_or_are_counted() -> None:
    stamps, poses = np.arange(10.0), random_walk(10)
    rel = rels(t1=[1.0, 2.0, 3.0], t2=[2.0, 99.5, 4.0], delta=np.zeros((3, 3)))
    with pytest.raises(DataFormatError, match="99.500000"):
        relations_error(stamps, poses, rel)
    errs = relations_error(stamps, poses, rel, on_missing="skip")
    assert errs.n == 2 and errs.n_missing == 1 and errs.missing_stamps.tolist() == [99.5]
    with pytest.raises(DataFormatError, match="none of the"):
        relations_error(stamps, poses, rels(t1=[50.0], t2=[51.0], delta=np.zeros((1, 3))), on_missing="skip")


def test_stamp_tolerance_and_ambiguous_duplicates() -> None:
    stamps, poses = 1000.0 + np.arange(10.0), random_walk(10)
    rel = rels(t1=[1001.0], t2=[1002.0], delta=between(poses[1], poses[2])[None])
    assert relations_error(stamps + 4e-7, poses, rel).trans[0] < 1e-9
    with pytest.raises(DataFormatError):
        relations_error(stamps + 4e-6, poses, rel)
    dup_t, dup_p = np.append(stamps, 1001.0), np.vstack([poses, poses[5]])
    with pytest.raises(DataFormatError, match="more than once"):
        relations_error(dup_t, dup_p, rel)
    # A duplicate with the same pose is harmless.
    assert relations_error(np.append(stamps, 1001.0), np.vstack([poses, poses[1]]), rel).n == 1


def test_reference_errors_of_a_trajectory_against_itself_are_zero() -> None:
    stamps, poses = np.arange(30.0), random_walk(30)
    s = reference_errors(stamps, poses, stamps[::-1], poses[::-1]).summary()
    assert s["n"] == 30 and s["n_unmatched"] == 0
    assert all(s[k] == 0.0 for k in ("mae_x_m", "mae_y_m", "mae_theta_rad", "rmse_position_m"))


def test_reference_errors_values_and_heading_wrap() -> None:
    ref = np.array([[0.0, 0.0, np.pi - 0.01], [1.0, 1.0, 0.0], [2.0, 0.0, 0.0]])
    est = ref + np.array([[0.3, 0.4, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    est[0, 2] = -np.pi + 0.01  # 0.02 rad from the reference heading, across the wrap
    res = reference_errors([0.0, 1.0, 2.0, 3.0], np.vstack([est, [[9, 9, 9]]]), [0.0, 1.0, 2.0], ref)
    s = res.summary()
    assert res.n_unmatched == 1 and s["n"] == 3
    assert s["mae_x_m"] == pytest.approx(0.1) and s["mae_y_m"] == pytest.approx(0.4 / 3)
    assert s["mae_theta_rad"] == pytest.approx(0.02 / 3) and s["mae_theta_deg"] == pytest.approx(np.degrees(0.02 / 3))
    assert s["rmse_position_m"] == pytest.approx(np.sqrt(0.25 / 3))
    with pytest.raises(DataFormatError):
        reference_errors([5.0], [[0, 0, 0]], [0.0], [[0, 0, 0]])


def test_aggregate_runs_mean_and_sample_std() -> None:
    runs = [{"n": 10, "rmse_position_m": 1.0, "note": "x"}, {"n": 10, "rmse_position_m": 3.0, "note": "y"}]
    agg = aggregate_runs(runs)
    assert agg["rmse_position_m"] == {"mean": 2.0, "std": pytest.approx(np.sqrt(2.0)), "n_runs": 2}
    assert "note" not in agg and np.isnan(aggregate_runs(runs[:1])["n"]["std"])


# ---------------------------------------------------------------------------- filling


def write_log(path: Path, stamps: list[float], odom: np.ndarray, ranges: list[list[float]] | None = None) -> Path:
    """A minimal FLASER log: one scan per stamp, file order as given, odom == pose field."""
    rows = ["# synthetic", "PARAM robot_frontlaser_offset 0.0 nohost 0"]
    for k, (t, o) in enumerate(zip(stamps, odom)):
        r = ranges[k] if ranges else [1.0 + k, 2.0, 3.0]
        p = " ".join(f"{v:.9f}" for v in o)
        rows.append(f"FLASER {len(r)} {' '.join(map(str, r))} {p} {p} {t:.6f} nohost {0.5 * k:.6f}")
        rows.append(f"ODOM {p} 0 0 0 {t:.6f} nohost {0.5 * k:.6f}")
    path.write_text("\n".join(rows) + "\n")
    return path


def test_fill_with_exact_odometry_recovers_every_pose(tmp_path: Path) -> None:
    true = random_walk(40, seed=8)
    odom = compose(np.array([5.0, -3.0, 1.0]), true)  # exact odometry in its own frame
    stamps = (200.0 + 0.1 * np.random.default_rng(9).permutation(40)).tolist()  # not sorted
    log = write_log(tmp_path / "raw.clf", stamps, odom)
    keep = np.arange(7, 40, 5)
    filled = fill_trajectory(np.array(stamps)[keep], true[keep], log)
    assert len(filled) == 40 and filled.n_processed == len(keep) and not filled.filled[keep].any()
    np.testing.assert_array_equal(filled.stamps, stamps)  # file order, never sorted
    d = filled.poses - true
    d[:, 2] = wrap_angle(d[:, 2])
    np.testing.assert_allclose(d, 0.0, atol=1e-7)  # includes the 7 back-filled scans
    assert "backwards" in filled.rule and "file order" in filled.rule


def test_interpolated_fill_is_crlam_fills_rule_after_the_first_processed_scan(tmp_path: Path) -> None:
    true = random_walk(40, seed=3)
    odom = compose(np.array([5.0, -3.0, 1.0]), true)
    stamps = (100.0 + 0.1 * np.arange(40)).tolist()
    log = write_log(tmp_path / "raw.clf", stamps, odom)
    keep = np.arange(4, 40, 6)
    # Exact odometry: nothing to correct, every pose is recovered either way.
    exact = fill_trajectory(np.array(stamps)[keep], true[keep], log, fill="interpolate")
    np.testing.assert_allclose(exact.poses, fill_trajectory(np.array(stamps)[keep], true[keep], log).poses, atol=1e-9)
    # Estimates that disagree with the odometry: after the first processed scan the rule of crlam.slam.fill.
    est = true[keep] + np.random.default_rng(4).normal(0.0, 0.05, (keep.size, 3))
    got = fill_trajectory(np.array(stamps)[keep], est, log, fill="interpolate", updates=(0.5, 0.25))
    processed = np.zeros(40, dtype=bool)
    processed[keep] = True
    want = fill_skipped(est, processed[4:], odom[4:], np.array(stamps[4:]), "interpolate", 0.5, 0.25)
    np.testing.assert_allclose(got.poses[4:], want, atol=1e-9)
    np.testing.assert_allclose(got.poses[:4], fill_trajectory(np.array(stamps)[keep], est, log).poses[:4], atol=1e-12)
    assert not np.allclose(got.poses[5:10], fill_trajectory(np.array(stamps)[keep], est, log).poses[5:10])


def test_fill_anchors_on_the_previous_scan_in_file_order_not_in_time(tmp_path: Path) -> None:
    odom = np.array([[0.0, 0, 0], [1.0, 0, 0], [2.0, 0, 0.5], [3.0, 1, 0.5], [4.0, 1, 1.0]])
    stamps = [1.0, 3.0, 2.0, 4.0, 5.0]  # the third scan is older than the second
    log = write_log(tmp_path / "raw.clf", stamps, odom)
    est_t = np.array([1.0, 3.0])
    est_p = np.array([[10.0, 0, 0], [20.0, 5.0, 0.3]])  # deliberately inconsistent with odometry
    f = fill_trajectory(est_t, est_p, log)
    np.testing.assert_allclose(f.poses[2], compose(est_p[1], between(odom[1], odom[2])))
    np.testing.assert_allclose(f.poses[4], compose(est_p[1], between(odom[1], odom[4])))
    assert f.filled.tolist() == [False, False, True, True, True]


def test_fill_without_backfill_omits_leading_scans_and_counts_strays(tmp_path: Path) -> None:
    odom = random_walk(10, seed=11)
    stamps = (10.0 + np.arange(10.0)).tolist()
    log = write_log(tmp_path / "raw.clf", stamps, odom)
    f = fill_trajectory([13.0, 16.0, 99.0], odom[[3, 6, 0]], log, backfill=False)
    assert len(f) == 7 and f.n_omitted == 3 and f.n_unmatched_estimates == 1 and f.stamps[0] == 13.0
    assert "left out" in f.rule
    with pytest.raises(DataFormatError, match="none of the"):
        fill_trajectory([0.5], [[0, 0, 0]], log)
    index = index_scans(log)
    assert isinstance(index, ScanIndex) and len(index) == 10
    assert len(fill_trajectory([13.0], odom[[3]], index)) == 10


def test_align_a_log_with_other_stamps_to_the_raw_log_by_readings(tmp_path: Path) -> None:
    odom = random_walk(6, seed=12)
    raw = index_scans(write_log(tmp_path / "raw.clf", [50.0 + k for k in range(6)], odom))
    ranges = [[1.0 + k, 2.0, 3.0] for k in (1, 3, 4)]
    corrected = compose(np.array([0.1, 0.2, 0.3]), odom[[1, 3, 4]])
    # Logger-like stamps; the second coincides with the ipc stamp of another raw scan (52.0).
    log = index_scans(write_log(tmp_path / "cor.log", [0.5, 52.0, 2.0], corrected, ranges))
    al = align_to_raw(log, raw)
    assert al.stamps.tolist() == [51.0, 53.0, 54.0] and al.n_by_ranges == 3 and al.n_by_stamp == 0
    np.testing.assert_allclose(al.poses, corrected)
    assert align_to_raw(raw, raw).n_by_stamp == 6
    stray = index_scans(write_log(tmp_path / "stray.log", [7.0], odom[:1], [[9.0, 9.0, 9.0]]))
    with pytest.raises(DataFormatError, match="line 3"):
        align_to_raw(stray, raw)


# ------------------------------------------------------------------------- real data oracles


def printed(x: float, digits: int) -> str:
    return f"{x:.{digits}f}"


def agrees_with_printed(x: float, want: str, digits: int) -> bool:
    """``x`` rounds to ``want``, allowing 1e-5 beyond the half unit: the README's ACES raw-odometry
    std "2.676" is 2.675492 double-rounded (2.675492 -> 2.6755 -> 2.676); every other oracle
    value rounds exactly."""
    return printed(x, digits) == want or abs(x - float(want)) <= 0.5 * 10.0**-digits + 1e-5


@pytest.fixture(scope="module")
def real(data_dir: Path) -> dict[str, object]:
    """Indexes of the raw and corrected logs and the relations, read once (about 5 s)."""
    out: dict[str, object] = {}
    for name in ("aces", "intel"):
        out[f"{name}-raw"] = index_scans(data_dir / name / f"{name}.clf.bz2")
        out[f"{name}-corrected"] = index_scans(data_dir / "corrected" / f"{name}-corrected.log.gz")
        out[f"{name}-relations"] = read_relations(data_dir / name / f"{name}.relations")
    return out


RAW_ODOMETRY = {  # README: mean +- std, m and deg, to the printed digits
    "aces": (("0.549", 3), ("2.676", 3), ("2.33", 2), ("6.51", 2)),
    "intel": (("7.37", 2), ("14.35", 2), ("39.2", 1), ("53.8", 1)),
}
CORRECTED = {
    "aces": (("0.0493", 4), ("0.0487", 4), ("1.06", 2), ("1.50", 2), 1277),
    "intel": (("0.0424", 4), ("0.0367", 4), ("1.92", 2), ("1.67", 2), 2984),
}
KEYS = ("trans_mean_m", "trans_std_m", "rot_mean_deg", "rot_std_deg")


@pytest.mark.realdata
@pytest.mark.parametrize("name", ("aces", "intel"))
def test_raw_odometry_oracle(real: dict[str, object], name: str) -> None:
    raw = real[f"{name}-raw"]
    rel = real[f"{name}-relations"]
    assert isinstance(raw, ScanIndex) and isinstance(rel, Relations)
    # Every relation stamp is the exact ipc_timestamp of a raw scan: tolerance 0 finds them all.
    s = relations_error(raw.stamps, raw.odom, rel, tolerance=0.0).summary()
    assert s["n"] == len(rel) and s["n_missing"] == 0
    for key, (want, digits) in zip(KEYS, RAW_ODOMETRY[name]):
        assert agrees_with_printed(s[key], want, digits), (key, s[key])
    if name == "aces":
        assert printed(s["trans_std_m"], 4) == "2.6755"


@pytest.mark.realdata
@pytest.mark.parametrize("name", ("aces", "intel"))
def test_gmapping_corrected_with_odometry_fill_oracle(real: dict[str, object], name: str) -> None:
    raw, cor, rel = real[f"{name}-raw"], real[f"{name}-corrected"], real[f"{name}-relations"]
    assert isinstance(raw, ScanIndex) and isinstance(cor, ScanIndex) and isinstance(rel, Relations)
    al = align_to_raw(cor, raw)
    assert al.n_by_ranges == len(cor)  # the corrected logs carry logger stamps, not ipc stamps
    # README oracle: forward fill only; relations on scans before the first processed one skipped.
    f = fill_trajectory(al.stamps, al.poses, raw, backfill=False)
    s = relations_error(f.stamps, f.poses, rel, on_missing="skip", tolerance=0.0).summary()
    *want, n = CORRECTED[name]
    assert s["n"] == n
    for key, (value, digits) in zip(KEYS, want):
        assert printed(s[key], digits) == value, key
    # With the backward fill every relation is evaluated (ACES: 1279, 0.0492 +- 0.0487 m).
    g = fill_trajectory(al.stamps, al.poses, raw)
    s2 = relations_error(g.stamps, g.poses, rel, tolerance=0.0).summary()
    assert s2["n"] == len(rel) and abs(s2["trans_mean_m"] - s["trans_mean_m"]) < 2e-4
    # crlam slam's default fill (interpolate) on the same poses: GMapping's trajectory gains too,
    # so comparisons use one rule for both (docs/results/real-logs.md).
    h = fill_trajectory(al.stamps, al.poses, raw, backfill=False, fill="interpolate")
    s3 = relations_error(h.stamps, h.poses, rel, on_missing="skip", tolerance=0.0).summary()
    assert s3["n"] == n and printed(s3["trans_mean_m"], 4) == INTERPOLATED[name]
    assert "share of the next processed pose's correction" in h.rule


INTERPOLATED = {"aces": "0.0450", "intel": "0.0279"}


def eval_parser() -> argparse.ArgumentParser:
    from crlam.cli.eval import add_parser as add_eval_parser

    parser = argparse.ArgumentParser(prog="crlam")
    add_eval_parser(parser.add_subparsers(dest="command"))
    return parser


@pytest.mark.realdata
def test_cli_eval_reproduces_the_aces_oracle(data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "aces.json"
    args_list = [
        "eval",
        str(data_dir / "corrected" / "aces-corrected.log.gz"),
        "--relations",
        str(data_dir / "aces" / "aces.relations"),
        "--raw-log",
        str(data_dir / "aces" / "aces.clf.bz2"),
        "--no-backfill",
        "--out",
        str(out),
        "--force",
    ]
    args = eval_parser().parse_args(args_list)
    assert args.func(args) == 0
    text = capsys.readouterr().out
    assert "fill rule" in text and "file order" in text and "identical range readings" in text
    report = json.loads(out.read_text())
    s = report["summary"]
    assert s["n"] == 1277 and s["n_missing"] == 2 and report["fill"]["n_processed"] == 440
    assert [printed(s[k], d) for k, d in zip(KEYS, (4, 4, 2, 2))] == ["0.0493", "0.0487", "1.06", "1.50"]
    assert "between(odom_last_processed, odom_now)" in report["fill"]["rule"]
    # The same with crlam slam's fill rule.
    args = eval_parser().parse_args([*args_list, "--fill", "interpolate", "--fill-updates", "0.5", "0.25"])
    assert args.func(args) == 0
    report = json.loads(out.read_text())
    assert report["fill"]["fill"] == "interpolate" and printed(report["summary"]["trans_mean_m"], 4) == "0.0450"
    assert "0.5 m and turned / 0.25 rad" in report["fill"]["rule"]
    with pytest.raises(SystemExit):
        eval_parser().parse_args([*args_list, "--fill-updates", "0", "0.5"])


def test_cli_eval_tum_against_reference_and_clean_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from crlam.io.tum import write_tum

    stamps, poses = 10.0 + np.arange(20.0), random_walk(20, seed=13)
    write_tum(tmp_path / "gt.tum", stamps, poses)
    write_tum(tmp_path / "est.tum", stamps, poses + np.array([0.1, 0.0, 0.0]))
    args = eval_parser().parse_args(
        ["eval", str(tmp_path / "est.tum"), "--reference", str(tmp_path / "gt.tum"), "--out", str(tmp_path / "r.json")]
    )
    assert args.func(args) == 0
    assert "RMSE position (m)  0.1" in capsys.readouterr().out
    assert json.loads((tmp_path / "r.json").read_text())["summary"]["mae_x_m"] == pytest.approx(0.1)
    rel = tmp_path / "r.relations"
    rel.write_text("10.000000 99.000000 1 0 0 0 0 0\n")
    args = eval_parser().parse_args(["eval", str(tmp_path / "est.tum"), "--relations", str(rel)])
    with pytest.raises(CrlamError, match="99.000000.*--skip-missing"):
        args.func(args)
    with pytest.raises(SystemExit):  # --relations and --reference are exclusive, one is required
        eval_parser().parse_args(["eval", "x.tum"])
