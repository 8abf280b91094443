//! The IIG main loop (planner-spec 3.3–3.7, 3.9–3.10), generic over the information function.

use std::time::Instant;

use super::paths::{main_paths, max_info_path, path_gain};
use super::primitives::{distance, edge_is_free, steer, SampleFree};
use super::settings::{IigSettings, InfoAccumulation, MapMutation, NearestMode};
use super::spatial::PointGrid;
use super::world::PlannerWorld;
use crate::error::{config_err, CrlamError, Result};
use crate::info::posecov::{propagate_covariance, Cov3};
use crate::info::{candidate_seed, Candidate, InformationFunction};

/// Bucket side (m) of the node index; any value gives the same tree.
const NODE_BUCKET: f64 = 1.0;
/// Margin (m) of the node index box around the lattice nodes. Every node is a convex combination
/// of the start (inside the lattice's cells) and lattice nodes, so it stays inside.
const NODE_BOX_PAD: f64 = 1.0;

/// Why the loop ended (planner-spec 3.7).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopReason {
    /// The mean of the last `ric_window` penalized RIC values fell to δ_RIC or below.
    Converged,
    /// `max_iterations` samples were drawn.
    MaxIterations,
    /// `max_wall_seconds` elapsed.
    WallClock,
    /// No open node was left (cannot happen while the root is open; kept as the spec's guard).
    NoOpenNodes,
}

impl StopReason {
    /// Parses `"converged" | "max_iterations" | "wall_clock" | "no_open_nodes"`.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "converged" => Ok(Self::Converged),
            "max_iterations" => Ok(Self::MaxIterations),
            "wall_clock" => Ok(Self::WallClock),
            "no_open_nodes" => Ok(Self::NoOpenNodes),
            other => Err(config_err(
                "stop_reason",
                format!("unknown stop reason {other:?}"),
            )),
        }
    }

    /// Canonical name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Converged => "converged",
            Self::MaxIterations => "max_iterations",
            Self::WallClock => "wall_clock",
            Self::NoOpenNodes => "no_open_nodes",
        }
    }
}

/// One tree node. Information values are in the function's units (bits or nats).
#[derive(Clone, Debug, PartialEq)]
pub struct IigNode<B> {
    /// Position (m).
    pub position: [f64; 2],
    /// Parent index (always smaller than this node's); `None` for the root (index 0).
    pub parent: Option<usize>,
    /// Cumulative path length C (m) from the root.
    pub cost: f64,
    /// Cumulative information I (planner-spec 3.4); the root's is its own gain.
    pub info: f64,
    /// Marginal gain ΔI of the node's evaluation; 0 for the root (see `IigResult::root_gain`).
    pub gain: f64,
    /// C > budget: never extended.
    pub closed: bool,
    /// Pose covariance of (x, y, θ) (m², m², rad²) by planner-spec 3.9, for every function.
    pub covariance: Cov3,
    /// The function's pose belief: the evaluation's for a node, the given one for the root.
    pub belief: B,
    /// The sample (1-based loop iteration) in which the node was accepted; 0 for the root.
    pub iteration: usize,
}

/// The tree and the per-run log of planner-spec 3.10.
#[derive(Clone, Debug, PartialEq)]
pub struct IigResult<B> {
    /// Nodes in acceptance order; node 0 is the root.
    pub nodes: Vec<IigNode<B>>,
    /// ΔI of the root's evaluation.
    pub root_gain: f64,
    /// Penalized RIC (I_u / I_v − 1) / n_s of each accepted node, skipped ones left out.
    pub ric: Vec<f64>,
    /// Running sum of `ric`, one entry per node, starting at 0 for the root (a skipped node
    /// repeats the previous value).
    pub cum_ric: Vec<f64>,
    /// Per iteration: the mean ΔI of the evaluations made in it, 0 if none.
    pub iteration_gain: Vec<f64>,
    /// Loop iterations = samples drawn.
    pub iterations: usize,
    /// Calls of `evaluate`, the root's included.
    pub evaluations: usize,
    /// Accepted nodes that got no RIC entry because I_v ≤ `ric_epsilon`.
    pub ric_skipped: usize,
    /// Which rule ended the loop.
    pub stop: StopReason,
    /// Wall-clock of the whole call, path extraction included (s).
    pub seconds: f64,
    /// Main paths (planner-spec 3.8), root-first node indices, in leaf order.
    pub main_paths: Vec<Vec<usize>>,
    /// The main path with the largest Σ ΔI.
    pub max_info_path: Vec<usize>,
    /// Σ of all edge lengths (m).
    pub total_cost: f64,
    /// Σ ΔI over all nodes (the root's stored 0 included, so `root_gain` is not counted).
    pub total_info: f64,
    /// Length (m) of the most informative path.
    pub max_info_path_length: f64,
    /// Σ ΔI along the most informative path (root 0).
    pub max_info_path_info: f64,
}

impl<B> IigResult<B> {
    /// The parent list (root `None`), as the path functions take it.
    pub fn parents(&self) -> Vec<Option<usize>> {
        self.nodes.iter().map(|n| n.parent).collect()
    }

    /// ΔI per node (root 0).
    pub fn gains(&self) -> Vec<f64> {
        self.nodes.iter().map(|n| n.gain).collect()
    }

    /// "Average I_RIC" (planner-spec 3.6, Q4): `cumRIC[end]` / (#nodes − 1); 0 for a lone root.
    pub fn mean_ric(&self) -> f64 {
        let n = self.nodes.len().saturating_sub(1);
        if n == 0 {
            0.0
        } else {
            self.cum_ric.last().copied().unwrap_or(0.0) / n as f64
        }
    }
}

fn finite_gain(gain: f64) -> Result<f64> {
    if gain.is_finite() {
        Ok(gain)
    } else {
        Err(CrlamError::NonFinite {
            field: "information_gain",
            value: gain,
        })
    }
}

/// Runs the IIG planner (planner-spec 3.3, reference order of operations) with the information
/// function `f` on `map`, which it mutates (planner-spec 3.5). The root is evaluated at
/// `settings.start` (heading 0) with `root_belief`; each candidate x_new extending node v is
/// evaluated as `Candidate { pose: [x_new, 0], parent: x_v }` with v's belief and the seed
/// `candidate_seed(seed, k)` of the k-th evaluation (the root's is k = 0); SampleFree draws from
/// `Rng::new(seed)`. Same inputs, same tree, bit for bit.
///
/// Errors: invalid settings, a start outside the prior lattice's cells, no lattice node below
/// `sample_threshold`, or any error of `f`.
pub fn run_iig<F: InformationFunction>(
    f: &F,
    map: &mut F::Map,
    root_belief: F::Belief,
    world: &PlannerWorld,
    settings: &IigSettings,
    seed: u64,
) -> Result<IigResult<F::Belief>> {
    // The loop runs on a thread of the current rayon pool, so that a function's inner parallel
    // loops (UCRMI's particle likelihoods) do not wake a worker from outside the pool at every
    // evaluation (about 10 % of a one-thread UCRMI run). The results do not depend on it.
    rayon::scope(|_| run_iig_on_pool(f, map, root_belief, world, settings, seed))
}

fn run_iig_on_pool<F: InformationFunction>(
    f: &F,
    map: &mut F::Map,
    root_belief: F::Belief,
    world: &PlannerWorld,
    settings: &IigSettings,
    seed: u64,
) -> Result<IigResult<F::Belief>> {
    settings.validate()?;
    let clock = Instant::now();
    let s = settings;
    let mut sampler = SampleFree::new(world, s.sample_threshold, seed).ok_or_else(|| {
        config_err(
            "sample_threshold",
            format!("no lattice node has a prior below {}", s.sample_threshold),
        )
    })?;
    let (lat_lo, lat_hi) = world.lattice_box();
    let half = 0.5 * world.prior().geometry().resolution;
    if (0..2).any(|k| s.start[k] < lat_lo[k] - half || s.start[k] > lat_hi[k] + half) {
        return Err(CrlamError::OutOfBounds(format!(
            "start ({}, {}) is outside the prior lattice",
            s.start[0], s.start[1]
        )));
    }
    let lo = [0, 1].map(|k| lat_lo[k] - NODE_BOX_PAD);
    let hi = [0, 1].map(|k| lat_hi[k] + NODE_BOX_PAD);
    let mut index = PointGrid::new(lo, hi, NODE_BUCKET)?;

    // The root's evaluation mutates the map in both mutation modes: the root is accepted.
    let root_pose = [s.start[0], s.start[1], 0.0];
    let root_eval = f.evaluate(
        map,
        &root_belief,
        &Candidate::at(root_pose),
        candidate_seed(seed, 0),
    )?;
    let root_gain = finite_gain(root_eval.gain)?;
    f.commit(map, &root_eval.update)?;
    let mut evaluations = 1usize;
    index.insert(s.start)?;
    let mut nodes = vec![IigNode {
        position: s.start,
        parent: None,
        cost: 0.0,
        info: root_gain,
        gain: 0.0,
        closed: false,
        covariance: s.root_covariance,
        belief: root_belief,
        iteration: 0,
    }];

    let mut ric: Vec<f64> = Vec::new();
    let mut cum_ric = vec![0.0];
    let mut iteration_gain: Vec<f64> = Vec::new();
    let mut ric_skipped = 0usize;
    let mut open_nodes = 1usize;
    let mut cont = f64::INFINITY;
    let mut n_s = 0usize;
    let mut iterations = 0usize;
    let mut near: Vec<(usize, f64)> = Vec::new();
    let stop = loop {
        // `cont` changes only at acceptances, so a converged run ends right after one.
        if cont <= s.delta_ric {
            break StopReason::Converged;
        }
        if iterations >= s.max_iterations {
            break StopReason::MaxIterations;
        }
        if open_nodes == 0 {
            break StopReason::NoOpenNodes;
        }
        if clock.elapsed().as_secs_f64() >= s.max_wall_seconds {
            break StopReason::WallClock;
        }
        iterations += 1;
        let x_s = sampler.draw();
        n_s += 1;
        let (mut gain_sum, mut gain_count) = (0.0, 0usize);
        'sample: {
            let nearest = match s.nearest {
                NearestMode::AllNodes => index.nearest(x_s, |_| true),
                NearestMode::OpenOnly => index.nearest(x_s, |i| !nodes[i].closed),
            };
            let Some((nn, _)) = nearest else {
                break 'sample;
            };
            if nodes[nn].closed {
                break 'sample;
            }
            let Some(x_f) = steer(nodes[nn].position, x_s, s.steer) else {
                break 'sample;
            };
            index.within(x_f, s.r_near, &mut near);
            for &(v, _) in &near {
                let node_v = &nodes[v];
                if node_v.closed {
                    continue;
                }
                let x_v = node_v.position;
                let Some(x_new) = steer(x_v, x_f, s.steer) else {
                    continue;
                };
                if !edge_is_free(world, x_v, x_new, s.clearance, s.collision) {
                    continue;
                }
                let c_new = node_v.cost + distance(x_v, x_new);
                let candidate = Candidate {
                    pose: [x_new[0], x_new[1], 0.0],
                    parent: x_v,
                };
                let eval = f.evaluate(
                    map,
                    &node_v.belief,
                    &candidate,
                    candidate_seed(seed, evaluations as u64),
                )?;
                evaluations += 1;
                let gain = finite_gain(eval.gain)?;
                if s.mutation == MapMutation::EveryEvaluation {
                    // Kept even when the candidate is pruned below (global virtual coverage).
                    f.commit(map, &eval.update)?;
                }
                gain_sum += gain;
                gain_count += 1;
                let i_v = node_v.info;
                let i_new = match s.accumulation {
                    InfoAccumulation::Reference => {
                        gain + nodes[node_v.parent.unwrap_or(v)].info // the root is its own parent
                    }
                    InfoAccumulation::PathSum => i_v + gain,
                };
                if i_new < i_v && c_new > node_v.cost {
                    continue;
                }
                if s.mutation == MapMutation::AcceptedOnly {
                    f.commit(map, &eval.update)?;
                }
                let covariance =
                    propagate_covariance(&node_v.covariance, x_v, x_new, &s.edge_noise, s.jacobian);
                let closed = c_new > s.budget;
                index.insert(x_new)?;
                nodes.push(IigNode {
                    position: x_new,
                    parent: Some(v),
                    cost: c_new,
                    info: i_new,
                    gain,
                    closed,
                    covariance,
                    belief: eval.belief,
                    iteration: iterations,
                });
                open_nodes += usize::from(!closed);
                let last = *cum_ric.last().unwrap_or(&0.0);
                if i_v > s.ric_epsilon {
                    let penalized = (i_new / i_v - 1.0) / n_s as f64;
                    ric.push(penalized);
                    cum_ric.push(last + penalized);
                    if ric.len() >= s.ric_window {
                        let window = &ric[ric.len() - s.ric_window..];
                        cont = window.iter().sum::<f64>() / s.ric_window as f64;
                    }
                } else {
                    ric_skipped += 1;
                    cum_ric.push(last);
                }
                n_s = 0;
                break; // at most one node per sample
            }
        }
        iteration_gain.push(if gain_count > 0 {
            gain_sum / gain_count as f64
        } else {
            0.0
        });
    };

    let parents: Vec<Option<usize>> = nodes.iter().map(|n| n.parent).collect();
    let gains: Vec<f64> = nodes.iter().map(|n| n.gain).collect();
    let main = main_paths(&parents)?;
    let best = max_info_path(&main, &gains)?;
    let total_cost = nodes
        .iter()
        .filter_map(|n| n.parent.map(|p| distance(nodes[p].position, n.position)))
        .sum();
    let best_end = *best.last().unwrap_or(&0);
    let mut result = IigResult {
        root_gain,
        max_info_path_length: nodes[best_end].cost,
        max_info_path_info: path_gain(&best, &gains),
        total_info: gains.iter().sum(),
        total_cost,
        nodes,
        ric,
        cum_ric,
        iteration_gain,
        iterations,
        evaluations,
        ric_skipped,
        stop,
        seconds: 0.0,
        main_paths: main,
        max_info_path: best,
    };
    result.seconds = clock.elapsed().as_secs_f64();
    Ok(result)
}
