"""Figures of the IIG comparison: trees (paper Fig. 3), box plots (Fig. 4), RIC and gain curves (Fig. 5)."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection
from matplotlib.patches import Ellipse

from crlam.viz.maps import metric_axes, save_figure
from crlam.viz.palette import colour

if TYPE_CHECKING:
    from crlam.info.prior import MapPrior
    from crlam.planner import IigTree

__all__ = ["draw_tree", "save_boxplots", "save_ric_and_gain", "save_trees"]

CHI2_90_2DOF = -2.0 * math.log(0.1)
"""Squared radius of the 90 % ellipse of a 2-D Gaussian."""


def _ellipse(mean: np.ndarray, cov: np.ndarray) -> Ellipse | None:
    if not np.all(np.isfinite(cov)):
        return None
    vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
    if vals.min() < 0:
        return None
    angle = math.degrees(math.atan2(vecs[1, 1], vecs[0, 1]))
    r = math.sqrt(CHI2_90_2DOF)
    return Ellipse(tuple(mean), 2 * r * math.sqrt(vals[1]), 2 * r * math.sqrt(vals[0]), angle=angle)


def draw_tree(ax: Axes, prior: MapPrior, tree: IigTree, *, ellipses: bool = True) -> None:
    """The prior map, tree edges (grey), main paths (brown), the most informative path (dark
    grey), the start (square) and 90 % pose ellipses (white): the node's own pose belief when
    the function has one (UCRMI particles, UGPVR), else the edge-propagated covariance."""
    ext = prior.extent
    ax.imshow(np.where(prior.obstacle, 0.0, 1.0), origin="lower", extent=ext, cmap="gray", vmin=0, vmax=1.4)
    pos, par = tree.positions, tree.parents
    segs = [(pos[p], pos[i]) for i, p in enumerate(par) if p >= 0]
    ax.add_collection(LineCollection(segs, colors="0.55", linewidths=0.4))
    for path in tree.main_paths:
        ax.plot(pos[path, 0], pos[path, 1], color="#8c510a", linewidth=1.4)
    if tree.max_info_path:
        p = tree.max_info_path
        ax.plot(pos[p, 0], pos[p, 1], color="0.2", linewidth=2.2)
    if ellipses:
        own = tree.belief_covariances
        for i in range(tree.n_nodes):
            cov = own[i] if np.all(np.isfinite(own[i])) else tree.covariances[i][:2, :2]
            e = _ellipse(pos[i], cov)
            if e is not None:
                e.set(facecolor="none", edgecolor="white", linewidth=0.35, alpha=0.8)
                ax.add_patch(e)
    ax.plot(*pos[0], marker="s", color="tab:red", markersize=6, zorder=5)
    ax.set_xlim(ext[0], ext[1])
    ax.set_ylim(ext[2], ext[3])
    metric_axes(ax, ext)


def save_trees(
    path: str | os.PathLike[str], prior: MapPrior, trees: Mapping[str, IigTree], labels: Mapping[str, str], *, dpi: int = 150
) -> Path:
    """Fig. 3: one panel per function (all five: the paper's figure leaves GPVR out), each titled in
    the function's colour."""
    names = [n for n in ("ogmi", "crmi", "ucrmi", "gpvr", "ugpvr") if n in trees]
    cols = min(len(names), 3) or 1
    rows = max(1, math.ceil(len(names) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(6.0 * cols, 5.6 * rows), constrained_layout=True, squeeze=False)
    for ax in axes.flat[len(names) :]:
        ax.set_visible(False)
    for ax, n in zip(axes.flat, names, strict=False):
        t = trees[n]
        draw_tree(ax, prior, t)
        ax.set_title(f"{labels.get(n, n)}: {t.n_nodes} nodes, {t.iterations} samples, {t.stop}", color=colour(n))
    return save_figure(fig, path, dpi)


def save_boxplots(
    path: str | os.PathLike[str],
    rows: Sequence[Mapping[str, Any]],
    functions: Sequence[str],
    labels: Mapping[str, str],
    *,
    dpi: int = 150,
) -> Path:
    """Fig. 4: planning time and total cost of every run, per function."""
    present = [f for f in functions if any(r["function"] == f for r in rows)]
    fig, axes = plt.subplots(1, 2, figsize=(11.0, 4.2), constrained_layout=True)
    for ax, key, title in ((axes[0], "planning_time_s", "planning time [s]"), (axes[1], "total_cost_m", "total cost [m]")):
        data = [[float(r[key]) for r in rows if r["function"] == f] for f in present]
        box = ax.boxplot(data, tick_labels=[labels.get(f, f) for f in present], patch_artist=True)
        for patch, f in zip(box["boxes"], present, strict=True):
            patch.set(facecolor=colour(f), alpha=0.45)
        ax.set_ylabel(title)
        ax.grid(axis="y", alpha=0.3)
    axes[0].set_yscale("log")
    n = max((sum(1 for r in rows if r["function"] == f) for f in present), default=0)
    fig.suptitle(f"IIG over {n} runs per function")
    return save_figure(fig, path, dpi)


def save_ric_and_gain(
    path: str | os.PathLike[str], trees: Mapping[str, IigTree], labels: Mapping[str, str], *, dpi: int = 150
) -> Path:
    """Fig. 5: (a) cumulative penalized I_RIC against the number of nodes, (b) the evolution of
    the information gain (mean Delta I of each sample's evaluations) against samples."""
    fig, axes = plt.subplots(1, 2, figsize=(12.0, 4.4), constrained_layout=True)
    for n, t in trees.items():
        axes[0].plot(np.arange(len(t.cum_ric)), t.cum_ric, label=labels.get(n, n), linewidth=1.2, color=colour(n))
        g = t.iteration_gain
        if len(g):
            # A 50-sample moving average: single samples are 0 whenever no extension was evaluated.
            w = min(50, len(g))
            smooth = np.convolve(g, np.ones(w) / w, mode="valid")
            axes[1].plot(
                np.arange(len(smooth)) + w, smooth, label=f"{labels.get(n, n)} [{t.units}]", linewidth=1.0, color=colour(n)
            )
    axes[0].set_xlabel("nodes")
    axes[0].set_ylabel("cumulative penalized I_RIC")
    axes[0].set_title("(a) cumulative penalized I_RIC")
    axes[1].set_xlabel("samples")
    axes[1].set_ylabel("information gain per sample (50-sample mean)")
    axes[1].set_yscale("symlog", linthresh=1e-2)
    axes[1].set_xscale("log")
    axes[1].set_title("(b) evolution of the information gain")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    return save_figure(fig, path, dpi)
