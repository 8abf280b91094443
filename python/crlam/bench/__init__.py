"""``crlam bench``: the project's benchmarks, measured in one run, as a JSON object.

- :mod:`crlam.bench.slam`: whole ``crlam slam`` runs on a simulated real-log-like workload;
- :mod:`crlam.bench.suite`: the micro-benchmarks of the Rust core, the information functions,
  the planner and the ROS 2 nodes, and the SLAM figures among them (:func:`run_benchmarks`).

The command itself is :mod:`crlam.cli.bench`.
"""

from __future__ import annotations

from crlam.bench.suite import BENCHMARKS, BenchSpec, machine_info, run_benchmarks, simd_info, write_json

__all__ = ["BENCHMARKS", "BenchSpec", "machine_info", "run_benchmarks", "simd_info", "write_json"]
