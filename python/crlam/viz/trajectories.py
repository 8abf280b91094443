"""Figures of SLAM runs: trajectories over the map, and errors against time."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from crlam.eval.trajectory import ReferenceErrors, RelationsErrors  # noqa: E402
from crlam.mapping import MapLayer  # noqa: E402
from crlam.viz.maps import metric_axes, save_figure, show_occupancy  # noqa: E402
from crlam.viz.palette import colour, line_style

__all__ = [
    "save_trajectory_figure",
    "save_error_figure",
    "save_error_spread_figure",
    "save_relations_error_figure",
    "save_trajectories_on_map",
]


def save_trajectories_on_map(
    path: str | os.PathLike[str],
    mean: MapLayer,
    unknown: NDArray[np.bool_] | None,
    trajectories: Mapping[str, NDArray[np.float64]],
    *,
    title: str = "",
    dpi: int = 150,
) -> Path:
    """Several named trajectories (n, 2 or 3) over a map's expected occupancy."""
    vals = np.ma.masked_array(mean.values, mask=unknown) if unknown is not None else mean.values
    # The figure takes the shape of what is drawn, the map and every trajectory (odometry may run
    # far off the map), so that the equal-aspect axes fill it instead of floating in white space.
    x0, x1, y0, y1 = (float(v) for v in mean.extent)
    for t in trajectories.values():
        if len(t):
            x0, x1 = min(x0, float(np.min(t[:, 0]))), max(x1, float(np.max(t[:, 0])))
            y0, y1 = min(y0, float(np.min(t[:, 1]))), max(y1, float(np.max(t[:, 1])))
    aspect = (y1 - y0) / max(x1 - x0, 1e-9)
    fig, ax = plt.subplots(figsize=(8, float(np.clip(8 * aspect, 4.0, 16.0))), constrained_layout=True)
    show_occupancy(ax, vals, mean.extent)
    # Colours from the project's palette; the ground truth is drawn dashed on top of the estimates.
    for name, t in trajectories.items():
        ax.plot(t[:, 0], t[:, 1], label=name, **line_style(name))
    ax.legend(loc="upper right", fontsize=8)
    metric_axes(ax, mean.extent)
    if title:
        ax.set_title(title)
    return save_figure(fig, path, dpi)


def save_trajectory_figure(
    path: str | os.PathLike[str],
    mean: MapLayer,
    unknown: NDArray[np.bool_] | None,
    estimate: NDArray[np.float64],
    *,
    reference: NDArray[np.float64] | None = None,
    title: str = "",
    label: str = "estimate",
) -> Path:
    """The estimated trajectory (and the reference, if given) over the best particle's map;
    ``label`` names the estimate in the legend and picks its colour (:mod:`crlam.viz.palette`)."""
    traj = {label: estimate}
    if reference is not None:
        traj = {"reference": reference, label: estimate}
    return save_trajectories_on_map(path, mean, unknown, traj, title=title)


def _error_axes() -> tuple[Any, Any]:
    """A figure with the position error above the heading error, sharing the time axis."""
    return plt.subplots(2, 1, figsize=(9, 5.5), sharex=True, constrained_layout=True)


def _save_error_axes(
    fig: Any,
    axes: Any,
    path: str | os.PathLike[str],
    title: str,
    dpi: int,
    ylabels: tuple[str, str] = ("position error [m]", "heading error [deg]"),
    xlabel: str = "time [s]",
) -> Path:
    axes[0].set_ylabel(ylabels[0])
    axes[1].set_ylabel(ylabels[1])
    axes[1].set_xlabel(xlabel)
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    if title:
        fig.suptitle(title)
    return save_figure(fig, path, dpi)


def save_error_figure(
    path: str | os.PathLike[str],
    errors: ReferenceErrors | Sequence[tuple[str, ReferenceErrors]],
    *,
    title: str = "",
    dpi: int = 150,
) -> Path:
    """Position and heading error against time, for one run or several named ones."""
    runs = [("estimate", errors)] if isinstance(errors, ReferenceErrors) else list(errors)
    fig, axes = _error_axes()
    for name, e in runs:
        t = e.stamps - e.stamps[0]
        c = colour(name)
        axes[0].plot(t, np.hypot(e.errors[:, 0], e.errors[:, 1]), color=c, linewidth=0.8, label=name)
        axes[1].plot(t, np.degrees(np.abs(e.errors[:, 2])), color=c, linewidth=0.8, label=name)
    return _save_error_axes(fig, axes, path, title, dpi)


def save_error_spread_figure(
    path: str | os.PathLike[str],
    groups: Mapping[str, Sequence[ReferenceErrors]],
    *,
    title: str = "",
    dpi: int = 150,
) -> Path:
    """Position and heading error against time of every run, one colour per group (method)."""
    fig, axes = _error_axes()
    for name, runs in groups.items():
        color = colour(name)
        for j, e in enumerate(runs):
            t = e.stamps - e.stamps[0]
            label = f"{name} ({len(runs)} run{'s' if len(runs) != 1 else ''})" if j == 0 else None
            axes[0].plot(t, np.hypot(e.errors[:, 0], e.errors[:, 1]), color=color, linewidth=0.6, alpha=0.8, label=label)
            axes[1].plot(t, np.degrees(np.abs(e.errors[:, 2])), color=color, linewidth=0.6, alpha=0.8)
    return _save_error_axes(fig, axes, path, title, dpi)


def save_relations_error_figure(
    path: str | os.PathLike[str],
    errors: RelationsErrors | Mapping[str, RelationsErrors],
    *,
    t0: float | None = None,
    title: str = "",
    dpi: int = 150,
) -> Path:
    """Translational and rotational error of every relation against the time of its first pose.

    Each relation is a dot at its first stamp ``t1``; the dashed lines are the means the
    metric reports, so a few large errors and where in the log they arise can be told apart.

    Parameters
    ----------
    errors : RelationsErrors or mapping of name to RelationsErrors
        The relations metric of a run (``relations_error``), or of several trajectories of it
        (e.g. the weighted mean and the best particle's path), one colour each.
    t0 : float, optional
        Time (s) shown as 0, e.g. the log's first scan; default: the earliest relation stamp.
    """
    runs = {"estimate": errors} if isinstance(errors, RelationsErrors) else dict(errors)
    fig, axes = _error_axes()
    start = min(float(np.min(e.t1)) for e in runs.values()) if t0 is None else t0
    for name, e in runs.items():
        t = e.t1 - start
        c = colour(name)
        for ax, y, unit in ((axes[0], e.trans, "m"), (axes[1], e.rot, "deg")):
            mean = float(np.mean(y))
            ax.plot(t, y, ".", markersize=2.5, color=c, alpha=0.7, label=f"{name} ({e.n} relations)")
            ax.axhline(mean, color=c, linestyle="--", linewidth=0.9, label=f"{name}: mean {mean:.3g} {unit}")
            ax.set_ylim(bottom=0.0)
    axes[1].legend(fontsize=8)
    labels = ("translational error [m]", "rotational error [deg]")
    return _save_error_axes(fig, axes, path, title, dpi, labels, "time of the relation's first pose [s]")
