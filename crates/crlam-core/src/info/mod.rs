//! Information functions: the expected information gain of a virtual scan at a candidate pose
//! (crm-spec 5–6, planner-spec 4–6).
//!
//! Every function implements [`InformationFunction`]: `evaluate` is pure (it reads the map and
//! the parent's pose belief and returns the gain, the candidate's pose belief and the map update
//! that the virtual scan would make), and `commit` applies that update. The planner's map
//! mutation (planner-spec 3.5) is `evaluate` followed by `commit`; a surface or a batch of
//! candidates is many `evaluate`s on one map state, which [`evaluate_batch`] runs in parallel with
//! results identical to the serial loop (each candidate draws from its own random stream).
//!
//! Dependencies point one way (a module uses only this file's items and modules listed before
//! it; `tests/test_rust_modules.py` checks that there are no loops):
//!
//! 1. [`lattice`] (occupancy lattices and their beams), [`posecov`], [`gp_kernel`], [`entropy`],
//!    [`shared_likelihood`], `crmi_kl` (the CRMI divergences);
//! 2. [`prior`] (a CRM from a lattice), [`fsmi`], then [`iig_mi`]; [`gp`] (GPVR, UGPVR);
//! 3. CRMI: `crmi_config` (settings), [`crmi_channel`] (one beam's channel), [`crmi`] (the
//!    pose evaluation), then [`crmi_authors`] and [`ucrmi`].

pub mod crmi;
pub mod crmi_authors;
pub mod crmi_channel;
mod crmi_config;
mod crmi_kl;
pub mod entropy;
pub mod fsmi;
pub mod gp;
pub mod gp_kernel;
pub mod iig_mi;
pub mod lattice;
pub mod posecov;
pub mod prior;
pub mod shared_likelihood;
pub mod ucrmi;

use rayon::prelude::*;

use crate::error::Result;

/// Units of a gain.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InfoUnits {
    Bits,
    Nats,
}

impl InfoUnits {
    /// Canonical name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Bits => "bits",
            Self::Nats => "nats",
        }
    }
}

/// A candidate: the new pose and the position of the node it extends (the edge start). Map-only
/// functions ignore `parent`; pose-aware ones propagate the parent's belief along the edge.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    /// (x, y, θ) of the candidate (m, m, rad). θ sets the beam angles in the clean beam mode.
    pub pose: [f64; 3],
    /// Position (m) of the node the candidate extends.
    pub parent: [f64; 2],
}

impl Candidate {
    /// A candidate with no edge (parent = own position), as for a surface.
    pub fn at(pose: [f64; 3]) -> Self {
        Self {
            pose,
            parent: [pose[0], pose[1]],
        }
    }
}

/// The result of evaluating one candidate.
#[derive(Clone, Debug)]
pub struct Evaluation<B, U> {
    /// Information gain in the function's units.
    pub gain: f64,
    /// The candidate's pose belief (the parent's, propagated along the edge).
    pub belief: B,
    /// What `commit` must apply to the map to record the virtual scan.
    pub update: U,
}

/// One interface for every information function (planner-spec 6:
/// `Info(x_new, M, belief_parent, edge) → (ΔI, M′, belief_new)`).
pub trait InformationFunction: Sync {
    /// The map state the function reads and mutates.
    type Map: Sync + Send;
    /// Pose belief carried per node: `()` for map-only functions.
    type Belief: Clone + Send + Sync;
    /// A recorded virtual-scan update.
    type Update: Send;

    /// Short name (`"crmi"`, `"fsmi"`, ...).
    fn name(&self) -> &'static str;

    fn units(&self) -> InfoUnits;

    /// Gain of the candidate. Pure: the map is not changed. `seed` keys any random draw.
    fn evaluate(
        &self,
        map: &Self::Map,
        parent: &Self::Belief,
        candidate: &Candidate,
        seed: u64,
    ) -> Result<Evaluation<Self::Belief, Self::Update>>;

    /// Applies an update returned by `evaluate` (the planner's map mutation).
    fn commit(&self, map: &mut Self::Map, update: &Self::Update) -> Result<()>;

    /// The gain of `evaluate` alone (surfaces, exploration decisions). Functions whose update
    /// costs extra work skip it here; the value equals `evaluate(..).gain`.
    fn gain(
        &self,
        map: &Self::Map,
        parent: &Self::Belief,
        candidate: &Candidate,
        seed: u64,
    ) -> Result<f64> {
        self.evaluate(map, parent, candidate, seed).map(|e| e.gain)
    }
}

/// Evaluates many candidates on one map state in parallel. Candidate `i` uses the random stream
/// keyed by `(seed, i)`, so the result equals the serial loop whatever the thread count.
pub fn evaluate_batch<F: InformationFunction>(
    f: &F,
    map: &F::Map,
    parent: &F::Belief,
    candidates: &[Candidate],
    seed: u64,
) -> Result<Vec<Evaluation<F::Belief, F::Update>>>
where
    F::Belief: Send,
{
    candidates
        .par_iter()
        .enumerate()
        .map(|(i, c)| f.evaluate(map, parent, c, candidate_seed(seed, i as u64)))
        .collect()
}

/// The gains only (a surface), in parallel; equal to the serial loop.
pub fn gain_batch<F: InformationFunction>(
    f: &F,
    map: &F::Map,
    parent: &F::Belief,
    candidates: &[Candidate],
    seed: u64,
) -> Result<Vec<f64>> {
    candidates
        .par_iter()
        .enumerate()
        .map(|(i, c)| f.gain(map, parent, c, candidate_seed(seed, i as u64)))
        .collect()
}

/// The seed of candidate `index` in a batch keyed by `seed`.
pub fn candidate_seed(seed: u64, index: u64) -> u64 {
    crate::rng::Rng::stream(seed, 0x1AF0, index).next_u64()
}

/// Shannon entropy of a pmf in nats (0 log 0 = 0).
#[inline]
pub fn entropy_nats(p: &[f64]) -> f64 {
    -p.iter()
        .filter(|&&x| x > 0.0)
        .map(|&x| x * x.ln())
        .sum::<f64>()
}

/// Bernoulli entropy h(p) in nats.
#[inline]
pub fn bernoulli_entropy(p: f64) -> f64 {
    let mut h = 0.0;
    if p > 0.0 {
        h -= p * p.ln();
    }
    if p < 1.0 {
        h -= (1.0 - p) * (-p).ln_1p();
    }
    h
}
