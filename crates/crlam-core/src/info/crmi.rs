//! CRMI: the expected information gain of a virtual scan about the CRM cells it crosses, by the
//! exact discrete channel of crm-spec 5.2.
//!
//! A beam's reading is discretised into Q = ⌈z_max/λ_z⌉ range bins plus the no-return atom; each
//! cause's bin masses come from CDFs, so the channel is exactly normalised. For every bin the
//! backward sweep of the map update gives the bin's predictive probability P(q) = η and each
//! cell's update coefficient α_l(q); the cell's MI is H(p) − Σ_q P(q) H(p ⊙ (1 + α(μ − m̂))).
//!
//! With the pure-hit (`ijrr`) model most (cell, bin) pairs need no entropy: a bin whose Gaussian
//! support lies wholly beyond cell l leaves it the constant "seen free" posterior
//! p ⊙ (1 − μ)/(1 − m̂) (α = −1/(1 − m̂)), and a bin wholly before cell l leaves it unchanged (α = 0).
//! Those bins are pooled, which makes the cost O(N · bins-per-support · K) instead of O(N Q K)
//! with the same result. The hit Gaussian is cut at ±[`SUPPORT_SIGMAS`] σ and its mass
//! renormalised over the bins it covers (the moved tail mass is 2e-9), so that the pooled bins
//! carry exactly zero hit likelihood and the channel stays exactly normalised.

use crate::crm::update::LINEAR_ETA_MIN;
use crate::crm::CrmMap;
use crate::error::Result;
use crate::grid::check_pose;
use crate::info::crmi_channel::sweep;
pub use crate::info::crmi_channel::{
    beam_crmi, beam_posteriors, channel_masses, BeamChannel, BeamPosteriors,
};
pub use crate::info::crmi_config::{CellDedupe, CrmiConfig, CrmiQuadrature, SUPPORT_SIGMAS};
use crate::info::crmi_kl::KlBatch;
use crate::info::{Candidate, Evaluation, InfoUnits, InformationFunction};
use crate::numeric::fastmath::ln_clamped_slice;
use crate::raycast::traverse_with;
use crate::sensor::{SensorModel, SensorModelKind};

/// Per-beam scratch buffers.
#[derive(Debug, Default)]
pub struct CrmiScratch {
    channel: BeamChannel,
    probs: Vec<f64>,
    log_p: Vec<f64>,
    mhat: Vec<f64>,
    /// Σ_q P(q) KL(p'_l(q) ‖ p_l) per cell.
    kl: Vec<f64>,
    /// Σ_q P(q) α_l(q) per cell (midpoint quadrature only).
    eta_alpha: Vec<f64>,
    col: Vec<f64>,
    alpha: Vec<f64>,
    s: Vec<f64>,
    s2: Vec<f64>,
    reach: Vec<f64>,
    p_free: Vec<f64>,
    dist: Vec<f64>,
    cells: Vec<(i64, i64)>,
    per_cell: Vec<f64>,
    pose_cells: Vec<((i64, i64), f64)>,
    batch: KlBatch,
}

/// Pooled per-cell MI (nats) of one beam into `sc.per_cell`, from `sc.probs` (N × K), `sc.dist`.
///
/// The MI of a cell is the expected divergence of its posterior from its prior,
/// I_l = Σ_q P(q) KL(p'_l(q) ‖ p_l), equal to H(p_l) − Σ_q P(q) H(p'_l(q)) because the exact
/// channel is normalised (Σ_q P(q) = 1) and Bayes-consistent (Σ_q P(q) p'_l(q) = p_l). In this
/// form a bin that leaves a cell unchanged (α = 0) contributes nothing and no ln p is needed.
/// The midpoint quadrature renormalises P(q), which breaks both identities: there the entropy
/// difference is rebuilt from the same sums, H(p'_l(q)) = −(A_l + α B_l)/s − KL with
/// A_l = Σ_i p_i ln p_i and B_l = Σ_i p_i (μ_i − m̂_l) ln p_i (s = 1 up to rounding).
fn beam_crmi_pooled(cfg: &CrmiConfig, mu: &[f64], sc: &mut CrmiScratch) {
    let k = mu.len();
    let n = sc.dist.len();
    sc.channel.build(cfg, &sc.dist);
    let q_n = cfg.n_bins();
    let pure_hit = cfg.model.kind == SensorModelKind::Ijrr;
    let midpoint = cfg.quadrature == CrmiQuadrature::Midpoint;
    let ch = &sc.channel;
    sc.mhat.clear();
    sc.reach.clear();
    let mut reach = 1.0;
    for l in 0..n {
        let p = &sc.probs[l * k..(l + 1) * k];
        let m: f64 = (0..k).map(|i| mu[i] * p[i]).sum();
        sc.mhat.push(m);
        sc.reach.push(reach);
        reach *= 1.0 - m;
    }
    sc.kl.clear();
    sc.kl.resize(n, 0.0);
    sc.eta_alpha.clear();
    sc.eta_alpha.resize(n, 0.0);
    sc.p_free.clear();
    sc.p_free.resize(n + 1, 0.0);
    sc.col.resize(n, 0.0);
    sc.alpha.resize(n, 0.0);
    sc.s.resize(n, 0.0);
    let mut total = 0.0;
    let (mut lo, mut hi) = (0usize, 0usize);
    // At most one job per cell and bin of its support, one "free" job per cell and, when the
    // model gives the no-return atom mass of its own, one per cell for it (`ijrr`); one per cell
    // and bin for the other models, whose generic path queues every cell.
    let capacity = if pure_hit {
        ch.support.iter().map(|&(a, b)| b + 1 - a).sum::<usize>() + 2 * n
    } else {
        n * (q_n + 2)
    };
    let mut jobs = sc.batch.open(capacity);
    for q in 0..=q_n {
        let w = q_n + 1;
        if pure_hit && q == q_n && cfg.model.w_max == 0.0 {
            // The no-return atom: only the ∞ cause gives it, so every cell was seen free
            // (α_l = −R_l S_{l+1}/η = −1/(1 − m̂_l)) with η = Π(1 − m̂) ℓ_∞(Q): pooled with the
            // free bins of every cell.
            let eta = reach * ch.like_inf[q];
            if eta > 0.0 {
                total += eta;
                sc.p_free[n] += eta;
            }
            continue;
        }
        let range = if pure_hit && q < q_n {
            // Cells whose hit support contains bin q: a window that only moves forward with q.
            while lo < n && ch.support[lo].1 < q {
                lo += 1;
            }
            hi = hi.max(lo);
            while hi < n && ch.support[hi].0 <= q {
                hi += 1;
            }
            if lo >= hi {
                continue; // no cause can give this bin: P(q) = 0
            }
            // Only the window has likelihood; before it the beam passes, after it nothing
            // returns (ℓ_∞(q) = 0 below the atom), so the sweep starts at 0 after the window.
            // (Local slices of the window, so that the loops keep their pointers in registers.)
            let (mhat, reach) = (&sc.mhat[lo..hi], &sc.reach[lo..hi]);
            let like = |l: usize| ch.like[(lo + l) * w + q];
            let s_win = &mut sc.s[lo..hi];
            let mut s_acc = 0.0;
            for l in (0..hi - lo).rev() {
                s_win[l] = s_acc;
                let m = mhat[l];
                s_acc = m * like(l) + (1.0 - m) * s_acc;
            }
            let eta = reach[0] * s_acc;
            if eta >= LINEAR_ETA_MIN {
                let inv = 1.0 / eta;
                total += eta;
                // Cells before the window see this bin as "free" (pooled below); cells after it
                // are left unchanged (α = 0) and gain nothing from it.
                sc.p_free[lo] += eta;
                let eta_alpha = &mut sc.eta_alpha[lo..hi];
                for l in 0..hi - lo {
                    let a = reach[l] * (like(l) - s_win[l]) * inv;
                    eta_alpha[l] += eta * a;
                    jobs.push(lo + l, eta, a, mhat[l]);
                }
                continue;
            }
            // Underflow: the generic sweep below has the log-space fallback.
            lo..hi
        } else {
            0..n
        };
        for l in 0..n {
            sc.col[l] = ch.like[l * w + q];
        }
        let eta = sweep(&sc.mhat, &sc.col, ch.like_inf[q], &mut sc.s2, &mut sc.alpha);
        if eta.is_nan() || eta <= 0.0 {
            continue;
        }
        total += eta;
        if pure_hit && q < q_n {
            sc.p_free[range.start] += eta;
        }
        for l in range {
            sc.eta_alpha[l] += eta * sc.alpha[l];
            jobs.push(l, eta, sc.alpha[l], sc.mhat[l]);
        }
    }
    if pure_hit {
        // Cell l sees "free" from every bin whose window starts after l (a suffix sum of the
        // per-bin masses): one posterior per cell, α = −1/(1 − m̂).
        let mut pf = 0.0;
        for l in (0..n).rev() {
            pf += sc.p_free[l + 1];
            if pf > 0.0 {
                let a = -1.0 / (1.0 - sc.mhat[l]).max(1e-300);
                sc.eta_alpha[l] += pf * a;
                jobs.push(l, pf, a, sc.mhat[l]);
            }
        }
    }
    let used = jobs.used();
    sc.batch.close(used);
    // Every cell's sum runs in queue order, i.e. in bin order with its "free" job last.
    sc.batch.flush(&sc.probs, mu, &mut sc.kl);
    sc.per_cell.clear();
    if !midpoint {
        sc.per_cell.extend_from_slice(&sc.kl);
        return;
    }
    // I = H − r Σ_q η_q H'_q with H = −A, H'_q = −A − α_q B − KL_q and r = 1 / Σ_q η_q.
    let renorm = if total > 0.0 { 1.0 / total } else { 1.0 };
    // Pmf entries are 0 or positive normal numbers (widened from f32). A zero entry gets the
    // finite ln(MIN_POSITIVE), which only ever multiplies its own zero weight.
    sc.log_p.resize(sc.probs.len(), 0.0);
    ln_clamped_slice(&sc.probs, &mut sc.log_p);
    for l in 0..n {
        let (p, lp) = (&sc.probs[l * k..(l + 1) * k], &sc.log_p[l * k..(l + 1) * k]);
        let m = sc.mhat[l];
        let a: f64 = (0..k).map(|i| p[i] * lp[i]).sum();
        let b: f64 = (0..k).map(|i| p[i] * (mu[i] - m) * lp[i]).sum();
        let expected_h = -(a * total + b * sc.eta_alpha[l] + sc.kl[l]);
        sc.per_cell.push((-a - renorm * expected_h).max(0.0));
    }
}

/// The virtual scan a candidate records on commit: the most likely reading of each beam (the
/// first cell whose mean exceeds the threshold, else a no-return), at the candidate's pose.
#[derive(Clone, Debug, PartialEq)]
pub struct VirtualScan {
    pub pose: [f64; 3],
    /// Beam angles relative to the pose heading (rad).
    pub angles: Vec<f64>,
    /// Ranges (m); z_max for no-returns.
    pub ranges: Vec<f64>,
}

/// CRMI of candidate poses on a [`CrmMap`].
#[derive(Clone, Debug)]
pub struct Crmi {
    cfg: CrmiConfig,
}

impl Crmi {
    pub fn new(cfg: CrmiConfig) -> Result<Self> {
        cfg.validate()?;
        Ok(Self { cfg })
    }

    pub fn config(&self) -> &CrmiConfig {
        &self.cfg
    }

    /// World-frame beam angles at a candidate.
    pub fn beam_angles(&self, pose: [f64; 3]) -> Vec<f64> {
        self.cfg.beam_angles.angles(self.cfg.n_beams, pose[2])
    }

    /// CRMI (in the configured units) at `pose`, using `sc` for buffers.
    pub fn gain_with(&self, map: &CrmMap, pose: [f64; 3], sc: &mut CrmiScratch) -> Result<f64> {
        check_pose(pose)?;
        map.check_ray_reach(self.cfg.model.z_max)?;
        let mu = map.levels();
        let k = mu.len();
        let g = *map.geometry();
        let ext = map.grid().fixed_extent();
        sc.pose_cells.clear();
        let mut total = 0.0;
        for angle in self.beam_angles(pose) {
            sc.cells.clear();
            sc.dist.clear();
            let (cells, dist) = (&mut sc.cells, &mut sc.dist);
            traverse_with(
                &g,
                [pose[0], pose[1]],
                angle,
                self.cfg.model.z_max,
                ext.as_ref(),
                |c| {
                    cells.push((c.ix, c.iy));
                    dist.push(c.mid());
                    true
                },
            );
            sc.probs.clear();
            for &(ix, iy) in sc.cells.iter() {
                let p = map.cell(ix, iy);
                let inv = 1.0 / p.iter().map(|&x| x as f64).sum::<f64>();
                sc.probs.extend(p.iter().map(|&x| x as f64 * inv));
            }
            debug_assert_eq!(sc.probs.len(), sc.cells.len() * k);
            beam_crmi_pooled(&self.cfg, mu, sc);
            match self.cfg.dedupe {
                CellDedupe::Sum => total += sc.per_cell.iter().sum::<f64>(),
                CellDedupe::Max => sc
                    .pose_cells
                    .extend(sc.cells.iter().copied().zip(sc.per_cell.iter().copied())),
            }
        }
        if self.cfg.dedupe == CellDedupe::Max {
            sc.pose_cells
                .sort_by(|a, b| a.0.cmp(&b.0).then(b.1.total_cmp(&a.1)));
            sc.pose_cells.dedup_by(|a, b| a.0 == b.0);
            total = sc.pose_cells.iter().map(|c| c.1).sum();
        }
        Ok(match self.cfg.units {
            InfoUnits::Nats => total,
            InfoUnits::Bits => total / std::f64::consts::LN_2,
        })
    }

    /// The most likely scan at `pose` on the current map (see [`VirtualScan`]).
    pub fn virtual_scan(&self, map: &CrmMap, pose: [f64; 3]) -> VirtualScan {
        virtual_scan(
            map,
            pose,
            &self.beam_angles(pose),
            self.cfg.model.z_max,
            self.cfg.hit_threshold,
        )
    }
}

/// Casts the beams (world-frame `angles`) from `pose` against the map's mean: a beam returns the
/// chord midpoint of the first cell whose mean exceeds `threshold`, else z_max (a no-return).
pub fn virtual_scan(
    map: &CrmMap,
    pose: [f64; 3],
    angles: &[f64],
    z_max: f64,
    threshold: f64,
) -> VirtualScan {
    let g = *map.geometry();
    let ext = map.grid().fixed_extent();
    let ranges = angles
        .iter()
        .map(|&a| {
            let mut r = z_max;
            traverse_with(&g, [pose[0], pose[1]], a, z_max, ext.as_ref(), |c| {
                if map.mean_at(c.ix, c.iy) > threshold {
                    r = c.mid().min(z_max);
                    false
                } else {
                    true
                }
            });
            r
        })
        .collect();
    VirtualScan {
        pose,
        angles: angles.iter().map(|a| a - pose[2]).collect(),
        ranges,
    }
}

impl InformationFunction for Crmi {
    type Map = CrmMap;
    type Belief = ();
    type Update = VirtualScan;

    fn name(&self) -> &'static str {
        "crmi"
    }

    fn units(&self) -> InfoUnits {
        self.cfg.units
    }

    fn evaluate(
        &self,
        map: &CrmMap,
        parent: &(),
        candidate: &Candidate,
        seed: u64,
    ) -> Result<Evaluation<(), VirtualScan>> {
        Ok(Evaluation {
            gain: self.gain(map, parent, candidate, seed)?,
            belief: (),
            update: self.virtual_scan(map, candidate.pose),
        })
    }

    fn gain(&self, map: &CrmMap, _parent: &(), candidate: &Candidate, _seed: u64) -> Result<f64> {
        // One scratch per thread, reused across candidates (buffers and cached channels).
        thread_local! {
            static SCRATCH: std::cell::RefCell<CrmiScratch> =
                std::cell::RefCell::new(CrmiScratch::default());
        }
        SCRATCH.with(|cell| self.gain_with(map, candidate.pose, &mut cell.borrow_mut()))
    }

    fn commit(&self, map: &mut CrmMap, update: &VirtualScan) -> Result<()> {
        commit_virtual_scan(map, update, &self.cfg.model)
    }
}

/// Applies a virtual scan to the map with `model` (the map mutation of planner-spec 3.5).
pub fn commit_virtual_scan(
    map: &mut CrmMap,
    scan: &VirtualScan,
    model: &SensorModel,
) -> Result<()> {
    let mut sc = crate::crm::CrmScratch::default();
    map.update_scan(
        scan.pose,
        &scan.angles,
        &scan.ranges,
        model,
        &crate::crm::ScanOptions::default(),
        &mut sc,
    )?;
    Ok(())
}
