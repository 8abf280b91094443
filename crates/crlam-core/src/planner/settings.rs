//! Settings of the IIG planner (planner-spec 3.1–3.7): the reference-parity preset, the clean
//! preset, and one switch per reference quirk.

use crate::error::{config_err, CrlamError, Result};
use crate::info::posecov::{check_covariance, root_covariance, Cov3, EdgeNoise, PoseJacobian};

/// How a point is moved toward a target (planner-spec 3.2 Steer).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SteerMode {
    /// \[REF\] fail when ‖b − a‖ < `min_distance` (m), else return a + `fraction`·(b − a). The
    /// reference uses fraction 0.5 and a 1 m minimum, so every edge is in [0.5, ½ r_near] m.
    Reference { fraction: f64, min_distance: f64 },
    /// \[CLEAN\] the classic RIG step: b itself when ‖b − a‖ ≤ `step` (m), else the point `step`
    /// metres from a toward b. Fails only for coincident points (‖b − a‖ ≤ [`MIN_EDGE`]).
    Clean { step: f64 },
}

/// Shortest edge (m) the clean steer produces; shorter moves fail so that costs strictly increase.
pub const MIN_EDGE: f64 = 1e-9;

impl SteerMode {
    /// The reference steer: fraction 0.5, 1 m minimum distance.
    pub const REFERENCE: Self = Self::Reference {
        fraction: 0.5,
        min_distance: 1.0,
    };
    /// The clean steer: at most 0.5 m per step (the reference Δ = 0.5 read as a length).
    pub const CLEAN: Self = Self::Clean { step: 0.5 };

    /// Parses `"reference" | "clean"` into the preset of that name.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "reference" => Ok(Self::REFERENCE),
            "clean" => Ok(Self::CLEAN),
            other => Err(config_err(
                "steer",
                format!("unknown mode {other:?}; expected reference or clean"),
            )),
        }
    }

    /// Canonical name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Reference { .. } => "reference",
            Self::Clean { .. } => "clean",
        }
    }

    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        match *self {
            Self::Reference {
                fraction,
                min_distance,
            } => {
                if !(fraction > 0.0 && fraction <= 1.0) {
                    return Err(config_err(
                        "steer.fraction",
                        format!("must be in (0, 1], got {fraction}"),
                    ));
                }
                if !(min_distance.is_finite() && min_distance >= 0.0) {
                    return Err(config_err(
                        "steer.min_distance",
                        format!("must be finite and ≥ 0, got {min_distance}"),
                    ));
                }
            }
            Self::Clean { step } => {
                if !(step.is_finite() && step > MIN_EDGE) {
                    return Err(config_err(
                        "steer.step",
                        format!("must be finite and > {MIN_EDGE}, got {step}"),
                    ));
                }
            }
        }
        Ok(())
    }
}

/// How an edge is checked against the obstacle points (planner-spec 3.2 NoCollision).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CollisionMode {
    /// \[REF\] test a + s·(b − a) for s = 0.08, 0.16, … ≤ L = ‖b − a‖: the direction is not
    /// normalised, so only the first fraction L of a short edge is checked and a long edge is
    /// checked beyond b.
    Reference,
    /// \[CLEAN\] walk a → b in equal steps of at most 0.08 m, both endpoints included.
    Clean,
}

/// The step (m) of both collision walks (0.4 × the 0.2 m lattice spacing).
pub const COLLISION_STEP: f64 = 0.08;

impl CollisionMode {
    /// Parses `"reference" | "clean"`.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "reference" => Ok(Self::Reference),
            "clean" => Ok(Self::Clean),
            other => Err(config_err(
                "collision",
                format!("unknown mode {other:?}; expected reference or clean"),
            )),
        }
    }

    /// Canonical name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Reference => "reference",
            Self::Clean => "clean",
        }
    }
}

/// How the cumulative information of a new node is formed (planner-spec 3.4).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InfoAccumulation {
    /// \[REF\] I_new = ΔI + I_{π(v)} for the near node v (the root is its own parent).
    Reference,
    /// \[CLEAN\] I_new = I_v + ΔI: the sum of the gains on the path, root included.
    PathSum,
}

impl InfoAccumulation {
    /// Parses `"reference" | "path_sum"` (`"clean"` is an alias of `path_sum`).
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "reference" => Ok(Self::Reference),
            "path_sum" | "clean" => Ok(Self::PathSum),
            other => Err(config_err(
                "info_accumulation",
                format!("unknown mode {other:?}; expected reference or path_sum"),
            )),
        }
    }

    /// Canonical name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Reference => "reference",
            Self::PathSum => "path_sum",
        }
    }
}

/// Which evaluations are committed to the map (planner-spec 3.5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapMutation {
    /// \[REF\] every evaluation, including those of pruned candidates.
    EveryEvaluation,
    /// [CLEAN ablation] only the root's and the accepted nodes' evaluations.
    AcceptedOnly,
}

impl MapMutation {
    /// Parses `"every_evaluation" | "accepted_only"` (aliases `"reference"`, `"clean"`).
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "every_evaluation" | "reference" => Ok(Self::EveryEvaluation),
            "accepted_only" | "clean" => Ok(Self::AcceptedOnly),
            other => Err(config_err(
                "mutation",
                format!("unknown mode {other:?}; expected every_evaluation or accepted_only"),
            )),
        }
    }

    /// Canonical name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::EveryEvaluation => "every_evaluation",
            Self::AcceptedOnly => "accepted_only",
        }
    }
}

/// Which nodes Nearest searches (planner-spec 3.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NearestMode {
    /// \[REF\] all nodes; a sample whose nearest node is closed is discarded.
    AllNodes,
    /// \[CLEAN\] open nodes only (RIG's V \ V_closed).
    OpenOnly,
}

impl NearestMode {
    /// Parses `"all_nodes" | "open_only"` (aliases `"reference"`, `"clean"`).
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "all_nodes" | "reference" => Ok(Self::AllNodes),
            "open_only" | "clean" => Ok(Self::OpenOnly),
            other => Err(config_err(
                "nearest",
                format!("unknown mode {other:?}; expected all_nodes or open_only"),
            )),
        }
    }

    /// Canonical name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::AllNodes => "all_nodes",
            Self::OpenOnly => "open_only",
        }
    }
}

/// Everything the IIG planner needs besides the world, the information function and the seed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IigSettings {
    /// Start position x_init (m).
    pub start: [f64; 2],
    /// Cost budget B (m of path): a node with C > B is closed.
    pub budget: f64,
    /// Convergence threshold δ_RIC on the mean penalized RIC of the window.
    pub delta_ric: f64,
    /// Number of most recent penalized RIC values averaged (31).
    pub ric_window: usize,
    /// Near radius (m).
    pub r_near: f64,
    /// Collision radius (m): a checked point at distance ≤ this from an obstacle point collides.
    pub clearance: f64,
    /// SampleFree draws lattice nodes whose prior occupancy is below this.
    pub sample_threshold: f64,
    /// Steer rule (reference: half-way with a 1 m minimum).
    pub steer: SteerMode,
    /// Collision walk (reference: unnormalised).
    pub collision: CollisionMode,
    /// How I_new is formed (reference: ΔI + I_{π(v)}).
    pub accumulation: InfoAccumulation,
    /// Which evaluations mutate the map (reference: all).
    pub mutation: MapMutation,
    /// Which nodes Nearest searches (reference: all).
    pub nearest: NearestMode,
    /// θ-coupling of the per-node covariance (planner-spec 3.9).
    pub jacobian: PoseJacobian,
    /// Per-edge motion noise Q of the per-node covariance.
    pub edge_noise: EdgeNoise,
    /// Σ of the root (m², m², rad²).
    pub root_covariance: Cov3,
    /// Guard: stop after this many samples (loop iterations).
    pub max_iterations: usize,
    /// Guard: stop once the run has taken this long (s).
    pub max_wall_seconds: f64,
    /// An acceptance from a node with I_v ≤ this gets no RIC entry (counted in `ric_skipped`).
    pub ric_epsilon: f64,
}

impl Default for IigSettings {
    fn default() -> Self {
        Self::reference()
    }
}

impl IigSettings {
    /// Reference parity (planner-spec 3.1, 7.1): start (10, 2), B = 1e5, δ_RIC = 0.005 over 31
    /// values, r_near 6 m, clearance 0.8 m, samples below 0.35, every quirk in reference mode,
    /// Σ_0 = diag(0.4², 0.1², 0), Q = diag(0.1², 0.1², (0.15°)²); guards 2e5 samples and 600 s.
    pub fn reference() -> Self {
        Self {
            start: [10.0, 2.0],
            budget: 1e5,
            delta_ric: 0.005,
            ric_window: 31,
            r_near: 6.0,
            clearance: 0.8,
            sample_threshold: 0.35,
            steer: SteerMode::REFERENCE,
            collision: CollisionMode::Reference,
            accumulation: InfoAccumulation::Reference,
            mutation: MapMutation::EveryEvaluation,
            nearest: NearestMode::AllNodes,
            jacobian: PoseJacobian::Reference,
            edge_noise: EdgeNoise::default(),
            root_covariance: root_covariance(),
            max_iterations: 200_000,
            max_wall_seconds: 600.0,
            ric_epsilon: 1e-12,
        }
    }

    /// The reference numbers with every quirk replaced by its clean form: 0.5 m RIG steer, the
    /// normalised collision walk, path-sum information, accepted-only map mutation, nearest over
    /// open nodes and the unicycle Jacobian.
    pub fn clean() -> Self {
        Self {
            steer: SteerMode::CLEAN,
            collision: CollisionMode::Clean,
            accumulation: InfoAccumulation::PathSum,
            mutation: MapMutation::AcceptedOnly,
            nearest: NearestMode::OpenOnly,
            jacobian: PoseJacobian::Unicycle,
            ..Self::reference()
        }
    }

    /// Checks every field (finite, in range).
    pub fn validate(&self) -> Result<()> {
        for v in self.start {
            if !v.is_finite() {
                return Err(CrlamError::NonFinite {
                    field: "start",
                    value: v,
                });
            }
        }
        let positive = |field: &'static str, v: f64, allow_inf: bool| {
            if v > 0.0 && (allow_inf || v.is_finite()) {
                Ok(())
            } else {
                Err(config_err(field, format!("must be > 0, got {v}")))
            }
        };
        positive("budget", self.budget, true)?;
        positive("delta_ric", self.delta_ric, false)?;
        positive("r_near", self.r_near, false)?;
        positive("max_wall_seconds", self.max_wall_seconds, true)?;
        if self.ric_window == 0 {
            return Err(config_err("ric_window", "must be ≥ 1"));
        }
        if !(self.clearance.is_finite() && self.clearance >= 0.0) {
            return Err(config_err(
                "clearance",
                format!("must be finite and ≥ 0, got {}", self.clearance),
            ));
        }
        if !(self.sample_threshold > 0.0 && self.sample_threshold <= 1.0) {
            return Err(config_err(
                "sample_threshold",
                format!("must be in (0, 1], got {}", self.sample_threshold),
            ));
        }
        if !(self.ric_epsilon.is_finite() && self.ric_epsilon >= 0.0) {
            return Err(config_err(
                "ric_epsilon",
                format!("must be finite and ≥ 0, got {}", self.ric_epsilon),
            ));
        }
        self.steer.validate()?;
        check_covariance("edge_noise", self.edge_noise.q())?;
        check_covariance("root_covariance", &self.root_covariance)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_validate_and_names_round_trip() {
        IigSettings::reference().validate().unwrap();
        IigSettings::clean().validate().unwrap();
        for m in [CollisionMode::Reference, CollisionMode::Clean] {
            assert_eq!(CollisionMode::parse(m.name()).unwrap(), m);
        }
        for m in [InfoAccumulation::Reference, InfoAccumulation::PathSum] {
            assert_eq!(InfoAccumulation::parse(m.name()).unwrap(), m);
        }
        for m in [MapMutation::EveryEvaluation, MapMutation::AcceptedOnly] {
            assert_eq!(MapMutation::parse(m.name()).unwrap(), m);
        }
        for m in [NearestMode::AllNodes, NearestMode::OpenOnly] {
            assert_eq!(NearestMode::parse(m.name()).unwrap(), m);
        }
        for m in [SteerMode::REFERENCE, SteerMode::CLEAN] {
            assert_eq!(SteerMode::parse(m.name()).unwrap(), m);
        }
        assert!(SteerMode::parse("x").is_err() && MapMutation::parse("").is_err());
    }

    #[test]
    fn bad_values_are_refused() {
        let bad: Vec<fn(&mut IigSettings)> = vec![
            |s| s.start[0] = f64::NAN,
            |s| s.budget = 0.0,
            |s| s.delta_ric = f64::INFINITY,
            |s| s.ric_window = 0,
            |s| s.r_near = -1.0,
            |s| s.clearance = f64::NAN,
            |s| s.sample_threshold = 0.0,
            |s| s.ric_epsilon = -1e-3,
            |s| s.max_wall_seconds = 0.0,
            |s| s.steer = SteerMode::Clean { step: 0.0 },
            |s| {
                s.steer = SteerMode::Reference {
                    fraction: 1.5,
                    min_distance: 1.0,
                }
            },
            |s| s.root_covariance[0][0] = -1.0,
        ];
        for (i, f) in bad.iter().enumerate() {
            let mut s = IigSettings::reference();
            f(&mut s);
            assert!(s.validate().is_err(), "case {i}");
        }
    }
}
