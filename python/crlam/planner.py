"""The IIG planner (planner-spec 3): an information-rich tree over a prior map.

>>> from crlam.info import load_map_prior, make_function                    # doctest: +SKIP
>>> from crlam.planner import IigSettings, plan_iig                          # doctest: +SKIP
>>> prior = load_map_prior("cave.pgm")                                       # doctest: +SKIP
>>> f = make_function("gpvr", mode="reference")                              # doctest: +SKIP
>>> tree = plan_iig(f, prior, IigSettings(), seed=0)                         # doctest: +SKIP
>>> tree.n_nodes, tree.stop, tree.seconds                                    # doctest: +SKIP
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from crlam import _native
from crlam.errors import ConfigError, DataFormatError
from crlam.info.functions import InformationFunction
from crlam.info.prior import MapPrior

__all__ = ["IigSettings", "IigTree", "plan_iig", "obstacle_points"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class IigSettings:
    """Planner settings (planner-spec 3.1, 3.7, 7.1).

    ``mode`` selects every reference-vs-clean switch at once ("reference" reproduces the public
    planner's behaviour, quirks included; "clean" the papers' semantics); ``overrides`` sets
    single switches: ``steer``, ``collision``, ``accumulation`` (``reference`` | ``path_sum``),
    ``mutation`` (``every_evaluation`` | ``accepted_only``), ``nearest``, ``jacobian``.
    """

    mode: str = "reference"
    start: tuple[float, float] = (10.0, 2.0)
    budget: float = 1e5
    delta_ric: float = 0.005
    ric_window: int = 31
    r_near: float = 6.0
    clearance: float = 0.8
    sample_threshold: float = 0.35
    max_iterations: int = 200_000
    max_wall_seconds: float = 600.0
    overrides: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.mode not in ("reference", "clean"):
            raise ConfigError(f"mode must be reference or clean, got {self.mode!r}")
        for name in ("budget", "delta_ric", "r_near", "clearance", "max_wall_seconds"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"{name} must be finite and > 0, got {v}")
        if self.ric_window < 1 or self.max_iterations < 1:
            raise ConfigError("ric_window and max_iterations must be >= 1")

    def options(self) -> dict[str, Any]:
        """The settings passed to the core (the preset comes from ``mode``)."""
        d: dict[str, Any] = {
            "start": tuple(self.start),
            "budget": self.budget,
            "delta_ric": self.delta_ric,
            "ric_window": self.ric_window,
            "r_near": self.r_near,
            "clearance": self.clearance,
            "sample_threshold": self.sample_threshold,
            "max_iterations": self.max_iterations,
            "max_wall_seconds": self.max_wall_seconds,
        }
        d.update(self.overrides)
        return d


@dataclass
class IigTree:
    """One planner run: the tree, its logs and the settings that made it.

    Attributes
    ----------
    positions : ndarray, shape (n, 2)
        Node positions (m); node 0 is the root.
    parents : ndarray, shape (n,), int64
        Parent index (-1 for the root); always smaller than the child's index.
    costs, infos, gains : ndarray, shape (n,)
        Cumulative path length (m), the planner's cumulative information I and each node's own
        gain Delta I (function units; the root's is 0 here and ``root_gain`` apart).
    covariances : ndarray, shape (n, 3, 3)
        Pose covariance propagated along the edges (planner-spec 3.9).
    belief_covariances : ndarray, shape (n, 2, 2)
        Position covariance of the node's own pose belief (UCRMI particles, UGPVR), NaN otherwise.
    ric, cum_ric : ndarray
        Penalized RIC per accepted node and its running sum (one entry per node, from 0).
    iteration_gain : ndarray, shape (iterations,)
        Mean Delta I of the evaluations of each iteration (0 when none).
    main_paths : list of list of int; max_info_path : list of int
        Paths of planner-spec 3.8 (node indices from the root).
    """

    function: str
    units: str
    seed: int
    mode: str
    positions: FloatArray
    parents: NDArray[np.int64]
    costs: FloatArray
    infos: FloatArray
    gains: FloatArray
    closed: NDArray[np.bool_]
    node_iterations: NDArray[np.int64]
    covariances: FloatArray
    belief_covariances: FloatArray
    ric: FloatArray
    cum_ric: FloatArray
    iteration_gain: FloatArray
    main_paths: list[list[int]]
    max_info_path: list[int]
    root_gain: float
    iterations: int
    evaluations: int
    ric_skipped: int
    stop: str
    seconds: float
    total_cost: float
    total_info: float
    max_info_path_length: float
    max_info_path_info: float
    settings: dict[str, Any] = field(default_factory=dict)

    @property
    def n_nodes(self) -> int:
        return int(len(self.positions))

    @property
    def converged(self) -> bool:
        return self.stop == "converged"

    @property
    def mean_ric(self) -> float:
        """Average penalized I_RIC over the accepted nodes (planner-spec 3.6, Q4)."""
        return float(self.cum_ric[-1] / max(self.n_nodes - 1, 1))

    @property
    def window_mean(self) -> float:
        """Mean of the last ``ric_window`` penalized RIC values (the stopping statistic)."""
        w = int(self.settings.get("ric_window", 31))
        return float(np.mean(self.ric[-w:])) if len(self.ric) else float("nan")

    def summary(self) -> dict[str, Any]:
        """One row of ``runs.csv``."""
        return {
            "function": self.function,
            "units": self.units,
            "seed": self.seed,
            "mode": self.mode,
            "planning_time_s": round(self.seconds, 6),
            "samples": self.iterations,
            "nodes": self.n_nodes,
            "evaluations": self.evaluations,
            "total_cost_m": round(self.total_cost, 6),
            "total_info": round(self.total_info, 6),
            "final_cum_ric": round(float(self.cum_ric[-1]), 6),
            "mean_ric": round(self.mean_ric, 6),
            "window_mean_ric": round(self.window_mean, 6),
            "converged": self.converged,
            "stop": self.stop,
            "max_info_path_length_m": round(self.max_info_path_length, 6),
            "max_info_path_info": round(self.max_info_path_info, 6),
        }

    def save(self, path: str | os.PathLike[str]) -> None:
        """Writes the tree as ``.npz`` (arrays) with its scalars and paths as JSON inside."""
        meta = {k: v for k, v in asdict(self).items() if not isinstance(v, np.ndarray)}
        arrays = {k: v for k, v in asdict(self).items() if isinstance(v, np.ndarray)}
        np.savez_compressed(Path(path), allow_pickle=False, meta=json.dumps(meta), **arrays)  # type: ignore[arg-type]

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> IigTree:
        from crlam.io.npz_check import check_npz

        try:
            check_npz(path, "IIG tree file")  # before anything is decompressed
        except OSError as e:
            raise DataFormatError(f"{path}: not an IIG tree file ({e})") from None
        try:
            with np.load(Path(path), allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                arrays = {k: z[k] for k in z.files if k != "meta"}
        except (OSError, ValueError, KeyError) as e:
            raise DataFormatError(f"{path}: not an IIG tree file ({e})") from None
        try:
            return cls(**meta, **arrays)
        except TypeError as e:
            raise DataFormatError(f"{path}: not an IIG tree file ({e})") from None


def obstacle_points(prior: MapPrior) -> FloatArray:
    """World positions (n, 2) of the prior's obstacle nodes: the planner's collision point set."""
    return np.ascontiguousarray(prior.node_positions(prior.obstacle))


def check_start(prior: MapPrior, start: tuple[float, float]) -> None:
    """Raises :class:`ConfigError` unless ``start`` (x, y) is finite and lies on a node of the
    prior that is not an obstacle (a tree grown from inside a wall would be reported as a run)."""
    x, y = (float(v) for v in start)
    if not (math.isfinite(x) and math.isfinite(y)):
        raise ConfigError(f"start must be two finite numbers, got ({x}, {y})")
    ox, oy = prior.lattice.origin
    r = prior.lattice.resolution
    ny, nx = prior.obstacle.shape
    fx, fy = (x - ox) / r, (y - oy) / r
    if not (0 <= fx < nx and 0 <= fy < ny):
        raise ConfigError(f"start ({x}, {y}) lies outside the map ({prior.source})")
    if prior.obstacle[int(fy), int(fx)]:
        raise ConfigError(f"start ({x}, {y}) lies inside an obstacle of the map ({prior.source})")


def plan_iig(
    function: InformationFunction,
    prior: MapPrior,
    settings: IigSettings | None = None,
    *,
    seed: int = 0,
    state: Any = None,
) -> IigTree:
    """Runs IIG with ``function`` from ``settings.start`` on a fresh state built from ``prior``
    (or on ``state``, which the run mutates). The only randomness is SampleFree, keyed by
    ``seed`` (plus UCRMI's particles); the same seed and settings give the same tree."""
    s = settings or IigSettings()
    check_start(prior, s.start)
    st = function.make_state(prior.lattice) if state is None else state
    d = _native.run_iig(
        function._native,
        st,
        prior.lattice,
        obstacle_points(prior),
        mode=s.mode,
        options=s.options(),
        seed=seed,
    )
    return IigTree(
        function=function.name,
        units=str(d["units"]),
        seed=seed,
        mode=s.mode,
        positions=np.asarray(d["positions"]),
        parents=np.asarray(d["parents"], dtype=np.int64),
        costs=np.asarray(d["costs"]),
        infos=np.asarray(d["infos"]),
        gains=np.asarray(d["gains"]),
        closed=np.asarray(d["closed"]) > 0,
        node_iterations=np.asarray(d["node_iterations"]).astype(np.int64),
        covariances=np.asarray(d["covariances"]),
        belief_covariances=np.asarray(d["belief_covariances"]),
        ric=np.asarray(d["ric"]),
        cum_ric=np.asarray(d["cum_ric"]),
        iteration_gain=np.asarray(d["iteration_gain"]),
        main_paths=[list(map(int, p)) for p in d["main_paths"]],
        max_info_path=[int(i) for i in d["max_info_path"]],
        root_gain=float(d["root_gain"]),
        iterations=int(d["iterations"]),
        evaluations=int(d["evaluations"]),
        ric_skipped=int(d["ric_skipped"]),
        stop=str(d["stop"]),
        seconds=float(d["seconds"]),
        total_cost=float(d["total_cost"]),
        total_info=float(d["total_info"]),
        max_info_path_length=float(d["max_info_path_length"]),
        max_info_path_info=float(d["max_info_path_info"]),
        settings={**dict(d["settings"]), "function_settings": function.settings},
    )
