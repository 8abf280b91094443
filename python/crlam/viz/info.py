"""Figures of information surfaces (the paper's Fig. 1(b): information as a heat map over the map)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from crlam.viz.maps import metric_axes, save_figure

if TYPE_CHECKING:
    from crlam.info.surface import InfoSurface

__all__ = ["save_surface_figure"]


def save_surface_figure(path: str | os.PathLike[str], surface: InfoSurface, *, dpi: int = 150) -> Path:
    """Heat map of the gain at every evaluated cell over the prior map (obstacles black,
    unevaluated cells grey)."""
    prior = surface.prior
    ext = prior.extent
    ny, nx = surface.values.shape
    fig, ax = plt.subplots(figsize=(7.0, 6.2 * ny / max(nx, 1) + 0.6), constrained_layout=True)
    base = np.where(prior.obstacle, 0.0, 0.75)
    ax.imshow(base, origin="lower", extent=ext, cmap="gray", vmin=0.0, vmax=1.0, interpolation="nearest")
    vals = np.ma.masked_invalid(surface.values)
    finite = surface.values[np.isfinite(surface.values)]
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
    if hi <= lo:
        hi = lo + 1e-12
    im = ax.imshow(vals, origin="lower", extent=ext, cmap="viridis", vmin=lo, vmax=hi, interpolation="nearest")
    cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.02)
    cb.set_label(f"{surface.function.upper()} [{surface.units}]")
    metric_axes(ax, ext)
    n = surface.n_poses
    us = 1e6 * surface.seconds / max(n, 1)
    ax.set_title(f"{surface.function.upper()} at {n} free cells ({us:.0f} µs per pose, wall)")
    return save_figure(fig, path, dpi)
