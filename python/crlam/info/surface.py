"""Information surfaces: a function evaluated at every free cell of a map (the paper's Fig. 1(b))."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from crlam.info.functions import InformationFunction, State
from crlam.info.prior import MapPrior

__all__ = ["InfoSurface", "compute_surface"]


@dataclass(frozen=True)
class InfoSurface:
    """Gains on the prior's lattice.

    Attributes
    ----------
    values : ndarray, shape (ny, nx), float64
        Gain at each evaluated node (in ``units``), NaN elsewhere.
    evaluated : ndarray, shape (ny, nx), bool
        Nodes that were evaluated (the free cells).
    prior : MapPrior
        The lattice the values live on.
    function : str
    units : str
    settings : dict
        The function's resolved settings.
    seconds : float
        Wall time of the batch evaluation.
    """

    values: NDArray[np.float64]
    evaluated: NDArray[np.bool_]
    prior: MapPrior
    function: str
    units: str
    settings: dict[str, Any] = field(default_factory=dict)
    seconds: float = 0.0

    @property
    def n_poses(self) -> int:
        return int(self.evaluated.sum())

    def summary(self) -> dict[str, Any]:
        """The content of ``info.json``."""
        v = self.values[self.evaluated]
        finite = v[np.isfinite(v)]
        n = int(v.size)
        return {
            "function": self.function,
            "units": self.units,
            "settings": self.settings,
            "source": self.prior.source,
            "lattice_shape": list(self.values.shape),
            "resolution_m": self.prior.lattice.resolution,
            "origin_m": list(self.prior.lattice.origin),
            "n_poses": n,
            "min": float(finite.min()) if finite.size else None,
            "max": float(finite.max()) if finite.size else None,
            "mean": float(finite.mean()) if finite.size else None,
            "wall_time_s": self.seconds,
            "us_per_pose_wall": 1e6 * self.seconds / max(n, 1),
            "threads": os.cpu_count(),
        }


def compute_surface(
    function: InformationFunction,
    state: State,
    prior: MapPrior,
    *,
    mask: NDArray[np.bool_] | None = None,
    heading: float = 0.0,
    seed: int = 0,
) -> InfoSurface:
    """Evaluates ``function`` on ``state`` at every node of ``mask`` (default: the free nodes).

    Candidates have heading ``heading`` (rad) and no edge; pose-aware functions start each one
    from its own root belief. The state is not changed.
    """
    m = prior.free if mask is None else mask
    xy = prior.node_positions(m)
    poses = np.column_stack([xy, np.full(len(xy), heading)])
    t0 = time.perf_counter()
    gains = function.gains(state, poses, seed=seed) if len(poses) else np.zeros(0)
    dt = time.perf_counter() - t0
    values = np.full(m.shape, np.nan)
    values[m] = gains
    return InfoSurface(
        values=values,
        evaluated=m.copy(),
        prior=prior,
        function=function.name,
        units=function.units,
        settings=dict(function.settings),
        seconds=dt,
    )
