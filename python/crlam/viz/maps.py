"""Figures of maps: expected occupancy and confidence side by side, with scale and colour bars."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; never needs a display (CI, workers)

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.cm import ScalarMappable  # noqa: E402
from matplotlib.colors import Normalize  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from crlam.mapping import MapLayer  # noqa: E402
from crlam.viz.palette import colour, line_style

__all__ = [
    "add_scale_bar",
    "metric_axes",
    "plot_layer",
    "save_figure",
    "save_crm_figure",
    "save_world_figure",
    "show_occupancy",
]


def _nice_length(span: float) -> float:
    """A round scale-bar length (m) near a fifth of ``span``."""
    target = max(span / 5.0, 1e-6)
    base = 10 ** np.floor(np.log10(target))
    for m in (1, 2, 5, 10):
        if m * base >= target * 0.7:
            return float(m * base)
    return float(10 * base)


def add_scale_bar(ax: Axes, extent: Sequence[float], color: str = "black") -> None:
    """Draws a labelled scale bar in the lower-left corner of ``ax`` (data units are metres)."""
    x0, x1, y0, y1 = extent
    length = _nice_length(x1 - x0)
    pad_x, pad_y = 0.04 * (x1 - x0), 0.05 * (y1 - y0)
    xs, ys = x0 + pad_x, y0 + pad_y
    from matplotlib.patches import Rectangle

    # A white plate keeps the bar readable over dark map content.
    ax.add_patch(
        Rectangle(
            (xs - 0.01 * (x1 - x0), ys - 0.015 * (y1 - y0)),
            length + 0.02 * (x1 - x0),
            0.045 * (y1 - y0),
            facecolor="white",
            edgecolor="none",
            alpha=0.85,
            zorder=4,
        )
    )
    ax.plot([xs, xs + length], [ys, ys], color=color, linewidth=3, solid_capstyle="butt", zorder=5)
    label = f"{length:g} m"
    ax.text(xs + length / 2, ys + 0.012 * (y1 - y0), label, ha="center", va="bottom", color=color, fontsize=8, zorder=5)


def show_occupancy(
    ax: Axes,
    values: NDArray[np.float64] | np.ma.MaskedArray,
    extent: tuple[float, float, float, float],
    *,
    cmap: str = "gray_r",
    bad: str = "#d8d8d8",
) -> None:
    """Draws occupancy values in [0, 1] (``(ny, nx)``, row 0 at the bottom; masked cells in
    ``bad``) on ``ax`` over ``extent`` (m), without a colour bar.

    The colours are computed here, once per cell, as 8-bit RGBA: given the floats, matplotlib
    resamples them to the output's pixels in float64 with several copies, which for a building's
    map at 150 dpi took 100 MB more than the filter that made the map.
    """
    cm = matplotlib.colormaps[cmap].with_extremes(bad=bad)
    rgba = cm(np.ma.clip(values, 0.0, 1.0), bytes=True)
    ax.imshow(rgba, origin="lower", extent=extent, interpolation="nearest")


def metric_axes(ax: Axes, extent: Sequence[float]) -> None:
    """Labels ``ax`` in metres, keeps the aspect true and adds a scale bar."""
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    add_scale_bar(ax, extent)


def save_figure(fig: Figure, path: str | os.PathLike[str], dpi: int) -> Path:
    """Writes ``fig`` to ``path`` and releases it."""
    out = Path(path)
    fig.savefig(out, dpi=dpi)
    plt.close(fig)
    return out


def plot_layer(
    ax: Axes,
    layer: MapLayer,
    *,
    cmap: str,
    vmin: float,
    vmax: float,
    label: str,
    mask: NDArray[np.bool_] | None = None,
) -> None:
    """Shows a layer in world coordinates with a colour bar; ``mask`` cells (and NaN) are shown grey.

    The colours are computed here, once per cell, as 8-bit RGBA (as :func:`show_occupancy`):
    matplotlib resampling the floats took about 100 MB more for a campus-scale map."""
    vals = np.ma.masked_array(layer.values, mask=mask) if mask is not None else np.ma.masked_invalid(layer.values)
    cm = matplotlib.colormaps[cmap].with_extremes(bad="#b0b0b0")
    norm = Normalize(vmin=vmin, vmax=vmax)
    ax.imshow(cm(norm(vals), bytes=True), origin="lower", extent=layer.extent, interpolation="nearest")
    cb = ax.figure.colorbar(ScalarMappable(norm=norm, cmap=cm), ax=ax, fraction=0.046, pad=0.02)
    cb.set_label(label)
    metric_axes(ax, layer.extent)


def save_crm_figure(
    path: str | os.PathLike[str],
    mean: MapLayer,
    variance: MapLayer,
    *,
    unknown: NDArray[np.bool_] | None = None,
    title: str = "",
    trajectory: NDArray[np.float64] | None = None,
    dpi: int = 150,
) -> Path:
    """Expected occupancy (left) and confidence as the belief standard deviation (right).

    Parameters
    ----------
    mean, variance : MapLayer
        Expected occupancy m̂ and belief variance over the same cells.
    unknown : ndarray of bool, shape (ny, nx), optional
        Cells never observed, drawn grey.
    trajectory : ndarray, shape (n, 2 or 3), optional
        Poses drawn as a line on the occupancy panel.
    """
    ny, nx = mean.shape
    aspect = ny / max(nx, 1)
    width = 13.0
    fig, axes = plt.subplots(1, 2, figsize=(width, max(3.5, 5.2 * aspect + 1.3)), constrained_layout=True)
    plot_layer(axes[0], mean, cmap="gray_r", vmin=0.0, vmax=1.0, label="expected occupancy m̂", mask=unknown)
    axes[0].set_title("Expected occupancy")
    std = MapLayer(np.sqrt(np.maximum(variance.values, 0.0)), variance.origin, variance.resolution, "std")
    # The uniform prior over 10 midpoint levels has std 0.287; the scale tops out just above it.
    plot_layer(axes[1], std, cmap="magma_r", vmin=0.0, vmax=0.3, label="belief std (lower = more confident)", mask=unknown)
    axes[1].set_title("Confidence")
    if trajectory is not None and len(trajectory):
        axes[0].plot(trajectory[:, 0], trajectory[:, 1], color="tab:blue", linewidth=0.5, alpha=0.6, label="trajectory")
        axes[0].legend(loc="upper right", fontsize=8)
    if title:
        fig.suptitle(title)
    return save_figure(fig, path, dpi)


def save_world_figure(
    path: str | os.PathLike[str],
    occupied: NDArray[np.bool_],
    origin: Sequence[float] | NDArray[np.float64],
    resolution: float,
    *,
    trajectory: NDArray[np.float64] | None = None,
    title: str = "",
    dpi: int = 120,
) -> Path:
    """Ground-truth world raster with an optional trajectory."""
    layer = MapLayer(occupied.astype(np.float64), (float(origin[0]), float(origin[1])), resolution, "world")
    fig, ax = plt.subplots(figsize=(7, 7 * occupied.shape[0] / max(occupied.shape[1], 1) + 0.5), constrained_layout=True)
    ax.imshow(layer.values, origin="lower", extent=layer.extent, cmap="gray_r", vmin=0, vmax=1, interpolation="nearest")
    if trajectory is not None and len(trajectory):
        ax.plot(trajectory[:, 0], trajectory[:, 1], label="ground truth", **line_style("ground truth"))
        ax.plot(trajectory[0, 0], trajectory[0, 1], "o", color=colour("ground truth"), markersize=5, zorder=11)
    metric_axes(ax, layer.extent)
    if title:
        ax.set_title(title)
    return save_figure(fig, path, dpi)


def save_slam_beside_world(
    path: str | os.PathLike[str],
    occupied: NDArray[np.bool_],
    origin: Sequence[float] | NDArray[np.float64],
    resolution: float,
    mean: MapLayer,
    unknown: NDArray[np.bool_] | None,
    *,
    truth: NDArray[np.float64],
    estimate: NDArray[np.float64],
    title: str = "",
    margin: float = 8.0,
    dpi: int = 120,
) -> Path:
    """A SLAM map beside the ground-truth world, on the same axes.

    Left: the world raster (``occupied`` ``[iy, ix]``, lower-left corner ``origin``, cells of
    ``resolution`` m) with the true trajectory; right: the map's expected occupancy (``unknown``
    cells grey) with the estimated trajectory (RBPF-CLAM's colour) and the true one on top.
    ``truth`` and ``estimate`` are (n, 2 or 3) poses in m; both panels show the true path's
    bounding box grown by ``margin`` m (the sensor's reach).
    """
    world = MapLayer(occupied.astype(np.float64), (float(origin[0]), float(origin[1])), resolution, "world")
    # Both panels show the part of the world the run could see: the true path plus a margin.
    w = world.extent
    lo, hi = truth[:, :2].min(axis=0) - margin, truth[:, :2].max(axis=0) + margin
    ext = (max(w[0], lo[0]), min(w[1], hi[0]), max(w[2], lo[1]), min(w[3], hi[1]))
    aspect = (ext[3] - ext[2]) / max(ext[1] - ext[0], 1e-9)
    fig, axes = plt.subplots(1, 2, figsize=(13.0, min(6.2 * aspect, 14.0) + 0.8), constrained_layout=True)
    axes[0].imshow(world.values, origin="lower", extent=ext, cmap="gray_r", vmin=0, vmax=1, interpolation="nearest")
    axes[0].set_title("ground truth: the world")
    vals = np.ma.masked_array(mean.values, mask=unknown) if unknown is not None else mean.values
    cm = matplotlib.colormaps["gray_r"].with_extremes(bad="#d8d8d8")
    axes[1].set_facecolor("#d8d8d8")
    axes[1].imshow(vals, origin="lower", extent=mean.extent, cmap=cm, vmin=0, vmax=1, interpolation="nearest")
    axes[1].set_title("RBPF-CLAM: the best particle's map")
    axes[1].plot(estimate[:, 0], estimate[:, 1], label="RBPF-CLAM", **(line_style("RBPF-CLAM") | {"linewidth": 2.0}))
    for ax in axes:
        ax.plot(truth[:, 0], truth[:, 1], label="ground truth", **line_style("ground truth"))
        ax.set_xlim(ext[0], ext[1])
        ax.set_ylim(ext[2], ext[3])
        metric_axes(ax, ext)
        ax.legend(loc="upper right", fontsize=8)
    if title:
        fig.suptitle(title)
    return save_figure(fig, path, dpi)
