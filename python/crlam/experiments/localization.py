"""A short localization comparison on a simulated log, for the demo: RBPF-CLAM (and RBPF-OGM
when available) against raw odometry, with errors against the exact ground truth."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from crlam import _native
from crlam.eval.trajectory import ReferenceErrors, reference_errors
from crlam.experiments.known_poses import unknown_mask
from crlam.mapping import ConfidenceRichMap
from crlam.sim.simulate import SimulatedLog
from crlam.slam import SlamConfig, SlamRun

__all__ = ["LocalizationResult", "compare_localization", "available_methods"]


def available_methods() -> tuple[str, ...]:
    """Filters this build provides."""
    return ("ogm", "clam") if hasattr(_native, "OgmFilter") else ("clam",)


@dataclass
class LocalizationResult:
    """Per-method trajectories and errors over the first ``n_scans`` scans."""

    n_scans: int
    particles: int
    estimates: dict[str, NDArray[np.float64]]
    errors: dict[str, ReferenceErrors]
    wall_time_s: dict[str, float]
    clam_run: SlamRun

    def table(self) -> list[dict[str, Any]]:
        rows = []
        for name, e in self.errors.items():
            s = e.summary()
            rows.append(
                {
                    "method": name,
                    **{k: s[k] for k in ("mae_x_m", "mae_y_m", "mae_theta_deg", "rmse_position_m")},
                    "wall_time_s": self.wall_time_s.get(name, 0.0),
                }
            )
        return rows


def compare_localization(
    log: SimulatedLog, *, n_scans: int = 300, particles: int = 30, seed: int = 0, progress: bool = True
) -> LocalizationResult:
    """Runs each available filter on the first ``n_scans`` scans of a simulated log."""
    n = min(n_scans, log.n_scans)
    angles = log.sensor.angles
    ranges = np.where(log.ranges[:n] >= log.sensor.max_range, np.inf, log.ranges[:n])
    truth_t, truth = log.timestamps[:n], log.poses[:n]
    estimates = {"odometry": log.odometry[:n]}
    walls: dict[str, float] = {}
    clam_run: SlamRun | None = None
    for method in available_methods():
        cfg = SlamConfig(method=method, particles=particles, seed=seed, resolution=0.2, max_range=log.sensor.max_range)
        run = SlamRun(cfg)
        t0 = time.perf_counter()
        for k in tqdm(range(n), desc=f"RBPF-{method.upper()}", unit="scan", disable=not progress, leave=False, mininterval=1.0):
            run.step(log.odometry[k], angles, ranges[k], np.zeros(3), float(log.timestamps[k]))
        name = f"RBPF-{method.upper()}"
        walls[name] = time.perf_counter() - t0
        estimates[name] = run.trajectory()[1]
        if method == "clam":
            clam_run = run
    assert clam_run is not None
    errors = {k: reference_errors(truth_t, v, truth_t, truth) for k, v in estimates.items()}
    return LocalizationResult(n, particles, estimates, errors, walls, clam_run)


def save_localization_figures(res: LocalizationResult, truth: NDArray[np.float64], out: Path) -> tuple[Path, Path]:
    from crlam.viz.trajectories import save_error_figure, save_trajectories_on_map

    crm = res.clam_run.best_map()
    assert isinstance(crm, ConfidenceRichMap)
    mean, _, ent = crm.layers()
    trajs = {"ground truth": truth[: res.n_scans], **res.estimates}
    a = save_trajectories_on_map(
        out / "localization_trajectories.png",
        mean,
        unknown_mask(crm, ent),
        trajs,
        title=f"Localization, first {res.n_scans} scans ({res.particles} particles): on the RBPF-CLAM map",
    )
    b = save_error_figure(out / "localization_errors.png", list(res.errors.items()), title="Localization error against time")
    return a, b
