"""The settings of a SLAM run: :class:`SlamConfig` (every field with the paper's default) and the
checks of its values.

:mod:`crlam.slam` re-exports everything here; the named presets read their files through
:mod:`crlam.slam.preset_files`, which takes this class as an argument (it sits below it).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any, Literal

from crlam.errors import ConfigError
from crlam.mapping import MappingConfig
from crlam.preflight.map_range import MAP_RANGES
from crlam.slam.fill import FILLS
from crlam.slam.grid_alignment import GRID_ALIGNMENTS, SUB_CELL_CHOICES
from crlam.slam.preset_files import DEFAULT_PRESET, NOT_DEVIATIONS, paper_settings_of, resolve_preset

__all__ = [
    "SlamConfig",
    "Method",
    "TIME_OFFSET_CHOICES",
    "MAX_TIME_OFFSET",
    "FRONT_ENDS",
    "MATCH_CLIMBS",
    "DEGENERACIES",
    "MAX_MATCH_RANGE",
    "valid_time_offset",
]

Method = Literal["clam", "ogm"]

#: The named values of ``--time-offset`` (besides a number of seconds).
TIME_OFFSET_CHOICES = ("auto", "off")
#: Largest offset (s) a number may give.
MAX_TIME_OFFSET = 10.0


def valid_time_offset(value: object) -> bool:
    """``"auto"``, ``"off"`` or a finite number of seconds within +-:data:`MAX_TIME_OFFSET` (not a bool)."""
    if isinstance(value, str):
        return value in TIME_OFFSET_CHOICES
    return (
        isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and abs(value) <= MAX_TIME_OFFSET
    )


#: Front ends in front of the scan-match proposal: ``none`` (the odometry increment as given) or
#: ``correlative`` (a wide-window search on the best particle's map corrects it; docs/method/front-end.md).
FRONT_ENDS = ("none", "correlative")

#: What the scan-match proposal's hill climb maximises: ``score`` (GMapping's endpoint score) or
#: ``posterior`` (the endpoint log-likelihood plus the log motion density, the lattice's function).
MATCH_CLIMBS = ("score", "posterior")
DEGENERACIES = ("off", "remap")

#: Largest ``match_range`` in metres (the native matcher's bound on a usable range).
MAX_MATCH_RANGE = 1e5


def _valid_match_range(v: object) -> bool:
    """``"z_max"``, ``"full"`` or a finite range in (0, MAX_MATCH_RANGE] metres (not a bool)."""
    if isinstance(v, str):
        return v in ("z_max", "full")
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and 0 < v <= MAX_MATCH_RANGE


@dataclass(frozen=True)
class SlamConfig:
    """Settings of a SLAM run (crm-spec 4 and 9). The defaults are the paper's algorithm (the
    ``paper`` preset); :meth:`from_preset` builds the configuration of a named preset (default
    ``robust``), as the command line does.

    Attributes
    ----------
    method : str
        ``"clam"`` (RBPF-CLAM) or ``"ogm"`` (the GMapping-style baseline).
    particles : int
        Number of particles n_p.
    seed : int
        Seed of every random draw (per-particle streams derive from it).
    resolution, max_range : float
        Grid cell (m) and z_max (m): longer readings are no-returns.
    mapping_model, weight_model : str
        Cause models of the map update and of the weights (``ijrr`` / ``mixture`` by default).
    scan_update : str
        ``batch`` or ``sequential``.
    batch_kernel : str
        RBPF-CLAM batch scans: ``windowed`` (default) or ``full_ray`` (the reference sweep of
        every cell); the two agree to rounding (see :class:`crlam.mapping.MappingConfig`).
    front_end : str
        RBPF-CLAM scan_match: ``"correlative"`` searches ±``front_end_window`` (m, rad) around the
        odometry's guess on the best particle's map by branch and bound before the particles'
        proposals, and a confident match replaces the odometry increment they start from (sharp
        turns, wheel slip, a late laser); ``"none"`` (paper) uses the increment as given.
    map_range : str
        ``"fixed"`` (paper): z_max is ``max_range``. ``"readings"``: a run of a whole log
        (:func:`crlam.experiments.slam_run.run_slam_log`, ``crlam slam``) sets ``max_range`` to
        the range within which 90 % of the returns of the log's first 2,000 scans lie, rounded
        up to a metre, between the configured ``max_range`` and 20 m (:mod:`crlam.preflight.map_range`);
        :class:`SlamRun` fed scan by scan uses ``max_range`` as given.
    match_min_score : float
        RBPF-CLAM scan_match: a particle's scan match counts only when its endpoint score (the
        sum over beams of exp(-d²/σ), at most one per beam) exceeds this; otherwise the particle
        takes the paper's proposal, a motion-model draw weighed by the CRM likelihood
        (GMapping's ``minimumScore``; paper and GMapping: 0, any match counts).
    front_end_window : tuple of float
        Half-widths of the correlative search: translation (m) and heading (rad).
    hits_first : bool
        RBPF-CLAM batch map updates: a cell that a beam of the scan makes more occupied ignores
        the scan's beams that pass through it to readings far beyond, so one scan cannot erase
        its own hits (paper: ``False``, every beam's factor multiplied; see
        :class:`crlam.mapping.MappingConfig`). Needs ``scan_update = "batch"``.
    weight_stride, map_stride : int
        Use every n-th beam for the weights / the map update (paper: 1).
    tempering : float
        Weight tempering τ_T (paper: 1): every log-weight increment is divided by it. The
        likelihood-mode proposal still targets the untempered likelihood × motion density.
    tempering_beams : float or None
        Beam count b at which ``tempering`` applies as given: a scan whose weight uses n beams
        (its beams over ``weight_stride``) is tempered by τ_T·n/b, so a scan weighs the same
        whatever the laser's beam count. ``None`` (paper): τ_T for every scan.
    resample_threshold : float
        Resample when N_eff < threshold · n_p (paper: 0.5).
    proposal : str
        ``odometry`` (paper) or ``likelihood_mode`` (the CRM improved proposal).
    proposal_pose : str
        Improved proposals (RBPF-CLAM's ``likelihood_mode``, RBPF-OGM's scan matching): ``sample``
        draws the new pose from the Gaussian fitted around the match (Grisetti et al. 2007);
        ``match`` keeps the match itself, as GMapping's released code does (RBPF-CLAM then starts
        its climb from a motion-model sample, as GMapping does). Same weights either way.
    match_stride : int
        RBPF-CLAM's ``likelihood_mode``: the hill climbing to the mode uses every n-th beam
        (default 3); the lattice around the mode and the weights use every beam
        (``weight_stride``). 1 climbs on every beam (about 2x the proposal's cost).
    lattice_step : tuple of float
        RBPF-CLAM's ``likelihood_mode``: spacing (m, rad) of the 3×3×3 lattice of poses around
        the mode on which the Gaussian is fitted and whose sum is the weight (default
        (0.05, 0.025), half the climb's first step). A lattice much wider than the likelihood's
        peak sees only the mode: the fitted Gaussian is then the mode plus a floor of a tenth of
        the spacing, and the weight the peak height. GMapping samples at (0.01, 0.005).
    motion_outlier : float
        RBPF-CLAM's ``likelihood_mode``: probability ε that an odometry increment is an outlier
        (default 0: off). The climb and the lattice then use (1 − ε)·p(x | x', u) + ε·u₀, u₀ = 1
        per m²·rad: the motion model near the odometry guess and a floor of log ε farther away,
        so a tight motion model still lets a scan with a larger likelihood gain move the pose
        (a loop closure, a wheel slip).
    scan_match_weight : str
        RBPF-CLAM's ``scan_match`` proposal: the weights' measurement model, ``crm`` (the
        paper's CRM predictive likelihood as the importance weight of the drawn pose) or
        ``endpoint`` (GMapping's: the lattice normaliser of the endpoint likelihood × motion
        density the proposal was fitted to; the CRM is then the map only).
    match_range : str or float
        RBPF-CLAM's ``scan_match`` proposal: the readings its endpoint matcher uses (the map
        update and the CRM likelihood always use those below ``max_range``). ``"z_max"``
        (paper): readings below ``max_range``. ``"full"``: every reading that returned, at its
        measured range; beyond ``max_range`` the far endpoints land on cells mapped earlier from
        closer by (a corridor's end on a revisit) or on unknown cells that match nothing, and the
        weight scores them with GMapping's endpoint likelihood (the CRM likelihood scores the
        readings below ``max_range``; with ``scan_match_weight="endpoint"`` every used reading is
        scored by the endpoint model already). A number: as ``"full"`` up to that range (m).
        No-returns are never used: readings at or above the
        scan's stated maximum range (CARMEN ROBOTLASER1, a ROS ``range_max``; FLASER states none,
        81 m is taken) and, beyond ``max_range``, readings within 5 cm of the largest reading
        of the log so far (a laser reports a no-return as one fixed value, its maximum).
    hit_means : bool
        RBPF-CLAM's ``scan_match`` proposal: each particle also keeps, per cell, the mean of the
        scan endpoints that hit it, and the endpoint matcher measures a beam's distance to that
        mean rather than to the cell's centre, as GMapping's matcher does (paper: ``False``; inert
        with the other proposals). The matcher's score then changes with pose shifts smaller
        than a cell. Costs three floats per cell that was hit, shared between resampled copies.
        A continued run (``--continue``) starts without means: belief.npz does not store them.
    match_climb : str
        RBPF-CLAM's ``scan_match`` proposal: what the hill climb before the lattice maximises.
        ``"score"`` (GMapping's, the default of a bare ``SlamConfig``): the endpoint score alone;
        where the scan leaves a direction free (along a corridor) the climb follows the score's
        small features as far as they lead, and every particle climbing from the same guess
        slides with it. ``"posterior"``: the endpoint log-likelihood plus the log motion density,
        the function the lattice evaluates, so the free directions stay where the odometry puts
        them. Inert with the other proposals (``likelihood_mode`` climbs its own posterior).
    degeneracy : str
        RBPF-CLAM's ``scan_match`` proposal: what it does along a direction the scan leaves free
        (a featureless corridor's axis: the scan's endpoint normals constrain it less than 1/20
        as much as the best direction). ``"off"`` (the paper's and GMapping's, the default of a
        bare ``SlamConfig``): nothing. ``"remap"``: solution remapping (Zhang, Kaess and Singh
        2016): along that direction the climb's match and the front end's correction keep the
        odometry's prediction, and the CRM weight reads the scan at the drawn pose moved back
        along it to the prediction, so that the map's unevenness along the corridor ranks no
        particle. Scans that constrain every direction are not touched. Inert with the other
        proposals.
    motion : str
        ``gaussian`` (spec 4.4; ``motion_params`` = 3 sigmas per odometry step), ``thrun``
        (``motion_params`` = alpha1..alpha4, variance coefficients) or ``gmapping`` (GMapping's own
        model: ``motion_params`` = srr, srt, str, stt, standard deviations per m or rad that add
        linearly; default 0.1 0.2 0.1 0.2).
    motion_noise : str
        ``model`` (default): the motion model's parameters as given (``motion_params``, else the
        model's own). ``estimate``: GMapping's parameters fitted to the log's own odometry and
        scans before the run (:mod:`crlam.slam.motion_noise`; needs ``motion="gmapping"``), unless
        ``motion_params`` are given; ``crlam slam`` records the fitted values in config.toml.
    linear_update, angular_update : float
        Process a scan after this much travel (m) or rotation (rad) since the last processed one;
        0 and 0 process every scan (paper).
    init_sigma : tuple of float
        Spread (m, m, rad) of the initial particles around the first odometry pose.
    sigma_range : float
        Range noise σ_r (m) in σ_hit = sqrt(σ_r² + Δ²/12).
    cause_kernel : str
        RBPF-CLAM: ``midpoint`` (spec: a cause sits at its chord midpoint) or ``chord`` (spread
        along the chord; σ_hit = σ_r), for the map update and the weights alike.
    mode_bandwidth : tuple of float
        Kernel bandwidths (m, rad) of the mode-seeking estimate recorded next to the weighted
        mean (:func:`mode_seeking_pose`; default (0.05, 0.025), the default lattice spacing).
        It does not change the filter.
    ogm_map : str
        RBPF-OGM's cells: ``log_odds`` (default; +1 / −0.5 in base 2, clamped at ±100, and a
        match needs its companion cell seen free), ``hit_rate`` (GMapping's counting cells:
        occupied when hits / visits > 0.1, and a match's companion cell passes unless occupied,
        unknown included) or ``gmapping`` (``hit_rate`` cells that also keep the mean of their
        hits, to which the matcher measures distances instead of the cell centre: GMapping's
        cell in full; four values per cell). Ignored by RBPF-CLAM.
    ogm_motion_draws : str
        When RBPF-OGM draws its odometry noise: ``per_update`` (default; once per processed scan,
        on the increment since the previous one, as RBPF-CLAM always does) or ``per_scan`` (at
        every scan of the log, on its own increment, as GMapping's ``processScan`` does;
        step-proportional noise then adds up in variance, about 1/sqrt(k) of one draw over k
        steps). Ignored by RBPF-CLAM.
    ogm_weight_smoothing : float
        RBPF-OGM's weight smoothing, GMapping's ``ogain`` (default 3): the accumulated
        log-weights are divided by ``ogm_weight_smoothing * particles`` before N_eff, resampling
        and the weighted mean; 0 uses them as they are. The best particle is the same either way;
        the smoothing sets how often the filter resamples. Ignored by RBPF-CLAM.
    smoothing_lag : int or None
        The lineage smoother written next to the weighted mean (:meth:`SlamRun.smoothed_trajectory`):
        ``None`` (default) weighs every processed scan's ancestors with the final weights (full
        smoothing, available at the end of the run); an integer L weighs them with the weights
        L processed scans later (fixed lag, online with a delay of L scans). It does not change
        the filter.
    fill : str
        The pose written for a scan the update triggers skip (:meth:`SlamRun.trajectory` and the
        other recorded estimates; the filter never sees these scans). ``interpolate`` (default):
        the last processed scan's estimate composed with the raw-odometry increment since then,
        plus the share of the correction the next processed scan's estimate makes to that
        odometry prediction, the share being how far the robot has come towards the next
        update as the triggers measure it (max of travelled / ``linear_update`` and turned /
        ``angular_update``); available once that next scan is processed, a delay of at most one
        update. ``odometry``: without the correction, the estimate as it stands online while
        the scan is the latest. Scans after the last processed one get the odometry fill either
        way. It does not change the filter, nor the poses of processed scans.
    grid_alignment : str
        The map's frame. ``none`` (paper): the first odometry pose's frame. ``walls``: that frame
        turned about the first pose so that the grid runs along the walls the first scan sees
        (:func:`crlam.slam.grid_alignment.map_turn`): a building at an angle to the robot's first
        heading is drawn on its own axes rather than as staircases of cells. The estimates are
        in the map's frame; :meth:`SlamRun.to_odometry_frame` turns them back. Not used when
        continuing a saved run (its map keeps its frame).
    sub_cell : str
        RBPF-CLAM's sub-cell geometry: every cause spread along the chord its beam cuts through
        the cell (``cause_kernel="chord"``, for the map update and the weights) and the scan
        matcher's walls at the mean of their hits (``hit_means=True``), so that walls at an angle
        to the grid are not drawn and matched as staircases of cell centres. It costs about
        1.7-2 times the filter's time. ``"on"``: always. ``"unaligned"``: only when the map's
        grid does not run along the first scan's walls, i.e. with
        ``grid_alignment="none"``, when continuing a saved run, or when the first scan shows no
        rectilinear walls to turn the grid onto (:func:`crlam.slam.grid_alignment.walls_found`).
        ``"off"`` (paper, ``robust``): ``cause_kernel`` and ``hit_means`` as given.
        :attr:`SlamRun.sub_cell` and ``metrics.json`` (``map_frame``) say what a run used.
        docs/method/presets.md (Walls at an angle to the grid) has what it does and why it is
        not the default.
    no_return : str
        What a no-return (``inf``, NaN, 0, below ``range_min``, at or above ``range_max``)
        does (:mod:`crlam.io.readings`): ``"z_max"`` (paper: the z_max atom, the beam clears
        the cells to z_max) or ``"drop"`` (left out: never clears a cell).
    body_mask : str
        ``"auto"``: beams that read the robot's own body are found in the first scans and left
        out (:mod:`crlam.preflight.body_mask`); ``"off"`` (paper): every beam is used.
    time_offset : str or float
        The offset (s) between the log's laser and odometry stamps, read by ``crlam slam`` and
        :func:`crlam.experiments.slam_run.run_slam_log` (:mod:`crlam.slam.time_offset`): ``auto``
        (the ``robust`` preset's) estimates it from the log's scans and odometry and re-attaches the odometry at
        each scan's corrected stamp when the estimate is identified (else leaves it as logged);
        ``off`` (paper) leaves the odometry as the log attaches it; a number applies that offset. Input
        handling only: :meth:`SlamRun.step` takes the odometry it is given.
    loop_closing : str
        ``"off"`` (paper): the particles alone close loops. ``"graph"`` (robust; RBPF-CLAM only):
        a pose graph over the processed scans, closed by wide-window matches against scans
        mapped long ago and kept where the map then agrees better with itself; a correction
        beyond the filter's own reach re-anchors every particle on the map rebuilt at the
        corrected poses (:mod:`crlam.slam.loop_closing`), and the run's trajectory is then the
        graph's.
    preset : str or None
        Name of the preset the settings were resolved from (:meth:`from_preset`; None for a plain
        ``SlamConfig(...)``). Provenance only: recorded in ``config.toml`` and ``metrics.json``,
        not compared by ``==``, and it does not change the filter.
    """

    method: str = "clam"
    particles: int = 100
    seed: int = 0
    resolution: float = 0.2
    max_range: float = 8.0
    mapping_model: str = "ijrr"
    weight_model: str = "mixture"
    scan_update: str = "batch"
    batch_kernel: str = "windowed"
    hits_first: bool = False
    weight_stride: int = 1
    map_stride: int = 1
    tempering: float = 1.0
    tempering_beams: float | None = None
    resample_threshold: float = 0.5
    proposal: str = "odometry"
    proposal_pose: str = "sample"
    match_stride: int = 3
    lattice_step: tuple[float, float] = (0.05, 0.025)
    motion_outlier: float = 0.0
    scan_match_weight: str = "crm"
    match_range: str | float = "z_max"
    hit_means: bool = False
    match_climb: str = "score"
    degeneracy: str = "off"
    map_range: str = "fixed"
    front_end: str = "none"
    match_min_score: float = 0.0
    front_end_window: tuple[float, float] = (0.4, 0.35)
    motion: str = "gaussian"
    motion_params: tuple[float, ...] | None = None
    motion_noise: str = "model"
    linear_update: float = 0.0
    angular_update: float = 0.0
    init_sigma: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sigma_range: float = 0.01
    cause_kernel: str = "midpoint"
    mode_bandwidth: tuple[float, float] = (0.05, 0.025)
    smoothing_lag: int | None = None
    fill: str = "interpolate"
    grid_alignment: str = "none"
    sub_cell: str = "off"
    ogm_map: str = "log_odds"
    ogm_motion_draws: str = "per_update"
    ogm_weight_smoothing: float = 3.0
    no_return: str = "z_max"
    body_mask: str = "off"
    time_offset: str | float = "off"
    loop_closing: str = "off"
    preset: str | None = field(default=None, compare=False)

    @classmethod
    def from_preset(cls, name: str | None = None, **overrides: Any) -> SlamConfig:
        """The settings of preset ``name`` (default ``robust``, :data:`crlam.slam.presets.DEFAULT_PRESET`)
        with ``overrides`` (SlamConfig field names) on top; fields neither names keep the paper's
        defaults. Raises :class:`ConfigError` for an unknown preset or field, or a bad value."""
        return resolve_preset(cls, DEFAULT_PRESET if name is None else name, overrides)

    @staticmethod
    def settle_preset_settings(preset: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
        """A preset's settings with ``overrides`` on top, where a preset's ``motion_noise =
        "estimate"`` (a fit of GMapping's odometry model) becomes ``"model"`` when the overrides
        choose another motion model and say nothing of the noise: ``--motion thrun`` on the
        ``robust`` preset runs Thrun's model with its parameters rather than failing. Likewise a
        preset's ``loop_closing = "graph"`` (it re-anchors RBPF-CLAM's particles) becomes
        ``"off"`` when the overrides choose RBPF-OGM and say nothing of loop closing."""
        settings = preset | overrides
        if preset.get("loop_closing") == "graph" and "loop_closing" not in overrides and settings.get("method") == "ogm":
            settings["loop_closing"] = "off"
        if (
            preset.get("motion_noise") == "estimate"
            and "motion_noise" not in overrides
            and settings.get("motion", "gmapping") != "gmapping"
        ):
            settings["motion_noise"] = "model"
        return settings

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Raise :class:`ConfigError` naming the first invalid field."""

        def bad(name: str, why: str) -> ConfigError:
            return ConfigError(f"SlamConfig.{name}: {why} (got {getattr(self, name)!r})")

        if self.method not in ("clam", "ogm"):
            raise bad("method", "must be 'clam' or 'ogm'")
        if not (isinstance(self.particles, int) and self.particles >= 1):
            raise bad("particles", "must be an integer >= 1")
        if not (isinstance(self.seed, int) and 0 <= self.seed < 2**64):
            raise bad("seed", "must be an integer in [0, 2^64)")
        for name in ("resolution", "max_range", "tempering"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise bad(name, "must be a finite number > 0")
        for name in ("weight_stride", "map_stride", "match_stride"):
            if not (isinstance(getattr(self, name), int) and getattr(self, name) >= 1):
                raise bad(name, "must be an integer >= 1")
        spacings = self.lattice_step
        if not (len(spacings) == 2 and all(isinstance(v, (int, float)) and math.isfinite(v) and v > 0 for v in spacings)):
            raise bad("lattice_step", "needs 2 finite spacings > 0 (m, rad)")
        bandwidth = self.mode_bandwidth
        if not (len(bandwidth) == 2 and all(isinstance(v, (int, float)) and v > 0 for v in bandwidth)):
            raise bad("mode_bandwidth", "needs 2 bandwidths > 0 (m, rad; inf allowed)")
        if not isinstance(self.hit_means, bool):
            raise bad("hit_means", "must be True or False")
        if self.match_climb not in MATCH_CLIMBS:
            raise bad("match_climb", f"must be one of {', '.join(MATCH_CLIMBS)}")
        if self.degeneracy not in DEGENERACIES:
            raise bad("degeneracy", f"must be one of {', '.join(DEGENERACIES)}")
        if not isinstance(self.hits_first, bool):
            raise bad("hits_first", "must be True or False")
        if not (
            isinstance(self.match_min_score, (int, float))
            and not isinstance(self.match_min_score, bool)
            and math.isfinite(self.match_min_score)
            and self.match_min_score >= 0
        ):
            raise bad("match_min_score", "must be finite and >= 0")
        if self.map_range not in MAP_RANGES:
            raise bad("map_range", f"must be one of {', '.join(MAP_RANGES)}")
        if self.front_end not in FRONT_ENDS:
            raise bad("front_end", f"must be one of {', '.join(FRONT_ENDS)}")
        if self.front_end != "none" and not (self.method == "clam" and self.proposal == "scan_match"):
            raise bad("front_end", "the correlative front end needs method = 'clam' and proposal = 'scan_match'")
        window = self.front_end_window
        if not (
            len(window) == 2
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in window)
            and 0 < window[0] <= 10
            and 0 < window[1] <= math.pi
        ):
            raise bad("front_end_window", "needs a half-width in (0, 10] m and one in (0, pi] rad")
        if self.hits_first and self.scan_update != "batch":
            raise bad("hits_first", "needs scan_update = 'batch' (a sequential update applies each beam before the next)")
        if self.preset is not None and not isinstance(self.preset, str):
            raise bad("preset", "must be None or a preset name")
        if self.smoothing_lag is not None and not (
            isinstance(self.smoothing_lag, int) and not isinstance(self.smoothing_lag, bool) and self.smoothing_lag >= 0
        ):
            raise bad("smoothing_lag", "must be None (full smoothing) or an integer >= 0")
        if self.fill not in FILLS:
            raise bad("fill", f"must be one of {', '.join(FILLS)}")
        if self.grid_alignment not in GRID_ALIGNMENTS:
            raise bad("grid_alignment", f"must be one of {', '.join(GRID_ALIGNMENTS)}")
        if self.sub_cell not in SUB_CELL_CHOICES:
            raise bad("sub_cell", f"must be one of {', '.join(SUB_CELL_CHOICES)}")
        if self.tempering_beams is not None and not (
            isinstance(self.tempering_beams, (int, float)) and math.isfinite(self.tempering_beams) and self.tempering_beams >= 1
        ):
            raise bad("tempering_beams", "must be None or a finite number >= 1")
        if not (isinstance(self.motion_outlier, (int, float)) and 0.0 <= self.motion_outlier < 1.0):
            raise bad("motion_outlier", "must be in [0, 1)")
        if not 0.0 <= self.resample_threshold <= 1.0:
            raise bad("resample_threshold", "must be in [0, 1]")
        if self.proposal not in ("odometry", "likelihood_mode", "scan_match"):
            raise bad("proposal", "must be 'odometry', 'likelihood_mode' or 'scan_match'")
        if self.proposal_pose not in ("sample", "match"):
            raise bad("proposal_pose", "must be 'sample' or 'match'")
        if self.method == "clam" and self.proposal == "odometry" and self.proposal_pose != "sample":
            raise bad("proposal_pose", "'match' needs an improved proposal: proposal='likelihood_mode' (RBPF-CLAM)")
        if self.scan_match_weight not in ("crm", "endpoint"):
            raise bad("scan_match_weight", "must be 'crm' or 'endpoint'")
        if not valid_time_offset(self.time_offset):
            raise bad("time_offset", f"must be 'auto', 'off' or seconds within +-{MAX_TIME_OFFSET:g}")
        if not _valid_match_range(self.match_range):
            raise bad("match_range", f"must be 'z_max', 'full' or a range in metres in (0, {MAX_MATCH_RANGE:g}]")
        if self.ogm_map not in ("log_odds", "hit_rate", "gmapping"):
            raise bad("ogm_map", "must be 'log_odds', 'hit_rate' or 'gmapping'")
        if self.ogm_motion_draws not in ("per_update", "per_scan"):
            raise bad("ogm_motion_draws", "must be 'per_update' or 'per_scan'")
        if self.cause_kernel not in ("midpoint", "chord"):
            raise bad("cause_kernel", "must be 'midpoint' or 'chord'")
        if self.no_return not in ("drop", "z_max"):
            raise bad("no_return", "must be 'drop' or 'z_max' (crlam.io.readings)")
        if self.loop_closing not in ("off", "graph"):
            raise bad("loop_closing", "must be 'off' or 'graph' (crlam.slam.loop_closing)")
        if self.loop_closing == "graph" and self.method != "clam":
            raise bad("loop_closing", "'graph' re-anchors RBPF-CLAM's particles on a rebuilt CRM: needs method='clam'")
        if self.body_mask not in ("auto", "off"):
            raise bad("body_mask", "must be 'auto' or 'off' (crlam.preflight.body_mask)")
        if self.batch_kernel not in ("windowed", "full_ray"):
            raise bad("batch_kernel", "must be 'windowed' or 'full_ray'")
        if self.motion not in ("gaussian", "thrun", "gmapping"):
            raise bad("motion", "must be 'gaussian', 'thrun' or 'gmapping'")
        if self.motion_noise not in ("model", "estimate"):
            raise bad("motion_noise", "must be 'model' or 'estimate'")
        if self.motion_noise == "estimate" and self.motion != "gmapping":
            raise bad("motion_noise", "'estimate' fits GMapping's parameters: needs motion='gmapping'")
        if self.motion_params is not None and len(self.motion_params) != (3 if self.motion == "gaussian" else 4):
            raise bad("motion_params", "needs 3 sigmas (gaussian), 4 alphas (thrun) or srr srt str stt (gmapping)")
        for name in ("linear_update", "angular_update", "sigma_range", "ogm_weight_smoothing"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise bad(name, "must be finite and >= 0")

    def mapping_config(self) -> MappingConfig:
        """The map settings (model, grid, σ) of the particles' CRMs."""
        return MappingConfig(
            resolution=self.resolution,
            max_range=self.max_range,
            model=self.mapping_model,
            scan_update=self.scan_update,
            batch_kernel=self.batch_kernel,
            hits_first=self.hits_first,
            sigma_range=self.sigma_range,
            cause_kernel=self.cause_kernel,
        )

    def filter_settings(self, grid_on_walls: bool) -> SlamConfig:
        """The settings the filter runs with: these, with the sub-cell geometry
        (``cause_kernel="chord"``, ``hit_means=True``) where ``sub_cell`` asks for it.

        Parameters
        ----------
        grid_on_walls : bool
            Whether the map's grid runs along the first scan's walls (turned onto them, or found
            already on them); see ``sub_cell``.
        """
        if self.method != "clam" or self.sub_cell == "off" or (self.sub_cell == "unaligned" and grid_on_walls):
            return self
        return replace(self, cause_kernel="chord", hit_means=True)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def deviations(self) -> list[str]:
        """Settings that differ from the paper's algorithm (crm-spec 4.3, B6), reported with every
        result: every field whose value differs from the ``paper`` preset, as
        ``"name = value (paper: value)"`` in field order. Fields that do not change the filter
        (``seed``, ``mode_bandwidth``, ``smoothing_lag``) and the ``preset`` name are never listed."""
        paper = paper_settings_of(type(self))
        out = []
        for f in fields(self):
            if f.name in NOT_DEVIATIONS:
                continue
            mine, theirs = getattr(self, f.name), paper[f.name]
            if (tuple(mine) if isinstance(mine, list) else mine) != theirs:
                out.append(f"{f.name} = {mine!r} (paper: {theirs!r})")
        return out
