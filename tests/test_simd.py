"""The instruction-set level of the core's vector kernels (``CRLAM_SIMD``) and its report in ``crlam bench``."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from crlam import _native
from crlam.bench import simd_info

LEVELS = ("scalar", "avx2", "avx512")
INFO = "import json; from crlam.bench import simd_info; print(json.dumps(simd_info()))"


def _run(code: str, simd: str | None, *args: str) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k != "CRLAM_SIMD"}
    if simd is not None:
        env["CRLAM_SIMD"] = simd
    return subprocess.run([sys.executable, "-c", code, *args], env=env, capture_output=True, text=True, timeout=300)


def _supported(level: str) -> bool:
    return LEVELS.index(level) <= LEVELS.index(simd_info()["detected"])


def test_this_process_reports_a_supported_level_and_the_cpu_features() -> None:
    info = simd_info()
    assert info["level"] in LEVELS and info["detected"] in LEVELS
    assert _native.simd_level() == info["level"]
    assert LEVELS.index(info["level"]) <= LEVELS.index(info["detected"])
    assert isinstance(info["features"], list)
    if info["detected"] != "scalar":
        assert "avx2" in info["features"]


@pytest.mark.parametrize("level", LEVELS)
def test_crlam_simd_is_honoured_in_a_fresh_process(level: str) -> None:
    if not _supported(level):
        pytest.skip(f"{level} not supported by this CPU")
    r = _run(INFO, level)
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert info["level"] == level and info["requested"] == level and info["warning"] is None


def test_an_unknown_request_falls_back_to_the_detected_level_with_a_warning() -> None:
    r = _run(INFO, "sse9")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert info["level"] == simd_info()["detected"] and "not a level" in info["warning"]
    assert "CRLAM_SIMD=sse9" in r.stderr


def test_an_unsupported_request_falls_back_to_the_detected_level_with_a_warning() -> None:
    detected = simd_info()["detected"]
    if detected == "avx512":
        pytest.skip("this CPU supports every level: no unsupported request to make")
    r = _run(INFO, "avx512")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert info["level"] == detected and "does not support avx512" in info["warning"]
    assert "CRLAM_SIMD=avx512" in r.stderr


def test_bench_json_records_the_level_it_ran_at(tmp_path: Path) -> None:
    out = tmp_path / "bench.json"
    code = "import sys; from crlam.cli import main; sys.exit(main(sys.argv[1:]))"
    figures = ("crmi_us_per_pose", "rbpf_clam_scans_per_s_180x30")
    args = ("bench", "--quick", "--repeats", "1", "--only", *figures, "--out", str(out))
    r = _run(code, "scalar", *args)
    assert r.returncode == 0, r.stderr
    full = json.loads(out.read_text())
    assert full["simd"] == "scalar" and full["simd_requested"] == "scalar" and full["simd_warning"] is None
    assert full["simd_detected"] in LEVELS and isinstance(full["cpu_features"], list)
    assert full["figures"]["crmi_us_per_pose"] > 0
    assert "vector kernels at scalar" in r.stderr


GAINS = """
import json, sys
import numpy as np
from crlam.info import lattice_from_obstacles, make_function
n = 40
obstacle = np.zeros((n + 1, n + 1), dtype=bool)
obstacle[0, :] = obstacle[-1, :] = obstacle[:, 0] = obstacle[:, -1] = True
obstacle[20, 5:25] = True
obstacle[30:33, 30:33] = True
prior = lattice_from_obstacles(obstacle, None, 0.2, (0.0, 0.0))
xy = prior.node_positions(prior.free)[::53]
poses = np.column_stack([xy, np.linspace(0.0, 3.0, len(xy))])
out = {}
for name in ("crmi", "fsmi", "ucrmi"):
    f = make_function(name, n_particles=30)
    out[name] = [float(g).hex() for g in f.gains(f.make_state(prior.lattice), poses, seed=3)]
print(json.dumps(out))
"""


def test_every_level_gives_the_same_gains_bit_for_bit() -> None:
    # The information functions run the log, exp, Φ and KL kernels: each level, in a fresh
    # process, must give the scalar level's bits.
    results = {}
    for level in LEVELS:
        if not _supported(level):
            print(f"skipped: {level} not supported by this CPU")
            continue
        r = _run(GAINS, level)
        assert r.returncode == 0, r.stderr
        results[level] = json.loads(r.stdout)
    assert "scalar" in results
    for level, gains in results.items():
        assert gains == results["scalar"], level
    if len(results) < len(LEVELS):
        pytest.skip(f"compared {sorted(results)} only: the CPU lacks the other levels")


SLAM = """
import hashlib, sys
from pathlib import Path
from crlam.experiments.slam_run import run_slam_log
from crlam.slam import SlamConfig
log, out = Path(sys.argv[1]), Path(sys.argv[2])
run_slam_log(log, out, SlamConfig(particles=10, seed=2), max_scans=40, progress=False)
print(hashlib.sha256((out / "trajectory.tum").read_bytes()).hexdigest())
"""


def test_every_level_gives_the_same_slam_trajectory_bit_for_bit(tmp_path: Path) -> None:
    # RBPF-CLAM weighs its particles in the CRM lanes (AVX-512 or AVX2) or by the scalar kernel:
    # the same trajectory, byte for byte, at every level.
    from crlam.sim.simulate import SimulationConfig, simulate, write_simulation

    write_simulation(simulate(SimulationConfig(world="office", n_scans=60, seed=4)), tmp_path / "sim")
    digests = {}
    for level in LEVELS:
        if not _supported(level):
            print(f"skipped: {level} not supported by this CPU")
            continue
        r = _run(SLAM, level, str(tmp_path / "sim" / "log.clf"), str(tmp_path / level))
        assert r.returncode == 0, r.stderr
        digests[level] = r.stdout.strip()
    assert "scalar" in digests
    for level, digest in digests.items():
        assert digest == digests["scalar"], level
    if len(digests) < len(LEVELS):
        pytest.skip(f"compared {sorted(digests)} only: the CPU lacks the other levels")
