"""Figures of information surfaces (the paper's Fig. 1(b): information as a heat map over the map)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from crlam.info.surface import InfoSurface
from crlam.viz.maps import metric_axes, save_figure

__all__ = ["save_surface", "save_surface_figure"]


def save_surface(surface: InfoSurface, out: str | os.PathLike[str], *, dpi: int = 150) -> dict[str, Path]:
    """Writes ``surface.npy``, ``surface.png`` and ``info.json`` into ``out``."""
    d = Path(out)
    d.mkdir(parents=True, exist_ok=True)
    paths = {"surface": d / "surface.npy", "figure": d / "surface.png", "info": d / "info.json"}
    np.save(paths["surface"], surface.values)
    save_surface_figure(paths["figure"], surface, dpi=dpi)
    paths["info"].write_text(json.dumps(surface.summary(), indent=2, sort_keys=True) + "\n")
    return paths


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
