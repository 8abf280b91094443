"""``crlam bench``: the project's micro-benchmarks, measured in one run, as a JSON object.

Each figure is timed inside the Rust core on one thread (no Python in the timed loop). Ratios
between figures of the same run are machine-independent enough to compare across machines.
"""

from __future__ import annotations

import json
import os
import platform
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from crlam import __version__, _native

__all__ = ["BENCHMARKS", "BenchSpec", "machine_info", "run_benchmarks"]


@dataclass(frozen=True)
class BenchSpec:
    """A named figure and its workload size (full and quick)."""

    name: str
    size: int
    quick_size: int
    target_per_s: float | None = None


BENCHMARKS: tuple[BenchSpec, ...] = (
    # Issue 2 target: >= 300,000 CRM beam updates per second on one core.
    BenchSpec("crm_beam_updates_per_s", size=600, quick_size=40, target_per_s=300_000.0),
    BenchSpec("crm_beam_updates_per_s_paper_scan", size=400, quick_size=30),
    BenchSpec("raycast_cells_per_s", size=2_000_000, quick_size=100_000),
    # Issue 3 targets: >= 37 scans/s (the sensor's rate) for 100 particles x 1079 beams.
    BenchSpec("rbpf_clam_scans_per_s_1079x100", size=20, quick_size=2, target_per_s=37.0),
    BenchSpec("rbpf_clam_scans_per_s_180x30", size=100, quick_size=5),
    BenchSpec("rbpf_ogm_scans_per_s_180x30", size=100, quick_size=5),
)


def machine_info() -> dict[str, Any]:
    """CPU model, core count and versions, to record beside the figures."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "python": platform.python_version(),
        "platform": platform.platform(),
        "crlam": __version__,
    }


def run_benchmarks(names: list[str] | None = None, *, quick: bool = False, repeats: int = 3) -> dict[str, Any]:
    """Runs the benchmarks (best of ``repeats``) and returns ``{"figures": {...}, ...}``."""
    specs = [b for b in BENCHMARKS if names is None or b.name in names]
    unknown = set(names or []) - {b.name for b in BENCHMARKS}
    if unknown:
        raise ValueError(f"unknown benchmarks {sorted(unknown)}; known: {[b.name for b in BENCHMARKS]}")
    figures: dict[str, Any] = {}
    details: dict[str, Any] = {}
    for spec in specs:
        best: dict[str, Any] | None = None
        for _ in range(max(1, repeats)):
            r = _native.run_benchmark(spec.name, spec.quick_size if quick else spec.size)
            if best is None or r["per_second"] > best["per_second"]:
                best = r
        assert best is not None
        figures[spec.name] = round(float(best["per_second"]), 1)
        details[spec.name] = {**best, "target_per_s": spec.target_per_s, "repeats": repeats}
    if "crm_beam_updates_per_s" in figures and "raycast_cells_per_s" in figures:
        cells = details["crm_beam_updates_per_s"]["cells_per_ray"]
        # Cost of a CRM beam update relative to just walking its cells.
        figures["crm_update_over_traversal_cost"] = round(
            figures["raycast_cells_per_s"] / cells / figures["crm_beam_updates_per_s"], 2
        )
    return {
        "figures": figures,
        "details": details,
        "machine": machine_info(),
        "threads": 1,
        "quick": quick,
        "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
    }


def write_json(result: dict[str, Any], path: str | os.PathLike[str]) -> None:
    Path(path).write_text(json.dumps(result, indent=2, sort_keys=True) + "\n")
