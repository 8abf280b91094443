"""Figures of an exploration run: the paper's Fig. 1 pair, progress curves and an animation."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Protocol

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.animation import FuncAnimation, PillowWriter
from numpy.typing import NDArray

from crlam.mapping import ConfidenceRichMap
from crlam.viz.maps import metric_axes, save_figure
from crlam.viz.palette import colour

__all__ = ["ExploreRunView", "save_animation", "save_exploration_figure", "save_progress_figure", "save_sweep_figures"]


class _ExploreSettings(Protocol):
    """The settings of an exploration run that its figures show (read only)."""

    @property
    def function(self) -> str: ...
    @property
    def resolution(self) -> float: ...
    @property
    def sensor_range(self) -> float: ...
    @property
    def free_threshold(self) -> float: ...


class ExploreRunView(Protocol):
    """What the figures read of an exploration run (:class:`crlam.experiments.explore.ExploreRun`
    has it): a protocol, so that figures do not import the experiments above them."""

    @property
    def config(self) -> _ExploreSettings: ...
    @property
    def crm(self) -> ConfidenceRichMap: ...
    @property
    def truth(self) -> NDArray[np.bool_]: ...
    @property
    def poses(self) -> NDArray[np.float64]: ...
    @property
    def decisions(self) -> list[dict[str, Any]]: ...
    @property
    def frames(self) -> list[dict[str, Any]]: ...
    @property
    def stop(self) -> str: ...
    @property
    def distance(self) -> float: ...


def _extent(run: ExploreRunView) -> tuple[float, float, float, float]:
    ny, nx = run.truth.shape
    ext = run.crm.config.extent
    assert ext is not None
    r = run.config.resolution
    return (ext[0], ext[0] + nx * r, ext[1], ext[1] + ny * r)


def _draw_map(ax: plt.Axes, mean: np.ndarray, extent: tuple[float, float, float, float]) -> None:
    ax.imshow(mean, origin="lower", extent=extent, cmap="gray_r", vmin=0.0, vmax=1.0, interpolation="nearest")


def save_exploration_figure(path: str | os.PathLike[str], run: ExploreRunView, *, dpi: int = 150) -> Path:
    """Left: the trajectory (start square, end star) over the final CRM's expected occupancy.
    Right: CRMI (bits) at every known-free cell of the final map."""
    from crlam.info import make_function, prior_from_crm_mean

    ext = _extent(run)
    b = (ext[0], ext[2], ext[1], ext[3])
    mean = run.crm.expected_occupancy(b).values
    ent = run.crm.entropy(b).values
    fig, axes = plt.subplots(1, 2, figsize=(12.5, 5.2 * mean.shape[0] / max(mean.shape[1], 1) + 1.0), constrained_layout=True)
    _draw_map(axes[0], mean, ext)
    p = run.poses
    c = colour(run.config.function)
    axes[0].plot(p[:, 0], p[:, 1], color=c, linewidth=1.0)
    axes[0].plot(p[0, 0], p[0, 1], marker="s", color=c, markeredgecolor="black", markersize=8, label="start")
    axes[0].plot(p[-1, 0], p[-1, 1], marker="*", color=c, markeredgecolor="black", markersize=13, label="end")
    axes[0].legend(loc="upper right", fontsize=8)
    axes[0].set_title(f"{run.config.function.upper()} exploration: {run.distance:.0f} m, stop: {run.stop}")
    crmi = make_function("crmi", z_max=run.config.sensor_range, resolution=run.config.resolution)
    prior = prior_from_crm_mean(mean, (ext[0], ext[2]), run.config.resolution)
    free = (ent < np.log2(10.0) - 1e-3) & (mean < run.config.free_threshold)
    xy = prior.node_positions(free)
    values = np.full(mean.shape, np.nan)
    if len(xy):
        values[free] = crmi.gains(run.crm.native, np.column_stack([xy, np.zeros(len(xy))]))
    _draw_map(axes[1], mean, ext)
    im = axes[1].imshow(np.ma.masked_invalid(values), origin="lower", extent=ext, cmap="viridis", interpolation="nearest")
    cb = fig.colorbar(im, ax=axes[1], fraction=0.046, pad=0.02)
    cb.set_label("CRMI [bits]")
    axes[1].set_title("CRMI on the final map (known-free cells)")
    # Zoom to the observed part of the world (plus a margin): a short run in a large world. The
    # scale bar is sized and placed for the zoomed view.
    view = ext
    obs_y, obs_x = np.nonzero(ent < np.log2(10.0) - 1e-3)
    if obs_x.size:
        r = run.config.resolution
        margin = 3.0
        view = (
            max(ext[0], ext[0] + obs_x.min() * r - margin),
            min(ext[1], ext[0] + (obs_x.max() + 1) * r + margin),
            max(ext[2], ext[2] + obs_y.min() * r - margin),
            min(ext[3], ext[2] + (obs_y.max() + 1) * r + margin),
        )
    for ax in axes:
        ax.set_xlim(view[0], view[1])
        ax.set_ylim(view[2], view[3])
        metric_axes(ax, view)
    return save_figure(fig, path, dpi)


def save_progress_figure(path: str | os.PathLike[str], run: ExploreRunView, *, dpi: int = 150) -> Path:
    """Explored area and map entropy against the distance travelled."""
    d = np.array([r["distance_m"] for r in run.decisions])
    fig, axes = plt.subplots(1, 2, figsize=(11.0, 3.8), constrained_layout=True)
    axes[0].plot(d, [r["explored_m2"] for r in run.decisions], marker=".")
    axes[0].axhline(
        float((~run.truth).sum()) * run.config.resolution**2, color="0.5", linestyle="--", label="free area of the world"
    )
    axes[0].set_xlabel("distance travelled [m]")
    axes[0].set_ylabel("explored area [m²]")
    axes[0].legend(fontsize=8)
    axes[1].plot(d, [r["map_entropy_bits"] for r in run.decisions], marker=".", color="tab:orange")
    axes[1].set_xlabel("distance travelled [m]")
    axes[1].set_ylabel("map entropy [bits]")
    for ax in axes:
        ax.grid(alpha=0.3)
    return save_figure(fig, path, dpi)


def save_animation(path: str | os.PathLike[str], run: ExploreRunView, *, max_frames: int = 60, fps: int = 4) -> Path:
    """A GIF: the map and the trajectory at every decision (at most ``max_frames`` frames)."""
    ext = _extent(run)
    frames = run.frames[:: max(1, len(run.frames) // max_frames)]
    fig, ax = plt.subplots(figsize=(6.0, 6.0 * run.truth.shape[0] / max(run.truth.shape[1], 1) + 0.4))
    metric_axes(ax, ext)

    def draw(i: int) -> None:
        ax.clear()
        f = frames[i]
        _draw_map(ax, f["mean"] / 255.0, ext)
        p = f["poses"]
        ax.plot(p[:, 0], p[:, 1], color=colour(run.config.function), linewidth=1.0)
        ax.plot(p[-1, 0], p[-1, 1], marker="o", color=colour(run.config.function), markeredgecolor="black")
        ax.set_title(f"decision {f['decision']}")
        ax.set_xlim(ext[0], ext[1])
        ax.set_ylim(ext[2], ext[3])

    anim = FuncAnimation(fig, draw, frames=len(frames))
    out = Path(path)
    anim.save(out, writer=PillowWriter(fps=fps))
    plt.close(fig)
    return out


def save_sweep_figures(out: Path, rows: list[dict[str, Any]], *, dpi: int = 150) -> dict[str, Path]:
    """``coverage.png``: explored area, map error and pose error against distance (mean over the
    seeds of each world and variant, read from the runs' ``progress.csv``); ``pose_error.png``:
    the mean pose error of every run per variant."""
    import csv

    curves: dict[tuple[str, str], list[dict[str, np.ndarray]]] = {}
    for r in rows:
        path = Path(out) / "runs" / str(r["name"]) / "progress.csv"
        if not path.is_file():
            continue
        with path.open() as fh:
            prog = list(csv.DictReader(fh))
        if not prog:
            continue
        curves.setdefault((str(r["world"]), str(r["variant"])), []).append(
            {k: np.array([float(p[k]) for p in prog]) for k in ("distance_m", "explored_m2", "map_error", "pose_error_m")}
        )
    fig, axes = plt.subplots(1, 3, figsize=(16.0, 4.4), constrained_layout=True)
    # One colour per function (the palette's); variants of one function (UCRMI's alphas, several
    # worlds) are told apart by the line style.
    styles = ("-", "--", ":", "-.", (0, (5, 1, 1, 1, 1, 1)))
    seen: dict[str, int] = {}
    for (world, variant), runs in sorted(curves.items()):
        c = colour(variant)
        ls = styles[seen.setdefault(c, 0) % len(styles)]
        seen[c] += 1
        grid = np.linspace(0.0, max(float(c["distance_m"][-1]) for c in runs), 60)
        for ax, key in zip(axes, ("explored_m2", "map_error", "pose_error_m"), strict=True):
            ys = np.array([np.interp(grid, c["distance_m"], c[key]) for c in runs])
            ax.plot(grid, ys.mean(axis=0), label=f"{world}: {variant}", linewidth=1.2, color=c, linestyle=ls)
    for ax, label in zip(axes, ("explored area [m²]", "map error (observed cells)", "pose error [m]"), strict=True):
        ax.set_xlabel("distance travelled [m]")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    files = {"coverage": save_figure(fig, Path(out) / "coverage.png", dpi)}
    variants = sorted({str(r["variant"]) for r in rows})
    fig, ax = plt.subplots(figsize=(max(6.0, 1.1 * len(variants)), 4.0), constrained_layout=True)
    ax.boxplot([[float(r["pose_error_mean_m"]) for r in rows if r["variant"] == v] for v in variants], tick_labels=variants)
    ax.set_ylabel("mean pose error of a run [m]")
    ax.grid(axis="y", alpha=0.3)
    files["pose_error"] = save_figure(fig, Path(out) / "pose_error.png", dpi)
    return files
