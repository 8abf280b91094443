//! One beam of a batch scan with the cells far before the reading folded into pass counts
//! (crm-spec 3.1, 3.3, 4.1): the default [`BatchKernel::Windowed`] of the batch update and of
//! the fused weight + update walk.
//!
//! Under the `ijrr` mapping model the coefficient of cell l is α_l = R_l (L_l − S_{l+1}) / η,
//! and α_l (1 − m̂_l) = −(1 − F_l/η − R_l L_l/η) with F_l = Σ_{j<l} π_j L_j. Where no cause up to
//! l can explain the reading, α_l = −1/(1 − m̂_l) and the factor 1 + α_l (μ − m̂_l) is
//! (1 − μ)/(1 − m̂_l): the same shape for every such beam, the constant removed by the
//! normalisation. A cell passed by n such beams of a scan is multiplied by (1 − μ_k)^n once, at
//! write-back ([`super::scan_cells`]). Every cell of a no-return beam is such a pass (L_l = 0,
//! L_∞ = 1, exactly).
//!
//! For a hit at z, only the cells whose chord midpoint is within W σ below z, and those up to the
//! end of the mapping ray (z + 6σ + Δ), are swept with likelihoods. The cells before them ("far"
//! cells) cost a mean lookup, a reach product and, on every beam, an upper bound of the mass the
//! window ignores: Σ_far R_j · 2 φ_peak e^{−⌊u_j⌋²/2} with u_j = (z − d_j)/σ (a table; the
//! truncation normaliser is at least ½). A beam whose bound is not below 2^-60 of the window's
//! η, or whose window η underflows, is redone by the full sweep ([`BatchKernel::FullRay`]), so
//! the result equals the full sweep to rounding on every beam.
//!
//! The mixture weight of the same beam needs no check: every L_j ≥ w_r/z_max so η ≥ w_r/z_max,
//! and W is chosen per scan so that the hit terms of the far cells are below 2^-60 of that floor.
//! The far cells then contribute (1 − R_a)·w_r/z_max (their cause probabilities sum to
//! 1 − R_a; their short term is 0 before the reading), and the cells past the mapping ray are
//! summed forward until the rest of the ray cannot change η ([`super::forward`]'s rule); past
//! the hit reach their short terms are buffered and summed after the walk, a slice of
//! exponentials at a time.
//!
//! The weight never depends on the update (a beam whose map part needs the full sweep keeps its
//! windowed weight), so a weight-only call (`update = false`, used by a filter that updates only
//! the maps resampling keeps) does none of the update's work and gives the same weight bit for
//! bit; such beams may then be weighed sixteen at a time in lanes ([`super::lanes`]), which
//! hand a beam back to this kernel ([`LaneStart`]) where they stop.
//!
//! [`BatchKernel::Windowed`]: super::beam::BatchKernel::Windowed
//! [`BatchKernel::FullRay`]: super::beam::BatchKernel::FullRay

use crate::crm::beam::{BeamPlan, ScanStats};
use crate::crm::beam_job::BeamJob;
use crate::crm::scan_cells::ScanCells;
use crate::crm::update::LINEAR_ETA_MIN;
use crate::grid::{GridGeometry, TiledGrid};
use crate::raycast::{FastWalk, MIN_CHORD};
use crate::sensor::{
    CauseKernel, MixtureReading, SensorModel, SensorModelKind, GAUSS_CUTOFF_SIGMAS,
};

/// Relative size of what the window may ignore: far below half an ulp (2^-53).
pub(crate) const TAIL_EPS: f64 = 1.0 / (1u64 << 60) as f64;

/// A factor within this of 1 (|α| small) is skipped; one within this of the pass shape
/// (|α (1 − m̂) + 1| small) is counted as a pass. Both differ from the swept factor by less than
/// 2^-50 relative, far below the f32 storage of the pmfs.
const FACTOR_EPS: f64 = 1.0 / (1u64 << 50) as f64;

/// The window starts at least this many σ of the mapping model below the reading.
const MAP_WINDOW_SIGMAS: f64 = 10.0;

/// The pass-count bound is checked on every `CHECK_EVERY`-th cell past the mapping ray.
const CHECK_EVERY: u32 = 4;

/// Length of the bound table: e^{−k²/2} for k = ⌊u⌋ up to the Gaussian cutoff, 0 beyond.
const BOUND_TABLE: usize = GAUSS_CUTOFF_SIGMAS as usize + 2;

/// A cell of the window: its scan-table id, pre-scan mean, chord (cut at the mapping ray's end)
/// and the probability that the beam reaches it.
#[derive(Clone, Copy, Debug)]
struct WindowCell {
    id: u32,
    mhat: f64,
    t_in: f64,
    t_out: f64,
    reach: f64,
    /// The weight's hit density at the whole chord's midpoint (NaN if not computed).
    hit: f64,
    /// The chord was cut at the end of the mapping ray (its midpoint differs from the weight's).
    cut: bool,
    like: f64,
    s_next: f64,
}

/// Reusable buffers of the windowed beams (one per thread, inside the map scratch).
#[derive(Debug, Default)]
pub(crate) struct WindowScratch {
    far: Vec<u32>,
    window: Vec<WindowCell>,
    /// Past the mapping ray and the hit reach: each cause's probability π and −λd, whose short
    /// terms are summed after the walk (exponentials a slice at a time).
    tail_pi: Vec<f64>,
    tail_x: Vec<f64>,
}

impl WindowScratch {
    /// Σ π / (1 − e^{−λd}) over the buffered tail, in walk order (consumes the exponents).
    fn tail_short(&mut self) -> f64 {
        crate::numeric::fastmath::exp_for_sums(&mut self.tail_x);
        self.tail_pi
            .iter()
            .zip(&self.tail_x)
            .map(|(&pi, &e)| pi / (1.0 - e))
            .sum()
    }
}

/// Per-scan constants of the windowed kernel; `None` from [`WindowedScan::new`] when the scan's
/// models are not the ones it handles (the full sweep then does every beam).
#[derive(Clone, Debug)]
pub(crate) struct WindowedScan<'a> {
    mapping: &'a SensorModel,
    weight: Option<&'a SensorModel>,
    /// Window start below the reading (m).
    below: f64,
    /// 2 φ_peak e^{−k²/2} of the mapping model, 0 from the cutoff on.
    bound: [f64; BOUND_TABLE],
    inv_sigma: f64,
    /// Beyond this distance past the reading (m) the weight's hit term is below 2^-60 of its
    /// floor w_r/z_max and is left out (∞ when the floor is 0).
    weight_hit_reach: f64,
    /// The weight's hit density equals the mapping model's (same σ and z_max): computed once.
    shared_hit: bool,
}

/// Where the lanes left a weighed beam (after its far phase and, where they could, its window):
/// the walk, the reach, the reach at the window's first cell if the window was entered, and the
/// window's Σ π·L so far.
#[derive(Clone, Debug)]
pub(crate) struct LaneStart {
    pub(crate) walk: FastWalk,
    pub(crate) reach: f64,
    pub(crate) reach_far: Option<f64>,
    pub(crate) eta_w: f64,
}

/// What became of a beam.
pub(crate) enum WindowedBeam {
    /// Applied to the scan table; the weight's log η when the beam is weighed.
    Done(Option<f64>),
    /// The weight (log η, if weighed) is done, but the map update needs the full sweep; nothing
    /// was applied.
    MapFullSweep(Option<f64>),
    /// Nothing applied: the caller sweeps the whole ray for the weight and the update.
    FullSweep,
}

impl<'a> WindowedScan<'a> {
    /// The kernel for `mapping` (`ijrr`, midpoint causes) and an optional `weight` model
    /// (`mixture`, midpoint causes, the same z_max); `None` for any other combination.
    pub(crate) fn new(mapping: &'a SensorModel, weight: Option<&'a SensorModel>) -> Option<Self> {
        if mapping.kind != SensorModelKind::Ijrr || mapping.kernel != CauseKernel::Midpoint {
            return None;
        }
        let sqrt_2pi = (2.0 * std::f64::consts::PI).sqrt();
        let mut below = MAP_WINDOW_SIGMAS * mapping.sigma_hit;
        let mut weight_hit_reach = f64::INFINITY;
        if let Some(w) = weight {
            if w.kind != SensorModelKind::Mixture
                || w.kernel != CauseKernel::Midpoint
                || w.z_max != mapping.z_max
            {
                return None;
            }
            // Far hit terms below 2^-60 of the floor w_r/z_max (so of η).
            let reach = w.negligible_hit_distance();
            below = below.max(reach);
            if w.w_rand > 0.0 {
                weight_hit_reach = reach;
            }
        }
        let peak2 = 2.0 / (mapping.sigma_hit * sqrt_2pi);
        let mut bound = [0.0; BOUND_TABLE];
        for (k, b) in bound.iter_mut().enumerate().take(BOUND_TABLE - 1) {
            *b = peak2 * (-0.5 * (k * k) as f64).exp();
        }
        Some(Self {
            mapping,
            weight,
            below,
            bound,
            inv_sigma: 1.0 / mapping.sigma_hit,
            weight_hit_reach,
            shared_hit: weight.is_some_and(|w| w.sigma_hit == mapping.sigma_hit),
        })
    }

    /// The weight model and hit reach, for the window lanes ([`super::window_simd`], [`super::lane_io::WindowModel`]).
    pub(crate) fn window_model(&self) -> Option<super::lane_io::WindowModel> {
        self.weight.map(|w| super::lane_io::WindowModel {
            model: *w,
            hit_reach: self.weight_hit_reach,
        })
    }

    /// Where the far phase of a weighed beam ends: cells with a chord midpoint below this
    /// need only the reach (+∞ for a no-return: all of them).
    pub(crate) fn far_end(&self, w_plan: &BeamPlan) -> f64 {
        if w_plan.no_return {
            f64::INFINITY
        } else {
            w_plan.z - self.below
        }
    }

    /// Weighs (`w_plan`) and updates (`m_plan`) one beam, both from the same reading, walked
    /// along the unit vector `dir` of the plans' angle; the map has no fixed extent. Counters go to `st` only when the beam is done here. The weight
    /// does not depend on the update (only on `m_plan`'s length, where the tail check starts), so
    /// with `update = false` it is the one the updating call gives, bit for bit, and none of
    /// the update's work is done.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn beam(
        &self,
        grid: &TiledGrid<f32>,
        mu: &[f64],
        scan: &mut ScanCells,
        ws: &mut WindowScratch,
        job: &BeamJob,
        update: bool,
        start: Option<LaneStart>,
        st: &mut ScanStats,
    ) -> WindowedBeam {
        let (w_plan, m_plan, dir) = (job.w_plan.as_ref(), job.m_plan.as_ref(), job.dir);
        let Some(any) = w_plan.or(m_plan) else {
            return WindowedBeam::Done(None);
        };
        let (origin, z, no_return) = (any.origin, any.z, any.no_return);
        let reading = match (self.weight, w_plan) {
            (Some(w), Some(_)) => {
                let r = match job.consts {
                    Some(c) => MixtureReading::with_short_numerator(w, z, c.short_numerator),
                    None => MixtureReading::new(w, z),
                };
                match r {
                    Some(r) => Some(r),
                    None => return WindowedBeam::FullSweep,
                }
            }
            _ => None,
        };
        let m_len = m_plan.map_or(0.0, |p| p.length);
        let length = m_len.max(w_plan.map_or(0.0, |p| p.length));
        let lo = z - self.below;
        let bound_from = z - (BOUND_TABLE - 1) as f64 * self.mapping.sigma_hit;
        // Cause likelihood of a far cell under the weight model (hit and short terms vanish).
        let far_like = match &reading {
            Some(r) => r.far_before(),
            None => 0.0,
        };
        let g: GridGeometry = *grid.geometry();
        ws.far.clear();
        ws.window.clear();
        ws.tail_pi.clear();
        ws.tail_x.clear();
        // Σ π of the buffered tail: its floor part w_r/z_max · Σ π is known during the walk.
        let mut tail_mass = 0.0f64;
        let mut bound = 0.0f64;
        let mut past = 0u32;
        let mut stopped = false;
        let map_on = m_plan.is_some();
        // Past the mapping ray, every cause's L and L_∞ are below this (checked every cell); a
        // weight-only beam checks the bound at each cell's distance instead.
        let sup_past = match (&reading, map_on) {
            (Some(r), true) => job
                .consts
                .map_or_else(|| r.bound_beyond(m_len), |c| c.sup_past),
            _ => f64::INFINITY,
        };
        let Some(window) = scan.dense_window() else {
            return WindowedBeam::FullSweep;
        };
        let map_work = map_on && update;
        // Weighing only, the lanes may have walked part of the beam already.
        debug_assert!(start.is_none() || !update);
        let (walk, mut reach, mut reach_far, mut eta_w) = match start {
            Some(s) => (s.walk, s.reach, s.reach_far, s.eta_w),
            None => (
                FastWalk::along(&g, origin, dir, length, window),
                1.0,
                None,
                0.0,
            ),
        };
        for wc in walk {
            let c = wc.cell;
            // Only an update needs the cell registered in the scan table.
            let (id, m) = if update {
                let id = scan.id_at(wc.index as usize, grid, mu, c.ix, c.iy);
                (id, scan.mean(id))
            } else {
                (
                    0,
                    scan.pre_scan_mean(wc.index as usize, grid, mu, c.ix, c.iy),
                )
            };
            let in_map = map_on && c.t_in < m_len && m_len - c.t_in >= MIN_CHORD;
            let d = 0.5 * (c.t_in + c.t_out);
            if no_return || d < lo {
                if in_map && update {
                    ws.far.push(id as u32);
                    // Beyond the table's last entry the hit density is 0 (and so is the bound).
                    if !no_return && d > bound_from {
                        let k = ((z - d) * self.inv_sigma) as usize;
                        bound += reach * self.bound[k.min(BOUND_TABLE - 1)];
                    }
                }
                reach *= 1.0 - m;
                continue;
            }
            let r_far = *reach_far.get_or_insert(reach);
            let mut hit = f64::NAN;
            if let (Some(r), Some(w)) = (&reading, self.weight) {
                if !in_map && map_on && d - z > self.weight_hit_reach {
                    // Past the reading and the hit reach: floor + short term, summed later.
                    let pi = reach * m;
                    ws.tail_pi.push(pi);
                    ws.tail_x.push(-w.lambda_short * d);
                    tail_mass += pi;
                } else {
                    hit = if (d - z).abs() <= self.weight_hit_reach {
                        w.hit_density_fast(z, d)
                    } else {
                        0.0
                    };
                    eta_w += reach * m * r.range_cell_fast(d, hit);
                }
            }
            if in_map && update {
                ws.window.push(WindowCell {
                    id: id as u32,
                    mhat: m,
                    t_in: c.t_in,
                    t_out: c.t_out.min(m_len),
                    reach,
                    hit,
                    cut: c.t_out > m_len,
                    like: 0.0,
                    s_next: 0.0,
                });
            }
            reach *= 1.0 - m;
            if !in_map {
                let Some(r) = &reading else {
                    break;
                };
                past += 1;
                // A lower bound of η: the buffered short terms are left out.
                let total = (1.0 - r_far) * far_like + eta_w + r.rand_floor() * tail_mass;
                let stop = if map_on {
                    reach * sup_past <= total * TAIL_EPS
                } else {
                    past.is_multiple_of(CHECK_EVERY)
                        && reach * r.bound_beyond(c.t_out) <= total * TAIL_EPS
                };
                if stop {
                    stopped = true;
                    break;
                }
            }
        }
        let r_far = reach_far.unwrap_or(reach);

        if let Some(r) = &reading {
            if !ws.tail_x.is_empty() {
                eta_w += r.rand_floor() * tail_mass + r.short_scale() * ws.tail_short();
            }
        }
        let log_eta_w = match &reading {
            Some(r) => {
                let mut eta = (1.0 - r_far) * far_like + eta_w;
                if !stopped {
                    eta += reach * job.consts.map_or_else(|| r.infinity(), |c| c.infinity);
                }
                if !(eta >= LINEAR_ETA_MIN && eta.is_finite()) {
                    return WindowedBeam::FullSweep;
                }
                Some(eta.ln())
            }
            None => None,
        };
        if !map_work {
            return WindowedBeam::Done(log_eta_w);
        }
        if ws.far.is_empty() && ws.window.is_empty() {
            return WindowedBeam::MapFullSweep(log_eta_w);
        }
        if no_return {
            // η = R_end under ijrr; an underflowed or zero η is left to the log-space sweep.
            if reach.is_nan() || reach < LINEAR_ETA_MIN {
                return WindowedBeam::MapFullSweep(log_eta_w);
            }
            count_passes(scan, &ws.far, st);
            st.n_used += 1;
            st.n_no_return += 1;
            return WindowedBeam::Done(log_eta_w);
        }
        // Backward sweep over the window (S past its end is L_∞), then η and α.
        let model = self.mapping;
        let mut s = model.infinity(z);
        for c in ws.window.iter_mut().rev() {
            // The weight's hit density is the mapping model's where the chord is whole (the last
            // cell of the mapping ray may be cut) and it was computed, not left out, there.
            let d = 0.5 * (c.t_in + c.t_out);
            let shared = self.shared_hit
                && !c.cut
                && !c.hit.is_nan()
                && (d - z).abs() <= self.weight_hit_reach;
            c.like = if shared {
                c.hit
            } else {
                model.hit_density_fast(z, d)
            };
            c.s_next = s;
            s = c.mhat * c.like + (1.0 - c.mhat) * s;
        }
        let eta = r_far * s;
        if !(eta >= LINEAR_ETA_MIN && eta.is_finite()) || bound > eta * TAIL_EPS {
            return WindowedBeam::MapFullSweep(log_eta_w);
        }
        let inv = 1.0 / eta;
        for c in &ws.window {
            let alpha = c.reach * (c.like - c.s_next) * inv;
            let id = c.id as usize;
            if (alpha * (1.0 - c.mhat) + 1.0).abs() <= FACTOR_EPS {
                scan.pass(id, st);
            } else if alpha.abs() <= FACTOR_EPS {
                scan.unchanged(id, st);
            } else {
                scan.apply(grid, id, alpha, c.mhat, mu, st);
            }
        }
        count_passes(scan, &ws.far, st);
        st.n_used += 1;
        WindowedBeam::Done(log_eta_w)
    }
}

fn count_passes(scan: &mut ScanCells, far: &[u32], st: &mut ScanStats) {
    for &id in far {
        scan.pass(id as usize, st);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::crm::beam::{plan_beam, ScanOptions};
    use crate::crm::{CrmConfig, CrmMap, CrmScratch, LevelPlacement};
    use crate::grid::CellRect;

    /// A beam along +x from a cell centre, reading `z`, on a map with endpoint levels where the
    /// cells from `free_from` m on are certainly free (m̂ ≈ the floor): the window around the
    /// reading then explains it so poorly that the far cells' bound is not negligible, and the
    /// beam must go to the full sweep; with ordinary beliefs it is done here.
    fn outcome(free_from: Option<f64>) -> bool {
        let g = GridGeometry::new([0.0, 0.0], 0.2).unwrap();
        let mut cfg = CrmConfig::new(g);
        cfg.placement = LevelPlacement::Endpoints;
        let mut map = CrmMap::new(&cfg).unwrap();
        if let Some(x0) = free_from {
            let rect = CellRect {
                ix0: (x0 / 0.2) as i64,
                iy0: 0,
                nx: 30,
                ny: 1,
            };
            let k = map.levels().len();
            let mut pmf = vec![1e-13; k];
            pmf[0] = 1.0;
            map.set_beliefs(rect, &pmf.repeat(30)).unwrap();
        }
        let model = SensorModel::with_defaults(SensorModelKind::Ijrr, 8.0, 0.2);
        let kernel = WindowedScan::new(&model, None).unwrap();
        let plan = plan_beam(&model, &ScanOptions::default(), 0.2, [0.1, 0.1], 0.0, 4.05).unwrap();
        let mut sc = CrmScratch::default();
        sc.scan.begin(map.geometry(), [0.1, 0.1], 8.0, None, false);
        let mut st = ScanStats::default();
        let out = kernel.beam(
            map.grid(),
            map.levels(),
            &mut sc.scan,
            &mut sc.window,
            &BeamJob {
                w_plan: None,
                m_plan: Some(plan),
                dir: [1.0, 0.0],
                consts: None,
            },
            true,
            None,
            &mut st,
        );
        match out {
            WindowedBeam::Done(_) => true,
            WindowedBeam::MapFullSweep(_) => false,
            WindowedBeam::FullSweep => {
                panic!("the beam is not weighed: only the map can fall back")
            }
        }
    }

    #[test]
    fn a_window_that_cannot_explain_the_reading_goes_to_the_full_sweep() {
        assert!(outcome(None));
        assert!(!outcome(Some(3.4)));
    }
}
