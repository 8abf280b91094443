"""The command line: help everywhere, clean errors, and the commands end to end on small data."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from crlam.cli import build_parser, main

COMMANDS = ("demo", "simulate", "map", "bench")


@pytest.mark.parametrize("command", (None, *COMMANDS))
def test_help_on_every_command(command: str | None, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as e:
        main([command, "--help"] if command else ["--help"])
    assert e.value.code == 0
    assert "usage: crlam" in capsys.readouterr().out


def test_python_dash_m_works() -> None:
    r = subprocess.run([sys.executable, "-m", "crlam", "--help"], capture_output=True, text=True, check=True)
    assert all(c in r.stdout for c in COMMANDS)


def test_a_closed_output_pipe_ends_quietly() -> None:
    # `crlam data list | head -0`: the pipe has no reader before anything is written.
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "crlam", "data", "list"], stdout=write_end, stderr=subprocess.PIPE, timeout=120
        )
    finally:
        os.close(write_end)
    err = proc.stderr.decode()
    assert proc.returncode == 141, err
    assert "Traceback" not in err and "BrokenPipeError" not in err, err


def test_parser_knows_every_command() -> None:
    assert set(COMMANDS) <= set(build_parser()._subparsers._group_actions[0].choices)  # type: ignore[union-attr]


@pytest.mark.parametrize(
    "bad", (["map", "x.log", "--out", "o", "--resolution", "-1"], ["simulate", "--scans", "0", "--out", "o"])
)
def test_bad_values_are_usage_errors(bad: list[str]) -> None:
    with pytest.raises(SystemExit) as e:
        main(bad)
    assert e.value.code == 2


def test_map_of_a_missing_or_empty_log_is_a_clean_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["map", str(tmp_path / "nope.clf"), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert "nope.clf" in capsys.readouterr().err
    empty = tmp_path / "empty.clf"
    empty.write_text("")
    assert main(["map", str(empty), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert "empty.clf" in capsys.readouterr().err


def _digest(folder: Path) -> dict[str, str]:
    # The figures and the COMPLETE marker (it names the time and process) are not part of the data.
    return {
        p.name: hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.iterdir())
        if p.suffix != ".png" and p.name != "COMPLETE"
    }


def test_simulate_then_map_end_to_end(tmp_path: Path) -> None:
    a, b = tmp_path / "a", tmp_path / "b"
    for out in (a, b):
        assert main(["simulate", "--world", "office", "--scans", "60", "--seed", "3", "--out", str(out), "--quiet"]) == 0
    assert _digest(a) == _digest(b), "same seed must give the same bytes"
    assert {"log.clf", "groundtruth.tum", "odometry.tum", "world.pgm", "world.yaml", "simulation.json"} <= set(_digest(a))
    out = tmp_path / "map"
    assert main(["map", str(a / "log.clf"), "--out", str(out), "--quiet", "--resolution", "0.1"]) == 0
    for name in ("map.pgm", "map.yaml", "belief.npz", "ogm.pgm", "ogm.yaml", "map.png", "mapping.json"):
        assert (out / name).stat().st_size > 0, name
    summary = json.loads((out / "mapping.json").read_text())
    assert summary["n_scans"] == 60
    assert summary["update_stats"]["n_used"] > 0.5 * 60 * 1079


def test_bench_quick_prints_named_figures(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "--quick", "--repeats", "1", "--out", str(tmp_path / "b.json")]) == 0
    figures = json.loads(capsys.readouterr().out)
    assert figures["crm_beam_updates_per_s"] > 0 and figures["raycast_cells_per_s"] > 0
    # The windowed kernel's speed-up over the full sweep, both measured in this run.
    assert figures["rbpf_clam_windowed_over_full_ray"] == pytest.approx(
        figures["rbpf_clam_scans_per_s_1079x100"] / figures["rbpf_clam_scans_per_s_1079x100_full_ray"], rel=0.02
    )
    assert figures["rbpf_clam_over_ogm_1079x100"] == pytest.approx(
        figures["rbpf_clam_scans_per_s_1079x100"] / figures["rbpf_ogm_scans_per_s_1079x100"], rel=0.02
    )
    # The robust preset's filter against GMapping's setting of the baseline, in the same run.
    assert figures["rbpf_clam_scan_match_over_ogm_gmapping_180x30"] == pytest.approx(
        figures["rbpf_clam_scan_match_scans_per_s_180x30"] / figures["rbpf_ogm_gmapping_scans_per_s_180x30"], rel=0.02
    )
    full = json.loads((tmp_path / "b.json").read_text())
    assert full["machine"]["cores"] >= 1 and full["threads"] == 1
    # Whole `crlam slam` runs of the default preset and GMapping's setting on a log that has
    # readings beyond the default's 8 m map range, so its far-reading path is part of the figure.
    default, ogm = full["details"]["slam_default"], full["details"]["slam_ogm_gmapping"]
    assert default["returned_readings_beyond_8m"] > 0.1
    assert default["n_scans"] == ogm["n_scans"] == 200 and 0 < default["n_processed"] < 200
    assert default["settings"] == {"preset": "robust"} and ogm["settings"]["ogm_map"] == "gmapping"
    assert figures["slam_default_peak_rss_mb_sick"] == pytest.approx(default["peak_rss_mb"], abs=0.1)
    assert figures["slam_ogm_gmapping_peak_rss_mb_sick"] == pytest.approx(ogm["peak_rss_mb"], abs=0.1)
    assert default["peak_rss_mb"] >= default["filter_peak_rss_mb"] > 0
    assert figures["slam_default_command_over_filter_rss_sick"] == pytest.approx(
        default["peak_rss_mb"] / default["filter_peak_rss_mb"], abs=0.01
    )
    assert figures["slam_default_over_ogm_gmapping_sick"] == pytest.approx(
        figures["slam_default_scans_per_s_sick"] / figures["slam_ogm_gmapping_scans_per_s_sick"], rel=0.02
    )
    # The default once more on two threads: the same run (results never depend on the thread
    # count), timed against the one-thread run.
    two = full["details"]["slam_default_two_threads"]
    assert (two["threads"], default["threads"]) == (2, 1) and two["n_processed"] == default["n_processed"]
    assert figures["slam_default_two_threads_time_over_one_sick"] == pytest.approx(
        two["wall_time_s"] / default["wall_time_s"], abs=0.01
    )


@pytest.mark.slow
def test_demo_small_run_writes_a_complete_report(tmp_path: Path) -> None:
    assert main(["demo", "--out", str(tmp_path), "--scans", "150", "--quiet"]) == 0
    report = (tmp_path / "report.md").read_text()
    for link in ("world.png", "map_groundtruth_poses/map.png", "map_odometry_poses/map.png", "slam_map.png", "iig_trees.png"):
        assert link in report and (tmp_path / link).stat().st_size > 10_000
    results = json.loads((tmp_path / "results.json").read_text())
    s = results["scores"]["crm_true_poses"]
    assert s["free_accuracy"] > 0.95 and s["occupied_precision"] > 0.8
    assert results["scores"]["crm_odometry"]["accuracy"] <= s["accuracy"] + 1e-9
    # The whole-run SLAM with the default preset, and all five information functions.
    assert results["slam"]["preset"] == "robust" and results["slam"]["n_scans"] == 150
    assert results["slam"]["rmse_position_m"] < results["slam"]["odometry_rmse_position_m"]
    assert sorted(r["function"] for r in results["iig"]) == ["crmi", "gpvr", "ogmi", "ucrmi", "ugpvr"]
    assert not results["quick"] and "--quick" not in report


@pytest.mark.slow
def test_demo_quick_runs_every_step_on_a_short_log(tmp_path: Path) -> None:
    """``crlam demo --quick`` (the installation check of CI and of the installation guide)."""
    assert main(["demo", "--quick", "--out", str(tmp_path), "--quiet"]) == 0
    report = (tmp_path / "report.md").read_text()
    assert report.count("A quick run (`--quick`)") == 1 and "UCRMI with 10 particles" in report
    for link in ("world.png", "map_groundtruth_poses/map.png", "slam_map.png", "iig_trees.png", "exploration/exploration.png"):
        assert link in report and (tmp_path / link).stat().st_size > 10_000
    results = json.loads((tmp_path / "results.json").read_text())
    assert results["quick"] and results["n_scans"] == 300 and results["slam"]["n_scans"] == 300
    assert results["localization"]["n_scans"] == 60 and results["localization"]["particles"] == 10
    assert results["slam"]["rmse_position_m"] < results["slam"]["odometry_rmse_position_m"]
    assert (tmp_path / "simulation" / "log.clf").is_file()  # what CI then gives to crlam slam
