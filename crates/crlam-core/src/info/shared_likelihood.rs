//! Scan log-likelihoods of many poses under one shared CRM: UCRMI's particle weights (crm-spec
//! 6.4 step 3), the predictive likelihood of crm-spec 4.1 evaluated for every particle of a node
//! against the planner's single map.
//!
//! The result equals [`CrmMap::scan_log_likelihood`] to rounding (tested at 1e-12 relative). It
//! is faster for three reasons that do not change the model:
//! - the cells' means m̂ are read from a dense window filled once for all particles, not summed
//!   from the pmf at every visit;
//! - the cause sweep runs forward during the traversal (η = Σ_l R_l m̂_l L_l + R_end L_∞ with the
//!   reach R_l = Π_{j<l} (1 − m̂_j)), so nothing is gathered into buffers;
//! - the hit Gaussian is evaluated only where it can change L_l: beyond `hit_cutoff` standard
//!   deviations its term is below 2⁻⁶⁰ of the random floor w_rand / z_max that every L_l carries,
//!   so adding it would not change a single bit of L_l; where the density's truncation normaliser
//!   is 1 (causes more than 8.3σ from both range limits) it is one inlined table exponential
//!   ([`crate::numeric::fastmath::exp_table`], libm's call was a sixth of the time) times precomputed
//!   w_hit/(σ√(2π)), without the divisions of the general density.
//!
//! Beams the fast path does not cover exactly (a hit beyond where the map's fixed extent cuts the
//! ray, an η small enough for the log-space sweep, the authors' model or the chord kernel) are
//! handed to [`CrmMap::scan_log_likelihood`].

use rayon::prelude::*;

use crate::crm::beam::plan_beam;
use crate::crm::update::LINEAR_ETA_MIN;
use crate::crm::{with_thread_scratch, CrmMap, CrmScratch, ScanOptions};
use crate::error::{CrlamError, Result};
use crate::grid::{check_pose, CellRect};
use crate::numeric::fastmath::exp_table;
use crate::raycast::traverse_with;
use crate::sensor::{normal_cdf, CauseKernel, SensorModel, SensorModelKind, GAUSS_CUTOFF_SIGMAS};

/// Above this λd, 1 − e^{−λd} from [`exp_table`] is within a few ulp (relative); below it, expm1.
const SHORT_FAST_EXP_MIN: f64 = 0.1;

/// Below this many visited cells per window cell the window costs more than it saves.
const MIN_VISITS_PER_WINDOW_CELL: f64 = 0.5;

/// A read-only view of a [`CrmMap`] for many scan likelihoods under one sensor model.
pub struct SharedMapLikelihood<'a> {
    map: &'a CrmMap,
    model: SensorModel,
    /// Dense m̂ over `rect` (row-major, iy then ix); empty when no window was built.
    means: Vec<f64>,
    rect: CellRect,
    /// |z − d| / σ beyond which the hit term cannot change L_l.
    hit_cutoff: f64,
    /// L_l = floor + w_hit·hit + w_short·short for a hit reading.
    floor: f64,
    /// The fast path applies (midpoint kernel, `ijrr` or `mixture`).
    fast: bool,
    /// w_hit/(σ√(2π)), 1/σ and the untruncated cause range of the hit density, so that the hit
    /// term costs one exponential and no division where the truncation does not apply.
    hit_scale: f64,
    inv_sigma: f64,
    untruncated: (f64, f64),
}

impl<'a> SharedMapLikelihood<'a> {
    /// Prepares scans from `poses` (the window covers every cell a ray of length z_max from any
    /// of them can reach). `expected_visits` is the caller's estimate of cell visits (beams ×
    /// cells per beam × poses); the window is only built when it pays off.
    pub fn new(
        map: &'a CrmMap,
        model: &SensorModel,
        poses: &[[f64; 3]],
        expected_visits: f64,
    ) -> Result<Self> {
        model.validate()?;
        for &p in poses {
            check_pose(p)?;
        }
        let fast = model.kernel == CauseKernel::Midpoint
            && matches!(model.kind, SensorModelKind::Ijrr | SensorModelKind::Mixture);
        let floor = if model.kind == SensorModelKind::Mixture {
            model.w_rand / model.z_max
        } else {
            0.0
        };
        let mut out = Self {
            map,
            model: *model,
            means: Vec::new(),
            rect: CellRect {
                ix0: 0,
                iy0: 0,
                nx: 0,
                ny: 0,
            },
            hit_cutoff: hit_cutoff(model, floor),
            floor,
            fast,
            hit_scale: model.w_hit / (model.sigma_hit * (2.0 * std::f64::consts::PI).sqrt()),
            inv_sigma: 1.0 / model.sigma_hit,
            untruncated: model.untruncated_hit_range(),
        };
        if fast && !poses.is_empty() {
            if let Some(rect) = window_rect(map, poses, model.z_max) {
                if expected_visits >= MIN_VISITS_PER_WINDOW_CELL * rect.n_cells() as f64 {
                    out.means = window_means(map, rect)?;
                    out.rect = rect;
                }
            }
        }
        Ok(out)
    }

    /// Cells in the window of means (0 when none was built).
    pub fn window_cells(&self) -> usize {
        self.means.len()
    }

    #[inline]
    fn mean(&self, ix: i64, iy: i64) -> f64 {
        if self.rect.contains(ix, iy) {
            let r = &self.rect;
            self.means[((iy - r.iy0) * r.nx + (ix - r.ix0)) as usize]
        } else {
            self.map.mean_at(ix, iy)
        }
    }

    /// Σ log η over the beams of one scan at `pose` (`angles` in the robot frame, rad; `ranges`
    /// in m), every beam (stride 1), default [`ScanOptions`]. Equals
    /// [`CrmMap::scan_log_likelihood`] to rounding.
    pub fn scan_log_likelihood(
        &self,
        pose: [f64; 3],
        angles: &[f64],
        ranges: &[f64],
        sc: &mut CrmScratch,
    ) -> Result<f64> {
        let opts = ScanOptions::default();
        if !self.fast {
            return self
                .map
                .scan_log_likelihood(pose, angles, ranges, &self.model, &opts, sc)
                .map(|(ll, _)| ll);
        }
        check_pose(pose)?;
        if angles.len() != ranges.len() {
            return Err(CrlamError::Shape(format!(
                "scan has {} beam angles but {} ranges",
                angles.len(),
                ranges.len()
            )));
        }
        let mut total = 0.0;
        for (b, (&a, &r)) in angles.iter().zip(ranges).enumerate() {
            if !a.is_finite() {
                return Err(CrlamError::Shape(format!(
                    "beam angle {b} is not finite ({a})"
                )));
            }
            total += match self.beam_log_eta(pose, a, r) {
                Some(v) => v,
                None => {
                    self.map
                        .scan_log_likelihood(pose, &[a], &[r], &self.model, &opts, sc)?
                        .0
                }
            };
        }
        Ok(total)
    }

    /// log η of one beam, or `None` when the general path must decide (see the module docs).
    fn beam_log_eta(&self, pose: [f64; 3], angle: f64, range: f64) -> Option<f64> {
        let m = &self.model;
        let res = self.map.geometry().resolution;
        let Ok(plan) = plan_beam(
            m,
            &ScanOptions::default(),
            res,
            [pose[0], pose[1]],
            pose[2] + angle,
            range,
        ) else {
            return Some(0.0); // dropped reading: contributes nothing, as in the general path
        };
        let ext = self.map.grid().fixed_extent();
        let z = plan.z;
        // |z − d| < cut·σ, the cells where the hit term can change L_l; d_lo ≤ z always.
        let half_width = self.hit_cutoff * m.sigma_hit;
        let (d_lo, d_hi) = ((z - half_width).min(z), z + half_width);
        // w_short λ e^{−λz}: the short density of a cause at d ≥ z is this / (1 − e^{−λd}).
        let short_num = if m.w_short > 0.0 {
            m.w_short * m.lambda_short * (-m.lambda_short * z).exp()
        } else {
            0.0
        };
        let (mut eta, mut reach) = (0.0f64, 1.0f64);
        let end = traverse_with(
            self.map.geometry(),
            plan.origin,
            plan.angle,
            plan.length,
            ext.as_ref(),
            |c| {
                let mhat = self.mean(c.ix, c.iy);
                let like = if plan.no_return {
                    m.w_max
                } else {
                    let d = c.mid();
                    let mut l = self.floor;
                    // Before the hit window only the floor remains (no short term for d < z).
                    if d > d_lo {
                        if d < d_hi {
                            l += if d > self.untruncated.0 && d < self.untruncated.1 {
                                let u = (z - d) * self.inv_sigma;
                                self.hit_scale * exp_table(-0.5 * u * u)
                            } else {
                                m.w_hit * m.hit_density(z, d)
                            };
                        }
                        if short_num > 0.0 && d >= z && d > 0.0 {
                            let x = m.lambda_short * d;
                            // 1 − e^{−x} loses no precision from exp once x is not small.
                            let one_minus = if x > SHORT_FAST_EXP_MIN {
                                1.0 - exp_table(-x)
                            } else {
                                -(-x).exp_m1()
                            };
                            l += short_num / one_minus;
                        }
                    }
                    l
                };
                eta += reach * mhat * like;
                reach *= 1.0 - mhat;
                true
            },
        );
        if ext.is_some() && !plan.no_return && end + 1e-9 < plan.z {
            return None; // the extent cut the ray before the hit: a no-return (crm-spec 2.1)
        }
        let z_inf = if plan.no_return { f64::INFINITY } else { z };
        eta += reach * m.infinity(z_inf);
        (eta >= LINEAR_ETA_MIN && eta.is_finite()).then(|| eta.ln())
    }

    /// Scan log-likelihoods of many poses (one scan, rotated with each pose), in parallel;
    /// equal to the serial loop whatever the thread count.
    pub fn scan_log_likelihoods(
        &self,
        poses: &[[f64; 3]],
        angles: &[f64],
        ranges: &[f64],
    ) -> Result<Vec<f64>> {
        poses
            .par_iter()
            .map(|&p| with_thread_scratch(|sc| self.scan_log_likelihood(p, angles, ranges, sc)))
            .collect()
    }
}

/// The smallest |z − d|/σ at which w_hit·φ̃(z; d) < 2⁻⁶⁰·floor for every cause distance d, so
/// that adding the hit term cannot change a bit of L_l ≥ floor. Without a floor (`ijrr`), the
/// density's own cutoff.
fn hit_cutoff(model: &SensorModel, floor: f64) -> f64 {
    if floor <= 0.0 || model.w_hit <= 0.0 {
        return if model.w_hit > 0.0 {
            GAUSS_CUTOFF_SIGMAS
        } else {
            0.0
        };
    }
    let s = model.sigma_hit;
    // The truncation normaliser Z(d) = Φ((z_max − d)/σ) − Φ(−d/σ) is smallest at an end of
    // [0, z_max]; the density is at most its peak over that.
    let z_min = (normal_cdf(model.z_max / s) - 0.5).min(0.5 - normal_cdf(-model.z_max / s));
    let peak = model.w_hit / (s * (2.0 * std::f64::consts::PI).sqrt() * z_min.max(1e-300));
    let ratio = peak / (floor * 2f64.powi(-60));
    if ratio <= 1.0 {
        return 0.0;
    }
    (2.0 * ratio.ln()).sqrt().min(GAUSS_CUTOFF_SIGMAS)
}

/// The cells any ray of length `z_max` from `poses` can visit, within the map's fixed extent.
fn window_rect(map: &CrmMap, poses: &[[f64; 3]], z_max: f64) -> Option<CellRect> {
    let g = map.geometry();
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for p in poses {
        x0 = x0.min(p[0]);
        y0 = y0.min(p[1]);
        x1 = x1.max(p[0]);
        y1 = y1.max(p[1]);
    }
    let reach = z_max + 2.0 * g.resolution;
    let (ix0, iy0) = g.cell_of(x0 - reach, y0 - reach);
    let (ix1, iy1) = g.cell_of(x1 + reach, y1 + reach);
    let mut r = CellRect {
        ix0,
        iy0,
        nx: ix1 - ix0 + 1,
        ny: iy1 - iy0 + 1,
    };
    if let Some(e) = map.grid().fixed_extent() {
        let (ax, ay) = (r.ix0.max(e.ix0), r.iy0.max(e.iy0));
        let (bx, by) = (
            (r.ix0 + r.nx).min(e.ix0 + e.nx),
            (r.iy0 + r.ny).min(e.iy0 + e.ny),
        );
        r = CellRect {
            ix0: ax,
            iy0: ay,
            nx: bx - ax,
            ny: by - ay,
        };
    }
    (r.nx > 0 && r.ny > 0 && r.n_cells() <= 1 << 24).then_some(r)
}

fn window_means(map: &CrmMap, r: CellRect) -> Result<Vec<f64>> {
    let mut means = vec![0.0; r.n_cells()];
    map.means_into(r, &mut means)?;
    Ok(means)
}
