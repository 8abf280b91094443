"""Monte Carlo localization on a fixed confidence-rich map: the Python face of
``crlam_core::mcl``.

:class:`LocalizeConfig` holds every setting (AMCL's defaults where AMCL has one);
:class:`Localizer` feeds scans to the native filter with ``step(...)`` as :class:`crlam.slam.SlamRun`
does, and keeps one pose per scan, the particle set's summary per processed scan and when the
estimate converged.

The measurement model (``model``) is the CRM predictive likelihood of the scan (crm-spec 4.1)
under the map's beliefs, read from a dense layer of the map's expected occupancy: exact, except
that each beam's walk stops once the rest of its ray can change its likelihood by less than a
relative ``tail_tolerance``, that hit terms below ``tail_tolerance`` times the likelihood floor
are left out, and that, with a tolerance of at least 1e-7, the hit density's truncation
normaliser comes from a table of the normal CDF (each beam's log-likelihood then lies within
[-2 tail_tolerance - 1e-7, +1e-7] of the exact one), on at most ``max_beams`` beams
of each scan (60, AMCL's ``laser_max_beams``, spread evenly). ``model="crm-exact"`` weighs
every beam to rounding (tolerance 2^-60, no table, no beam cap);
``"likelihood_field"`` and ``"beam"`` are AMCL's models on the same filter
(``crlam_core::mcl::baseline``), for comparison.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from crlam import _native
from crlam.errors import ConfigError
from crlam.localize.map import LocalizationMap
from crlam.pose import between

MODELS = ("crm", "crm-exact", "likelihood_field", "beam")
"""The measurement models :class:`LocalizeConfig` takes."""

MODEL_PARAMS: dict[str, tuple[str, ...]] = {
    "crm": (),
    "crm-exact": (),
    "likelihood_field": ("z_hit", "z_rand", "sigma_hit", "max_dist"),
    "beam": ("z_hit", "z_short", "z_max", "z_rand", "sigma_hit", "lambda_short"),
}
"""The parameters each model takes in ``model_params`` (AMCL's models; defaults: nav2_amcl's)."""

EXACT_TOLERANCE = 2.0**-60
"""The tail tolerance of ``crm-exact``: each beam's log-likelihood to rounding."""

__all__ = [
    "EXACT_TOLERANCE",
    "MODELS",
    "MODEL_PARAMS",
    "Convergence",
    "LocalizeConfig",
    "LocalizeStep",
    "Localizer",
    "converged_at",
]


@dataclass(frozen=True)
class LocalizeConfig:
    """Settings of a localization run.

    Attributes
    ----------
    min_particles, max_particles : int
        KLD sampling's bounds (AMCL: 100, 5000). A global start draws ``spread_particles``
        (``max_particles`` when that is 0).
    kld_err : float
        ε, the bound on the KL divergence between the sample and the posterior (AMCL: 0.01).
    kld_z : float
        z_{1−δ}, the upper standard normal quantile of the confidence (2.326: δ = 0.01).
    kld_bin : tuple of float
        Histogram bin (m, rad) of the KLD bound and of the clusters (AMCL: 0.5 m, 10°).
    alpha_slow, alpha_fast : float
        Rates of the long- and short-term averages of the fit that decide the share of random
        particles, max(0, 1 − w_fast / w_slow) (AMCL's recovery_alpha_slow / _fast, whose
        values these are). 0 and 0 turn recovery off.
    tempering : float
        τ: a scan multiplies the weights by exp(Σ log η / τ). The CRM likelihood treats the beams
        as independent; neighbouring beams see the same map errors.
    sigma_max, anneal : float
        Annealing of the hit term: a scan is weighed with σ_hit = clamp(anneal · s, σ, sigma_max),
        s being the spread of the weighted set at the last scan (of its heaviest cluster when that
        holds at least half the weight, else of the whole set; position spread plus 1 m times the
        heading spread in rad) and σ the model's (``sigma_hit``). Particles spread over the
        map (a global start, a recovery) see a hit term as wide as AMCL's 0.2 m, which a particle
        decimetres from the true pose still fits; gathered, they see the model's. ``sigma_max``
        at or below σ turns it off.
    min_neff : float
        Smallest share of the effective sample size a scan may leave while the set is spread
        (above ``spread_limit``): a scan whose weights at τ would bring N_eff below this fraction
        of its value before the scan (the particle count right after resampling) is tempered
        more, until they do not (0: off). A gathered set keeps τ: there, the random particles of
        recovery would otherwise count against N_eff and flatten the weights. The CRM
        likelihood is sharp (σ_hit of a few cm); right after a global start the particle nearest
        the true pose is decimetres away, and one scan at τ would give all the weight to whichever
        particle happens to fit best, wrong or right.
    model : str
        The measurement model: ``"crm"`` (the CRM likelihood within ``tail_tolerance`` on
        ``max_beams`` beams), ``"crm-exact"`` (the CRM likelihood of every beam to rounding:
        ``beam_stride`` 1, no beam cap, tolerance 2^-60), ``"likelihood_field"`` (AMCL's, defaults
        z_hit 0.95, z_rand 0.05, sigma_hit 0.2 m, max_dist 2 m) or ``"beam"`` (AMCL's, defaults
        z_hit 0.5, z_short 0.05, z_max 0.05, z_rand 0.5, sigma_hit 0.2 m, lambda_short 0.1).
        AMCL's models read a cell as an obstacle when m̂ >= 0.5 and ignore the map's confidence;
        they use the laser's z_min and z_max but none of the mixture's weights.
    model_params : tuple of (str, float)
        Overrides of the AMCL model's parameters (:data:`MODEL_PARAMS`), e.g.
        ``(("sigma_hit", 0.1),)``.
    beam_stride, max_beams : int
        Every n-th beam, then at most ``max_beams`` of those spread evenly, first and last
        included (0: all; default 60, AMCL's ``laser_max_beams``).
    max_range : float or None
        z_max (m); longer readings are no-returns. None: the map's own (its config's
        ``max_range``), never longer than the laser's.
    sigma_hit : float or None
        σ of the hit term (m). None: the map's (σ_r and the cell size, crm-spec 2.3).
    w_hit, w_short, w_max, w_rand, lambda_short : float
        The beam mixture (the SLAM filters' weight model).
    motion : str
        ``gmapping`` (default), ``thrun`` or ``gaussian``, as :class:`crlam.slam.SlamConfig`.
    motion_params : tuple of float or None
        The motion model's parameters (None: its own).
    linear_update, angular_update : float
        Process a scan after this travel (m) or rotation (rad) since the last processed one
        (default 5 mm, 0.005 rad: every scan while the robot moves; 0 and 0: every scan). Standing
        still, the same view scanned again and again would multiply the same evidence into the
        weights, and resampling with no motion noise would shrink the set to a few poses. The
        scans in between get the last estimate carried by odometry.
    spread_update : tuple of float
        The triggers (m, rad) while the set is spread (its spread, as for the annealing, above
        ``spread_limit``): AMCL's update_min_d 0.25 m, and GMapping's angularUpdate 0.5 rad (a
        laser that sees all around learns nothing new by turning). Scans of nearly the same view
        are not independent evidence, and a spread set that weighs each of them as such collapses
        onto whichever place fits best by chance (a robot turning in place at a global start).
        Once the set has gathered, ``linear_update`` / ``angular_update`` apply.
    spread_limit : float
        Spread (m) above which the set counts as spread.
    resample_threshold : float
        Resample when N_eff < threshold · n (and whenever recovery injects).
    min_cluster, keep_ratio : int, float
        Competing hypotheses survive resampling: when more than one cluster holds at least
        ``keep_ratio`` times the heaviest cluster's weight, each of them keeps at least
        ``min_cluster`` particles (drawn from within it, up to ``max_particles`` in all) and its
        particles share its weight, so the resampling passes every cluster's weight on unchanged.
        Then a look-alike room keeps its particles until the scans rule it out, and the
        second-heaviest cluster's weight is the evidence against it (``convergence_odds``).
        While another cluster competes so, the set counts as spread (``spread_update``,
        ``min_neff``, the wide hit term): scans of nearly the same view would otherwise decide
        between the places by their chance differences. While recovery injects random particles
        the resampling is AMCL's (a place they find competes once it holds on without them).
        ``min_cluster`` 0 turns this off (AMCL's resampling).
    min_bin : int
        While the set is spread (``spread_limit``), every pose bin (``kld_bin``) holding at least
        ``keep_ratio`` times the heaviest bin's weight keeps at least ``min_bin`` particles
        through resampling (drawn first, from within it; then KLD sampling up to
        ``max_particles``), and its particles share its weight. While spread, a cluster is a
        whole room or corridor (its bins touch), so ``min_cluster`` cannot keep a place inside
        it; this floor keeps the few particles near every place not yet ruled out. 0: off.
    place_xy, place_theta : float
        Places while the set is spread (``spread_limit``; with ``min_cluster`` on and ``min_bin``
        0): the ``min_cluster`` floor is kept per place, a fixed cell of ``place_xy`` x
        ``place_xy`` m and ``place_theta`` rad of the pose space, instead of per cluster. Every
        place holding at least ``keep_ratio`` times the heaviest place's weight first gets
        ``min_cluster`` draws from within it by weight (heaviest first, up to the particle
        bound), then KLD sampling draws the rest, and the particles of each place share its
        weight. While spread, a cluster is a whole room or corridor, so a floor per cluster
        cannot keep a place inside it; a place of bounded size keeps the best particles near
        every pose not yet ruled out. Once one cluster is left, the floor is per cluster again.
        ``place_xy`` 0: off.
    spread_particles : int
        Largest particle count while the set is spread and recovery does not inject: a global
        start draws this many, and KLD sampling may keep up to this many until the set gathers
        (then ``max_particles``). A set spread over a building asks KLD for far more than 5,000;
        with too few, the true place has no particle near enough to its pose to win. 0: at most
        ``max_particles`` throughout.
    spread_climb : bool
        The scan-matched proposal while the set is spread (``spread_limit``): after its motion
        draw, each particle climbs to the nearby pose where the scan's beam endpoints fit the map
        best (the likelihood field of the endpoints at the scan's hit σ, from half a KLD bin down
        to the map's cell), and the CRM likelihood weighs it there. Moved by the odometry's noise
        alone, the particle nearest the true pose stays the decimetres off it that a set spread
        over a building leaves, and a look-alike place where some particle happens to sit closer
        to its best fit outweighs the true one. GMapping's proposal, used only while spread; a
        gathered set moves by the motion model alone, as in AMCL.
    free_threshold : float
        Cells with m̂ at most this are free: global starts and recovery place particles there.
    tail_tolerance : float
        Relative part of a beam's likelihood its walk may leave out, and again its hit window (the
        stated error is twice this, with 1e-7 from the table of the hit normaliser when the
        tolerance is at least 1e-7).
    skip_no_returns : bool
        Leave the no-returns out of the likelihood (AMCL's likelihood field does). For lasers that
        report failed readings (dark or shiny surfaces) as no-returns: the CRM likelihood reads a
        no-return as "nothing within range" and favours poses facing open space.
    convergence_xy, convergence_theta, convergence_weight : float
        The estimate is converged at a processed scan when the heaviest cluster holds at least
        ``convergence_weight`` of the weight and its particles' position and heading spreads are
        at most ``convergence_xy`` (m) and ``convergence_theta`` (rad), and it is at least
        ``convergence_odds`` times as heavy as the second-heaviest cluster.
    convergence_odds : float
        The posterior odds of the heaviest cluster against the next one that convergence needs
        (1: no such condition). With ``min_cluster`` the cluster weights carry the scans'
        (tempered) likelihood ratio of the two places since the start.
    convergence_hold : int
        The run converges at the first processed scan from which the criterion holds for this
        many processed scans in a row.
    seed : int
        Seed of every random draw.
    """

    min_particles: int = 100
    max_particles: int = 5000
    kld_err: float = 0.01
    kld_z: float = 2.3263478740408408
    kld_bin: tuple[float, float] = (0.5, math.radians(10.0))
    alpha_slow: float = 0.001
    alpha_fast: float = 0.1
    tempering: float = 10.0
    min_neff: float = 0.3
    sigma_max: float = 0.2
    anneal: float = 0.5
    model: str = "crm"
    model_params: tuple[tuple[str, float], ...] = ()
    beam_stride: int = 1
    max_beams: int = 60
    max_range: float | None = None
    sigma_hit: float | None = None
    w_hit: float = 0.7
    w_short: float = 0.1
    w_max: float = 0.1
    w_rand: float = 0.1
    lambda_short: float = 0.2
    motion: str = "gmapping"
    motion_params: tuple[float, ...] | None = None
    linear_update: float = 0.005
    angular_update: float = 0.005
    spread_update: tuple[float, float] = (0.25, 0.5)
    spread_limit: float = 0.5
    resample_threshold: float = 0.5
    min_cluster: int = 30
    keep_ratio: float = 1e-3
    min_bin: int = 0
    place_xy: float = 2.0
    place_theta: float = math.pi / 2
    spread_particles: int = 20000
    spread_climb: bool = True
    free_threshold: float = 0.25
    tail_tolerance: float = 1e-6
    skip_no_returns: bool = False
    convergence_xy: float = 0.5
    convergence_theta: float = 0.2
    convergence_weight: float = 0.9
    convergence_odds: float = 1000.0
    convergence_hold: int = 10
    seed: int = 0

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> ConfigError:
            return ConfigError(f"LocalizeConfig.{name}: {why} (got {getattr(self, name)!r})")

        for name in ("min_particles", "max_particles", "beam_stride", "convergence_hold"):
            v = getattr(self, name)
            if not (isinstance(v, int) and not isinstance(v, bool) and v >= 1):
                raise bad(name, "must be an integer >= 1")
        if self.min_particles > self.max_particles:
            raise bad("min_particles", f"must not exceed max_particles ({self.max_particles})")
        for name in ("max_beams", "min_cluster", "min_bin", "spread_particles"):
            v = getattr(self, name)
            if not (isinstance(v, int) and not isinstance(v, bool) and v >= 0):
                raise bad(name, "must be an integer >= 0 (0: off)")
        if not (math.isfinite(self.place_xy) and self.place_xy >= 0.0):
            raise bad("place_xy", "must be finite and >= 0 (0: off)")
        if not (math.isfinite(self.place_theta) and self.place_theta > 0.0):
            raise bad("place_theta", "must be finite and > 0")
        for name in ("spread_climb", "skip_no_returns"):
            if not isinstance(getattr(self, name), bool):
                raise bad(name, "must be true or false")
        if not (math.isfinite(self.keep_ratio) and 0.0 < self.keep_ratio <= 1.0):
            raise bad("keep_ratio", "must be in (0, 1]")
        if not (math.isfinite(self.convergence_odds) and self.convergence_odds >= 1.0):
            raise bad("convergence_odds", "must be finite and >= 1")
        if not (isinstance(self.seed, int) and self.seed >= 0):
            raise bad("seed", "must be an integer >= 0")
        for name in ("kld_err", "tempering", "convergence_xy", "convergence_theta"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise bad(name, "must be finite and > 0")
        if not (math.isfinite(self.min_neff) and 0.0 <= self.min_neff < 1.0):
            raise bad("min_neff", "must be in [0, 1)")
        for name in ("alpha_slow", "alpha_fast", "resample_threshold", "convergence_weight"):
            v = getattr(self, name)
            if not (math.isfinite(v) and 0.0 <= v <= 1.0):
                raise bad(name, "must be in [0, 1]")
        if not (len(self.spread_update) == 2 and all(math.isfinite(v) and v >= 0 for v in self.spread_update)):
            raise bad("spread_update", "needs 2 thresholds >= 0 (m, rad)")
        if not (math.isfinite(self.spread_limit) and self.spread_limit >= 0):
            raise bad("spread_limit", "must be finite and >= 0")
        if not (len(self.kld_bin) == 2 and all(math.isfinite(v) and v > 0 for v in self.kld_bin)):
            raise bad("kld_bin", "needs 2 bin sizes > 0 (m, rad)")
        if self.model not in MODELS:
            raise bad("model", f"must be one of {', '.join(MODELS)}")
        known = MODEL_PARAMS[self.model]
        for item in self.model_params:
            if not (isinstance(item, tuple) and len(item) == 2 and isinstance(item[0], str)):
                raise bad("model_params", "must be (name, value) pairs")
            if item[0] not in known:
                has = ", ".join(known) if known else "none"
                raise bad("model_params", f"model {self.model!r} has no parameter {item[0]!r} (it has {has})")
            if not math.isfinite(float(item[1])):
                raise bad("model_params", f"{item[0]} must be finite")
        if self.motion not in ("gaussian", "thrun", "gmapping"):
            raise bad("motion", "must be 'gaussian', 'thrun' or 'gmapping'")
        for name in ("sigma_max", "anneal"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise bad(name, "must be finite and >= 0")
        for name in ("max_range", "sigma_hit"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and v > 0):
                raise bad(name, "must be None or finite and > 0")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def sensor_model(self, map_: LocalizationMap, laser_max_range: float = math.inf) -> _native.SensorModel:
        """The mixture the weights use: this config's weights, z_max and σ_hit, with the map's
        resolution and cause kernel (and its σ_hit unless one is given)."""
        mc = map_.crm.config
        z_max = self.max_range if self.max_range is not None else mc.max_range
        z_max = min(z_max, laser_max_range) if math.isfinite(laser_max_range) and laser_max_range > 0 else z_max
        sigma = self.sigma_hit if self.sigma_hit is not None else mc.hit_sigma
        try:
            return _native.SensorModel(
                "mixture",
                z_max,
                mc.resolution,
                cause_kernel=mc.cause_kernel,
                sigma_hit=sigma,
                w_hit=self.w_hit,
                w_short=self.w_short,
                w_max=self.w_max,
                w_rand=self.w_rand,
                lambda_short=self.lambda_short,
            )
        except ValueError as e:
            raise ConfigError(f"LocalizeConfig: {e}") from e


@dataclass(frozen=True)
class LocalizeStep:
    """What the localizer did with one scan.

    Attributes
    ----------
    scan_index : int
        Index of the scan in the run (from 0).
    processed : bool
        Whether the update trigger fired.
    estimate : ndarray, shape (3,)
        The heaviest cluster's weighted mean (x m, y m, θ rad); between processed scans, the last
        one carried by odometry.
    n_particles, n_after : int
        Particles weighed at this scan, and after its resampling.
    neff : float
        Effective sample size of the weights (NaN when not processed).
    resampled : bool
    n_injected : int
        Random particles drawn from the free space by recovery.
    inject_probability : float
        max(0, 1 − w_fast / w_slow).
    fit : float
        The share of the scan the map explains, in [0, 1] (NaN when not processed).
    tempering : float
        The tempering the scan was weighed with (``tempering``, or more for ``min_neff``).
    sigma_hit : float
        The σ of the hit term the scan was weighed with (the annealing of ``sigma_max``).
    cluster_weight, spread_xy, spread_theta : float
        The heaviest cluster's weight, position spread (m, RMS) and heading spread (rad).
    second_weight : float
        The second-heaviest cluster's weight (0 with one cluster).
    n_clusters : int
    n_kept : int
        Clusters that kept ``min_cluster`` particles through the scan's resampling (0: none
        competing, or no resampling); while a spread set is floored per place (``place_xy``) or
        per bin (``min_bin``), the places or bins floored.
    converged : bool
        The convergence criterion (:class:`LocalizeConfig`) holds at this scan.
    """

    scan_index: int
    processed: bool
    estimate: NDArray[np.float64]
    n_particles: int
    n_after: int
    neff: float
    resampled: bool
    n_injected: int
    inject_probability: float
    fit: float
    tempering: float
    sigma_hit: float
    cluster_weight: float
    spread_xy: float
    spread_theta: float
    second_weight: float
    n_clusters: int
    n_kept: int
    converged: bool


@dataclass(frozen=True)
class Convergence:
    """When a run converged: the first processed scan from which the criterion held for
    ``convergence_hold`` processed scans in a row.

    Attributes
    ----------
    scan_index : int
    time_s : float
        Seconds since the run's first scan (stamps).
    distance_m : float
        Odometry path length since the run's first scan (m).
    """

    scan_index: int
    time_s: float
    distance_m: float


def converged_at(config: LocalizeConfig, weight: float, second_weight: float, spread_xy: float, spread_theta: float) -> bool:
    """The convergence criterion at one processed scan (:class:`LocalizeConfig`): the heaviest
    cluster (``weight``, position and heading spreads in m and rad) holds the weight, is compact,
    and outweighs the second-heaviest (``second_weight``) by the odds."""
    c = config
    return (
        weight >= c.convergence_weight
        and spread_xy <= c.convergence_xy
        and spread_theta <= c.convergence_theta
        and weight >= c.convergence_odds * second_weight
    )


@dataclass
class Localizer:
    """Feeds scans to a localizer on ``map`` and keeps one pose per scan (file order).

    Without ``initial_pose`` the localization is global (particles over the free space); with
    it, ``initial_cov`` (3 × 3, m² / rad², default diag(0.25, 0.25, 0.07) as AMCL's) spreads them.
    ``laser_max_range`` bounds z_max (the laser's own maximum).
    """

    map: LocalizationMap
    config: LocalizeConfig = field(default_factory=LocalizeConfig)
    initial_pose: ArrayLike | None = None
    initial_cov: ArrayLike | None = None
    laser_max_range: float = math.inf
    steps: list[LocalizeStep] = field(default_factory=list)
    stamps: list[float] = field(default_factory=list)
    odometry: list[NDArray[np.float64]] = field(default_factory=list)
    filter: _native.MclFilter | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        c = self.config
        pose = cov = None
        if self.initial_pose is not None:
            pose = np.ascontiguousarray(self.initial_pose, dtype=np.float64).reshape(3)
            cov_in = np.diag([0.25, 0.25, 0.0685]) if self.initial_cov is None else self.initial_cov
            cov = np.ascontiguousarray(cov_in, dtype=np.float64)
            if cov.shape == (3,):
                cov = np.ascontiguousarray(np.diag(cov))
            if cov.shape != (3, 3):
                raise ConfigError(f"initial_cov must be 3 variances or a 3 x 3 matrix, got shape {cov.shape}")
        elif self.initial_cov is not None:
            raise ConfigError("initial_cov needs an initial_pose")
        self.model = c.sensor_model(self.map, self.laser_max_range)
        params = list(c.motion_params) if c.motion_params is not None else None
        margin = int(math.ceil(min(self.model.z_max, 40.0) / self.map.resolution)) + 2
        exact = c.model == "crm-exact"
        try:
            self.filter = _native.MclFilter(
                self.map.crm.native,
                self.map.rect,
                self.model,
                initial_pose=pose,
                initial_cov=cov,
                free_threshold=c.free_threshold,
                margin=margin,
                n_min=c.min_particles,
                n_max=c.max_particles,
                kld_err=c.kld_err,
                kld_z=c.kld_z,
                bin_xy=float(c.kld_bin[0]),
                bin_theta=float(c.kld_bin[1]),
                alpha_slow=c.alpha_slow,
                alpha_fast=c.alpha_fast,
                tempering=c.tempering,
                min_neff=c.min_neff,
                sigma_max=c.sigma_max,
                anneal=c.anneal,
                beam_stride=1 if exact else c.beam_stride,
                max_beams=0 if exact else c.max_beams,
                motion=c.motion,
                motion_params=params,
                linear_update=c.linear_update,
                angular_update=c.angular_update,
                spread_update=(float(c.spread_update[0]), float(c.spread_update[1])),
                spread_limit=c.spread_limit,
                resample_threshold=c.resample_threshold,
                min_cluster=c.min_cluster,
                keep_ratio=c.keep_ratio,
                min_bin=c.min_bin,
                place_xy=float(c.place_xy),
                place_theta=float(c.place_theta),
                spread_max=c.spread_particles,
                spread_climb=bool(c.spread_climb),
                tail_tolerance=EXACT_TOLERANCE if exact else c.tail_tolerance,
                skip_no_returns=c.skip_no_returns,
                measurement="crm" if exact else c.model,
                measurement_params=[(k, float(v)) for k, v in c.model_params],
                seed=c.seed,
            )
        except ValueError as e:
            raise ConfigError(f"LocalizeConfig: {e}") from e
        self._held = 0
        self._travelled = 0.0
        self._distance: list[float] = []
        self.convergence: Convergence | None = None

    def step(self, odom: ArrayLike, angles: ArrayLike, ranges: ArrayLike, laser_offset: ArrayLike, stamp: float) -> LocalizeStep:
        """Feeds one scan (odometry pose of the robot, beam bearings, ranges, laser offset)."""
        assert self.filter is not None
        o = np.ascontiguousarray(odom, dtype=np.float64)
        d = self.filter.process(
            o,
            np.ascontiguousarray(angles, dtype=np.float64),
            np.ascontiguousarray(ranges, dtype=np.float64),
            np.ascontiguousarray(laser_offset, dtype=np.float64),
        )
        if self.odometry:
            inc = between(self.odometry[-1], o)
            self._travelled += float(math.hypot(inc[0], inc[1]))
        cl = d["cluster"]
        c = self.config
        converged = bool(d["processed"]) and converged_at(
            c, float(cl["weight"]), float(d["second_weight"]), float(cl["spread_xy"]), float(cl["std_theta"])
        )
        s = LocalizeStep(
            scan_index=len(self.steps),
            processed=bool(d["processed"]),
            estimate=np.array(d["estimate"], dtype=np.float64),
            n_particles=int(d["n_particles"]),
            n_after=int(d["n_after"]),
            neff=float(d["neff"]),
            resampled=bool(d["resampled"]),
            n_injected=int(d["n_injected"]),
            inject_probability=float(d["inject_probability"]),
            fit=float(d["fit"]),
            tempering=float(d["tempering"]),
            sigma_hit=float(d["sigma_hit"]),
            cluster_weight=float(cl["weight"]),
            spread_xy=float(cl["spread_xy"]),
            spread_theta=float(cl["std_theta"]),
            second_weight=float(d["second_weight"]),
            n_clusters=int(d["n_clusters"]),
            n_kept=int(d["n_kept"]),
            converged=converged,
        )
        self.steps.append(s)
        self.stamps.append(float(stamp))
        self.odometry.append(o)
        self._distance.append(self._travelled)
        self._note_convergence(s)
        return s

    def _note_convergence(self, s: LocalizeStep) -> None:
        if self.convergence is not None or not s.processed:
            return
        self._held = self._held + 1 if s.converged else 0
        if self._held >= self.config.convergence_hold:
            # The first processed scan of the run of converged ones.
            processed = [t for t in self.steps if t.processed]
            first = processed[-self._held].scan_index
            self.convergence = Convergence(
                scan_index=first,
                time_s=self.stamps[first] - self.stamps[0],
                distance_m=self._distance[first],
            )

    @property
    def n_scans(self) -> int:
        return len(self.steps)

    @property
    def distance_travelled(self) -> float:
        """Odometry path length since the first scan (m)."""
        return self._travelled

    @property
    def distances(self) -> list[float]:
        """Odometry path length (m) from the first scan to each scan."""
        return self._distance

    def trajectory(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(stamps (n,), poses (n, 3)), one per scan in order."""
        return np.array(self.stamps), np.array([s.estimate for s in self.steps]).reshape(-1, 3)

    def particles(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The current particle poses (n, 3) and normalised weights (n,)."""
        assert self.filter is not None
        return np.asarray(self.filter.particle_poses()), np.asarray(self.filter.weights())
