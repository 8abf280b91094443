"""Map quality against a ground-truth world raster.

The world is resampled onto the map grid (the fraction of each map cell covered by obstacles,
from ``k × k`` sub-samples per cell). A map cell counts as *truly occupied* when obstacles cover
at least ``occupied_min`` of it and as *truly free* when nothing covers it; cells with a mere
sliver of obstacle are ambiguous at the map's resolution and are not scored. Only cells the map
has observed are scored.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from crlam.mapping import MapLayer

__all__ = ["MapScores", "world_coverage", "score_map"]


def world_coverage(
    layer: MapLayer,
    occupied: NDArray[np.bool_],
    origin: NDArray[np.float64] | tuple[float, float],
    resolution: float,
    samples: int = 4,
) -> NDArray[np.float64]:
    """Fraction of each cell of ``layer``'s grid covered by obstacles of a world raster.

    Parameters
    ----------
    layer : MapLayer
        Defines the grid (its values are not used).
    occupied : ndarray of bool, shape (wy, wx)
        World raster, ``[iy, ix]``, ``iy = 0`` at the minimum y; outside it is free.
    origin, resolution
        World raster georeference (m).
    samples : int
        Sub-samples per cell side.
    """
    ny, nx = layer.shape
    off = (np.arange(samples) + 0.5) / samples
    xs = layer.origin[0] + (np.arange(nx)[:, None] + off[None, :]).ravel() * layer.resolution
    ys = layer.origin[1] + (np.arange(ny)[:, None] + off[None, :]).ravel() * layer.resolution
    wx = np.floor((xs - origin[0]) / resolution).astype(np.int64)
    wy = np.floor((ys - origin[1]) / resolution).astype(np.int64)
    vx = (wx >= 0) & (wx < occupied.shape[1])
    vy = (wy >= 0) & (wy < occupied.shape[0])
    sub = occupied[np.clip(wy, 0, occupied.shape[0] - 1)][:, np.clip(wx, 0, occupied.shape[1] - 1)]
    sub = sub & vy[:, None] & vx[None, :]
    return sub.reshape(ny, samples, nx, samples).mean(axis=(1, 3))


@dataclass(frozen=True)
class MapScores:
    """Classification of observed cells at threshold 0.5 against the world.

    Attributes
    ----------
    n_observed : int
        Cells the map has information on.
    occupied_precision : float
        Of the observed cells called occupied, the fraction truly occupied.
    occupied_recall : float
        Of the observed truly occupied cells, the fraction called occupied.
    free_accuracy : float
        Of the observed truly free cells, the fraction called free.
    accuracy : float
        Fraction of observed cells classified right.
    mean_occupied, mean_free : float
        Mean map value over truly occupied / truly free observed cells (calibration).
    """

    n_observed: int
    occupied_precision: float
    occupied_recall: float
    free_accuracy: float
    accuracy: float
    mean_occupied: float
    mean_free: float

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)


def score_map(
    layer: MapLayer, observed: NDArray[np.bool_], coverage: NDArray[np.float64], occupied_min: float = 0.25
) -> MapScores:
    """Scores a probability-like layer (m̂ or p) on its observed cells (see module docstring)."""
    truth = coverage >= occupied_min
    said = layer.values > 0.5
    obs = observed & (truth | (coverage == 0.0))
    tp = int((said & truth & obs).sum())
    fp = int((said & ~truth & obs).sum())
    fn = int((~said & truth & obs).sum())
    tn = int((~said & ~truth & obs).sum())
    n = max(tp + fp + fn + tn, 1)

    def ratio(a: int, b: int) -> float:
        return a / b if b else float("nan")

    occ_vals = layer.values[truth & obs]
    free_vals = layer.values[~truth & obs]
    return MapScores(
        n_observed=int(obs.sum()),
        occupied_precision=ratio(tp, tp + fp),
        occupied_recall=ratio(tp, tp + fn),
        free_accuracy=ratio(tn, tn + fp),
        accuracy=(tp + tn) / n,
        mean_occupied=float(occ_vals.mean()) if occ_vals.size else float("nan"),
        mean_free=float(free_vals.mean()) if free_vals.size else float("nan"),
    )
