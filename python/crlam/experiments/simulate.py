"""``crlam simulate``: a simulated log folder (CARMEN log, ground truth, world, figure)."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

from crlam.sim.simulate import SimulationConfig, simulate, write_simulation

__all__ = ["simulate_to_folder"]


def simulate_to_folder(
    world: str,
    n_scans: int,
    seed: int,
    out_dir: str | os.PathLike[str],
    *,
    sensor: str = "paper",
    progress: bool = True,
    figure: bool = True,
) -> dict[str, Any]:
    """Simulates and writes ``log.clf``, ``groundtruth.tum``, ``odometry.tum``, ``world.pgm``/
    ``.yaml``, ``simulation.json`` and (optionally) ``trajectory.png``. Returns a summary.

    Every file but the figure is a pure function of the arguments: same seed, same bytes.
    """
    t0 = time.perf_counter()
    cfg = SimulationConfig(world=world, n_scans=n_scans, seed=seed, sensor=sensor)
    if progress:
        print(f"simulating {n_scans} scans in {world!r} (seed {seed}) ...", flush=True)
    log = simulate(cfg)
    paths = write_simulation(log, out_dir)
    if figure:
        from crlam.viz.maps import save_world_figure

        paths["figure"] = save_world_figure(
            Path(out_dir) / "trajectory.png",
            log.world.occupied,
            log.world.origin,
            log.world.resolution,
            trajectory=log.poses,
            title=f"{log.world.name}: {log.n_scans} scans, ground-truth trajectory",
        )
    summary = json.loads(Path(paths["json"]).read_text())
    return {
        "out": str(out_dir),
        "n_scans": log.n_scans,
        "path_length_m": summary["path_length_m"],
        "duration_s": summary["duration_s"],
        "wall_time_s": round(time.perf_counter() - t0, 2),
        "files": {k: str(v) for k, v in paths.items()},
    }
