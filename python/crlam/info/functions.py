"""The information functions behind one interface (crm-spec 5-6, planner-spec 4-6).

Every function evaluates the information gain of a virtual scan at a candidate pose on a map
state, and can record that scan in the state (the planner's map mutation):

==========  ===============================================  ===========  =========  ==========
name        what                                             state        belief     units
==========  ===============================================  ===========  =========  ==========
crmi        CRMI, exact discrete channel (crm-spec 5.2)      CRM          none       bits
ucrmi       alpha CRMI + (1 - alpha) pose information (6.4)  CRM          particles  bits
fsmi        OGMI by FSMI, exact (planner-spec 4.2)           lattice      none       nats
ogmi        OGMI by Julian's numerical integration (4.1)     lattice      none       nats
iig_mi      the IIG reference 'mi' heuristic (4.3, parity)   lattice      none       nats
gpvr        GP variance reduction (5.2)                      GP variances none       nats
ugpvr       GPVR with the expected kernel (5.3)              GP variances covariance nats
==========  ===============================================  ===========  =========  ==========

States are built from an :class:`~crlam._native.OccupancyLattice` of prior occupancy
probabilities with :meth:`InformationFunction.make_state`, so every function sees the same prior
mean map (crm-spec 6.5).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from crlam import _native
from crlam.errors import ConfigError

__all__ = ["FUNCTION_NAMES", "Evaluation", "InformationFunction", "make_function"]

FUNCTION_NAMES = ("crmi", "ucrmi", "fsmi", "ogmi", "iig_mi", "gpvr", "ugpvr")

State = _native.CrmMap | _native.OccupancyLattice | _native.GpVarianceMap


@dataclass(frozen=True)
class Evaluation:
    """One candidate's evaluation.

    Attributes
    ----------
    gain : float
        Information gain in the function's units.
    belief : ParticleBelief, ndarray (3, 3) or None
        The candidate's pose belief (UCRMI particles, UGPVR covariance), else None.
    update : InfoUpdate
        The virtual-scan map update; pass the evaluation to :meth:`InformationFunction.commit`.
    """

    gain: float
    belief: Any
    update: _native.InfoUpdate


def _pose(p: ArrayLike) -> NDArray[np.float64]:
    a = np.ascontiguousarray(p, dtype=np.float64).reshape(-1)
    if a.size == 2:
        a = np.array([a[0], a[1], 0.0])
    if a.size != 3:
        raise ConfigError(f"a pose needs (x, y) or (x, y, theta), got {a.size} values")
    return a


class InformationFunction:
    """An information function with its settings. Build with :func:`make_function`."""

    def __init__(self, native: _native.InfoFunction, name: str, settings: dict[str, Any]) -> None:
        self._native = native
        self._name = name
        self.settings = dict(settings)

    @property
    def name(self) -> str:
        return self._name

    @property
    def units(self) -> str:
        """``"bits"`` or ``"nats"``."""
        return self._native.units

    @property
    def state_kind(self) -> str:
        """``"crm"``, ``"lattice"`` or ``"gp"``."""
        return self._native.state_kind

    @property
    def belief_kind(self) -> str:
        """``"none"``, ``"particles"`` or ``"covariance"``."""
        return self._native.belief_kind

    def make_state(self, lattice: _native.OccupancyLattice) -> State:
        """A fresh map state for this function from prior occupancy probabilities: the tilted-pmf
        CRM (CRM functions), a copy of the lattice (OGMI) or GP variances of 1 (GP functions)."""
        if self.state_kind == "crm":
            return lattice.to_crm(int(self.settings.get("n_levels", 10)))
        if self.state_kind == "lattice":
            return lattice.copy()
        return _native.GpVarianceMap(lattice, 1.0)

    def root_belief(self, pose: ArrayLike, seed: int = 0) -> Any:
        """The root pose belief for a pose-aware function (None for the others)."""
        return self._native.root_belief(_pose(pose), seed)

    def evaluate(
        self, state: State, pose: ArrayLike, *, parent: ArrayLike | None = None, belief: Any = None, seed: int = 0
    ) -> Evaluation:
        """Gain of the candidate ``pose`` (x, y[, theta]) extending the node at ``parent`` (x, y).

        Pure: ``state`` is not changed. Pose-aware functions use ``belief`` (the parent's), or a
        root belief at the pose when it is None.
        """
        par = None if parent is None else (float(np.asarray(parent)[0]), float(np.asarray(parent)[1]))
        gain, new_belief, update = self._native.evaluate(state, _pose(pose), parent=par, belief=belief, seed=seed)
        return Evaluation(gain=float(gain), belief=new_belief, update=update)

    def commit(self, state: State, evaluation: Evaluation) -> None:
        """Records the evaluation's virtual scan in ``state`` (planner-spec 3.5)."""
        self._native.commit(state, evaluation.update)

    def gains(
        self,
        state: State,
        poses: ArrayLike,
        *,
        parents: ArrayLike | None = None,
        belief: Any = None,
        seed: int = 0,
    ) -> NDArray[np.float64]:
        """Gains of many candidates ``poses`` (n, 2 or 3) on one state, in parallel.

        Returns an (n,) array in :attr:`units`, equal to evaluating the candidates one by one
        (candidate i uses the random stream ``candidate_seed(seed, i)``).
        """
        p = np.ascontiguousarray(poses, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] not in (2, 3):
            raise ConfigError(f"poses must have shape (n, 2) or (n, 3), got {p.shape}")
        if p.shape[1] == 2:
            p = np.ascontiguousarray(np.column_stack([p, np.zeros(len(p))]))
        par = None if parents is None else np.ascontiguousarray(parents, dtype=np.float64)
        return self._native.gains(state, p, parents=par, belief=belief, seed=seed)

    def __repr__(self) -> str:
        return f"InformationFunction({self._name!r}, units={self.units!r})"


def _crm_models(z_max: float, resolution: float, model: str, sigma_hit: float | None) -> _native.SensorModel:
    return _native.SensorModel(model, z_max, resolution, sigma_hit=sigma_hit)


def make_function(
    name: str,
    *,
    z_max: float = 5.0,
    resolution: float = 0.2,
    n_beams: int = 10,
    beam_angles: str | None = None,
    mode: str = "clean",
    alpha: float = 0.5,
    n_particles: int = 100,
    crm_model: str = "ijrr",
    weight_model: str = "mixture",
    lambda_z: float = 0.1,
    quadrature: str = "cdf",
    dedupe_cells: str = "sum",
    sigma_hit: float | None = None,
    ogm_sigma: float = 0.05,
    delta_occ: float = 1.5,
    delta_emp: float = 1.0 / 1.5,
    fsmi_variant: str = "full",
    julian_points_per_cell: int = 16,
    n_levels: int = 10,
    crmi_variant: str = "exact",
) -> InformationFunction:
    """Builds an information function by name (see the module table).

    Parameters
    ----------
    name : str
        One of :data:`FUNCTION_NAMES`.
    z_max : float
        Beam length (m); 5 m in the paper's planner runs.
    resolution : float
        Grid cell size (m); sets the CRM hit sigma default sqrt(0.01^2 + resolution^2 / 12).
    n_beams : int
        Beams per virtual scan (10).
    beam_angles : str or None
        ``"distinct"`` (10 directions theta + 2 pi j / n) or ``"reference"`` (linspace(-pi, pi, n),
        9 distinct). Default: distinct, except ``mode="reference"`` for the planner baselines.
    mode : str
        ``"clean"`` or ``"reference"`` for GPVR/UGPVR quirks (planner-spec 5) and beam angles.
    alpha : float
        UCRMI weight of the map term, in [0, 1].
    n_particles : int
        UCRMI particles per node.
    crm_model, weight_model : str
        CRM mapping model of CRMI/UCRMI (``ijrr`` or ``mixture``) and the UCRMI particle
        likelihood model.
    lambda_z, quadrature, dedupe_cells : float, str, str
        CRMI range-bin width (m), ``"cdf"`` or ``"midpoint"``, ``"sum"`` or ``"max"``.
    ogm_sigma, delta_occ, delta_emp, fsmi_variant, julian_points_per_cell
        OGMI beam model (sigma in m, odds factors) and FSMI variant
        (``full | truncated | noise_free``); ``ogmi`` always integrates numerically.
    n_levels : int
        K of the CRM state built by :meth:`InformationFunction.make_state`.
    crmi_variant : str
        ``"exact"`` (crm-spec 5.2, default), or the authors' ``"ml_scan_binary"`` (5.4: binary
        entropy drop of one update with the most likely scan) and ``"r1_map"`` (5.3: R1's
        per-cell Bernoulli MI map), for comparison only; both use the ``authors_code`` update.
    """
    if name not in FUNCTION_NAMES:
        raise ConfigError(f"unknown information function {name!r}; expected one of {', '.join(FUNCTION_NAMES)}")
    if mode not in ("clean", "reference"):
        raise ConfigError(f"mode must be clean or reference, got {mode!r}")
    for key, v in (("z_max", z_max), ("resolution", resolution)):
        if not (math.isfinite(v) and v > 0):
            raise ConfigError(f"{key} must be finite and > 0, got {v}")
    angles = beam_angles or ("reference" if mode == "reference" else "distinct")
    settings: dict[str, Any] = {
        "function": name,
        "z_max": z_max,
        "resolution": resolution,
        "n_beams": n_beams,
        "beam_angles": angles,
        "mode": mode,
        "n_levels": n_levels,
    }
    native: _native.InfoFunction
    if name in ("crmi", "ucrmi"):
        model = _crm_models(z_max, resolution, crm_model, sigma_hit)
        settings.update(crm_model=crm_model, lambda_z=lambda_z, quadrature=quadrature, dedupe_cells=dedupe_cells)
        settings["sigma_hit"] = model.sigma_hit
        if name == "crmi":
            settings["variant"] = crmi_variant
            native = _native.InfoFunction.crmi(
                model,
                n_beams=n_beams,
                beam_angles=angles,
                lambda_z=lambda_z,
                quadrature=quadrature,
                dedupe_cells=dedupe_cells,
                variant=crmi_variant,
                resolution=resolution,
            )
        else:
            wm = _crm_models(z_max, resolution, weight_model, sigma_hit)
            settings.update(alpha=alpha, n_particles=n_particles, weight_model=weight_model)
            native = _native.InfoFunction.ucrmi(
                model,
                wm,
                alpha=alpha,
                n_particles=n_particles,
                n_beams=n_beams,
                beam_angles=angles,
                lambda_z=lambda_z,
                quadrature=quadrature,
                dedupe_cells=dedupe_cells,
            )
    elif name in ("fsmi", "ogmi"):
        variant = "julian" if name == "ogmi" else fsmi_variant
        settings.update(variant=variant, sigma=ogm_sigma, delta_occ=delta_occ, delta_emp=delta_emp)
        if variant == "julian":
            settings["points_per_cell"] = julian_points_per_cell
        native = _native.InfoFunction.fsmi(
            variant=variant,
            points_per_cell=julian_points_per_cell,
            delta_occ=delta_occ,
            delta_emp=delta_emp,
            sigma=ogm_sigma,
            z_max=z_max,
            n_beams=n_beams,
            beam_angles=angles,
        )
    elif name == "iig_mi":
        native = _native.InfoFunction.iig_mi(n_beams=n_beams, beam_angles=angles, z_max=z_max)
    elif name == "gpvr":
        native = _native.InfoFunction.gpvr(mode=mode)
    else:
        native = _native.InfoFunction.ugpvr(mode=mode)
    return InformationFunction(native, name, settings)
