"""The figure of a localization run: the estimate over the map, and the particle set against time."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from crlam.viz.maps import metric_axes, save_figure, show_occupancy  # noqa: E402

if TYPE_CHECKING:
    from crlam.localize import Localizer

__all__ = ["save_localization_figure", "save_trials_figure"]


def save_localization_figure(
    path: str | os.PathLike[str],
    loc: Localizer,
    *,
    reference: NDArray[np.float64] | None = None,
    title: str = "",
    dpi: int = 150,
) -> Path:
    """Left: the map's expected occupancy with the estimated trajectory (grey before convergence,
    red after), the start, the convergence point and the final particles. Right: the particle
    count (before resampling) and the heaviest cluster's position spread against time."""
    mean = loc.map.expected_occupancy()
    stamps, poses = loc.trajectory()
    t = stamps - stamps[0]
    conv = loc.convergence
    split = len(poses) if conv is None else conv.scan_index
    fig = plt.figure(figsize=(13, 6.2), constrained_layout=True)
    grid = fig.add_gridspec(2, 2, width_ratios=(1.35, 1))
    ax = fig.add_subplot(grid[:, 0])
    show_occupancy(ax, mean.values, mean.extent)
    if reference is not None:
        ax.plot(reference[:, 0], reference[:, 1], color="tab:blue", linewidth=0.8, alpha=0.8, label="reference")
    if split > 0:
        ax.plot(poses[:split, 0], poses[:split, 1], color="0.55", linewidth=0.8, label="estimate before convergence")
    if split < len(poses):
        ax.plot(poses[split:, 0], poses[split:, 1], color="tab:red", linewidth=0.9, label="estimate")
        ax.plot(*poses[split, :2], "o", color="tab:red", markersize=6, markerfacecolor="none", label="converged here")
    particles, _ = loc.particles()
    ax.plot(particles[:, 0], particles[:, 1], ".", color="tab:green", markersize=1.5, alpha=0.6, label="final particles")
    ax.plot(*poses[0, :2], "^", color="black", markersize=6, label="first estimate")
    ax.legend(loc="upper right", fontsize=7)
    # Zoom on the trajectory (the map may be much larger than where the robot went).
    pts = np.vstack([poses[split:, :2] if split < len(poses) else poses[:, :2], particles[:, :2]])
    if reference is not None:
        pts = np.vstack([pts, reference[:, :2]])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = max(2.0, 0.1 * float(np.max(hi - lo)))
    x0, x1, y0, y1 = mean.extent
    zoom = (max(x0, lo[0] - pad), min(x1, hi[0] + pad), max(y0, lo[1] - pad), min(y1, hi[1] + pad))
    ax.set_xlim(zoom[0], zoom[1])
    ax.set_ylim(zoom[2], zoom[3])
    metric_axes(ax, zoom)
    steps = [s for s in loc.steps if s.processed]
    ts = np.array([t[s.scan_index] for s in steps])
    a1 = fig.add_subplot(grid[0, 1])
    a1.plot(ts, [s.n_particles for s in steps], color="tab:purple", linewidth=0.8)
    a1.set_ylabel("particles")
    a1.set_yscale("log")
    a2 = fig.add_subplot(grid[1, 1], sharex=a1)
    a2.plot(ts, [max(s.spread_xy, 1e-4) for s in steps], color="tab:orange", linewidth=0.8, label="heaviest cluster")
    a2.set_yscale("log")
    a2.set_ylabel("position spread [m]")
    a2.set_xlabel("time [s]")
    for a in (a1, a2):
        a.grid(alpha=0.3)
        if conv is not None:
            a.axvline(conv.time_s, color="tab:red", linestyle="--", linewidth=0.9, label=f"converged ({conv.distance_m:.1f} m)")
    a2.legend(fontsize=8)
    if title:
        fig.suptitle(title)
    return save_figure(fig, path, dpi)


def save_trials_figure(
    path: str | os.PathLike[str],
    rows: list[dict[str, object]],
    target_travel: float,
    max_travel: float,
    *,
    title: str = "",
    dpi: int = 150,
) -> Path:
    """The share of global-localization trials converged (correctly, when judged against a
    reference) against the distance travelled since their start."""
    judged = any(r.get("correct") not in ("", None) for r in rows)
    ok = [r for r in rows if r["converged"] and (r["correct"] == 1 if judged else True)]
    d = np.sort(np.array([float(str(r["distance_m"])) for r in ok]))
    n = len(rows)
    fig, ax = plt.subplots(figsize=(7, 4.2), constrained_layout=True)
    x = np.concatenate([[0.0], np.repeat(d, 2), [max_travel]])
    y = np.concatenate([[0.0, 0.0], np.repeat(np.arange(1, d.size + 1) / n, 2)])[: x.size]
    label = "converged to the reference" if judged else "converged"
    ax.plot(x, y, color="tab:red", linewidth=1.2, label=f"{label} ({len(ok)} of {n})")
    ax.axvline(target_travel, color="0.4", linestyle="--", linewidth=0.9, label=f"target: {target_travel:g} m")
    ax.set_xlim(0, max_travel)
    ax.set_ylim(0, 1.02)
    ax.set_xlabel("distance travelled since the start [m]")
    ax.set_ylabel("share of trials")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    if title:
        ax.set_title(title)
    return save_figure(fig, path, dpi)
