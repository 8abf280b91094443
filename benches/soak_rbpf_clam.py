"""Soak benchmark: RBPF-CLAM with many particles over a whole real log, memory sampled.

Runs the filter scan by scan (as ``crlam slam`` does) and samples, every ``--every`` scans, the
process's resident memory (``VmRSS``) and the bytes of the particles' maps (distinct tiles over
all particles, ``map_memory()``: the maps' own memory, shared tiles counted once). The figure of
merit is the memory that is *not* the maps, ``RSS - map bytes``: it must stay flat (no leak, no
per-scan growth outside the maps) while the maps grow with the explored area.

Writes a JSON file (samples, the figures below, CPU, SIMD level) and a PNG of both curves::

    python benches/soak_rbpf_clam.py --particles 1000 --out soak.json
    python benches/soak_rbpf_clam.py --log aces --max-scans 2000 --out soak-aces.json   # a stated part of a log

Figures: ``other_growth_mb`` (RSS - map bytes, last sample minus the first after the warm-up),
``other_slope_mb_per_1000_scans`` (least-squares slope of RSS - map bytes over the second half
of the samples), ``rss_minus_peak_map_*`` (the same against the maps' peak so far: the allocator
keeps freed memory for reuse and the maps' tile pool keeps up to 256 MB of dropped tiles, so the
resident memory follows the maps' peak), ``map_mb_final``, ``rss_mb_peak``, ``scans_per_s``.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np


def rss_mb() -> float:
    """Current resident memory of this process (MB; ``VmRSS``, Linux)."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    raise OSError("no VmRSS in /proc/self/status (Linux only)")


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def soak(log: Path, particles: int, preset: str, max_scans: int | None, every: int, seed: int) -> dict[str, Any]:
    from crlam import _native
    from crlam.experiments.slam_run import _scan_inputs, within_sensor_range
    from crlam.io.carmen import LaserScan
    from crlam.io.logs import open_log
    from crlam.slam import SlamConfig, SlamRun

    config = SlamConfig.from_preset(preset, particles=particles, seed=seed)
    run: SlamRun | None = None
    samples: list[dict[str, float]] = []
    t0 = time.perf_counter()
    n = 0
    for rec in open_log(log):
        if not isinstance(rec, LaserScan):
            continue
        if max_scans is not None and n >= max_scans:
            break
        if run is None:
            run = SlamRun(within_sensor_range(config, rec.max_range))
        angles, ranges = _scan_inputs(rec)
        run.step(rec.odom, angles, ranges, rec.laser_offset, rec.timestamp)
        n += 1
        if n % every == 0:
            assert run.filter is not None
            map_bytes, tiles, refs = run.filter.map_memory()
            samples.append(
                {
                    "scan": n,
                    "processed": run.filter.n_processed,
                    "wall_s": round(time.perf_counter() - t0, 2),
                    "rss_mb": round(rss_mb(), 2),
                    "map_mb": round(map_bytes / 2**20, 2),
                    "tiles": tiles,
                    "tile_refs": refs,
                }
            )
            print(
                f"scan {n}: rss {samples[-1]['rss_mb']:.0f} MB, maps {samples[-1]['map_mb']:.0f} MB, "
                f"{n / samples[-1]['wall_s']:.2f} scans/s",
                file=sys.stderr,
                flush=True,
            )
    wall = time.perf_counter() - t0
    if len(samples) < 4:
        raise SystemExit(f"only {len(samples)} samples: lower --every")
    other = np.array([s["rss_mb"] - s["map_mb"] for s in samples])
    # The allocator keeps freed memory for reuse (and the maps' tile pool keeps up to 256 MB of
    # dropped tiles), so the resident memory follows the maps' *peak* so far, not their size now.
    peak_map = np.maximum.accumulate(np.array([s["map_mb"] for s in samples]))
    beyond_peak = np.array([s["rss_mb"] for s in samples]) - peak_map
    scans = np.array([s["scan"] for s in samples], dtype=float)
    warm = max(1, len(samples) // 10)  # the first tenth: imports, the first maps, allocator warm-up
    half = len(samples) // 2
    slope = float(np.polyfit(scans[half:], other[half:], 1)[0]) * 1000.0
    slope_peak = float(np.polyfit(scans[half:], beyond_peak[half:], 1)[0]) * 1000.0
    return {
        "log": str(log),
        "scans": n,
        "preset": preset,
        "particles": particles,
        "seed": seed,
        "processed": samples[-1]["processed"],
        "wall_s": round(wall, 1),
        "scans_per_s": round(n / wall, 3),
        "rss_mb_peak": float(max(s["rss_mb"] for s in samples)),
        "map_mb_final": samples[-1]["map_mb"],
        "other_mb_after_warmup": round(float(other[warm]), 1),
        "other_mb_final": round(float(other[-1]), 1),
        "other_growth_mb": round(float(other[-1] - other[warm]), 1),
        "other_slope_mb_per_1000_scans": round(slope, 2),
        "rss_minus_peak_map_mb_final": round(float(beyond_peak[-1]), 1),
        "rss_minus_peak_map_mb_max": round(float(beyond_peak.max()), 1),
        "rss_minus_peak_map_slope_mb_per_1000_scans": round(slope_peak, 2),
        "cpu": cpu_name(),
        "simd": _native.simd_level(),
        "samples": samples,
    }


def plot(result: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = result["samples"]
    scans = [x["scan"] for x in s]
    fig, ax = plt.subplots(figsize=(8, 4.2), constrained_layout=True)
    ax.plot(scans, [x["rss_mb"] for x in s], label="resident memory (RSS)")
    ax.plot(scans, [x["map_mb"] for x in s], label="particles' maps (distinct tiles)")
    ax.plot(scans, [x["rss_mb"] - x["map_mb"] for x in s], label="RSS - maps")
    peak = np.maximum.accumulate([x["map_mb"] for x in s])
    ax.plot(scans, peak, ":", label="maps' peak so far")
    ax.set_xlabel("scan")
    ax.set_ylabel("MB")
    ax.set_title(f"RBPF-CLAM soak: {Path(result['log']).name}, {result['particles']} particles ({result['preset']})")
    ax.grid(alpha=0.3)
    ax.legend(loc="center right", fontsize=8)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--log", default="intel", help="a CARMEN log, or a dataset name: intel, aces (default: intel)")
    p.add_argument("--particles", type=int, default=1000)
    p.add_argument("--preset", default="robust")
    p.add_argument("--max-scans", type=int, default=None, help="only the first N scans (default: the whole log)")
    p.add_argument("--every", type=int, default=100, help="sample the memory every N scans (default: 100)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", required=True, help="JSON result (a PNG is written beside it)")
    args = p.parse_args()
    log = Path(args.log)
    if not log.is_file():
        from crlam.io.fetch import find_dataset

        log = find_dataset(args.log)
    result = soak(log, args.particles, args.preset, args.max_scans, args.every, args.seed)
    out = Path(args.out)
    out.write_text(json.dumps(result, indent=2) + "\n")
    plot(result, out.with_suffix(".png"))
    summary = {k: v for k, v in result.items() if k != "samples"}
    print(json.dumps(summary, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
