//! Walking scans through a [`CrmMap`]: one ray's cells and coefficients, the predictive
//! likelihood of a scan (crm-spec 4.1) and the sequential update (the batch scan is in
//! `batch.rs`).

use crate::crm::beam::{check_scan, plan_beam, BeamPlan, ScanOptions, ScanStats, ScanUpdateMode};
use crate::crm::forward::mixture_log_eta_forward;
use crate::crm::map::{CrmMap, CrmScratch};
use crate::crm::update::{apply_factor, cause_sweep, cause_sweep_log, LINEAR_ETA_MIN};
use crate::error::Result;
use crate::grid::check_pose;
use crate::raycast::traverse_with;
use crate::sensor::{MixtureReading, SensorModel, SensorModelKind};

impl CrmMap {
    /// Traverses the ray of `plan`, filling `sc.cells` and `sc.mhat` (and `sc.ids` if
    /// `batch`, see [`Self::gather_cells`]). A fixed extent truncates the ray; a hit beyond the
    /// truncation becomes a no-return over the truncated ray (2.1).
    pub(super) fn gather_ray(&self, plan: &mut BeamPlan, sc: &mut CrmScratch, batch: bool) {
        let end = self.gather_cells(plan.origin, plan.angle, plan.length, sc, batch);
        self.truncation_to_no_return(plan, end);
    }

    /// Traverses a ray of `length` (clipped to a fixed extent) into `sc.cells` / `sc.mhat`;
    /// returns where the traversal ended. With `batch`, the means come from the scan's cell
    /// table (each cell read once per scan) and `sc.ids` holds the cells' ids there.
    pub(super) fn gather_cells(
        &self,
        origin: [f64; 2],
        angle: f64,
        length: f64,
        sc: &mut CrmScratch,
        batch: bool,
    ) -> f64 {
        sc.cells.clear();
        let g = *self.grid.geometry();
        let ext = self.grid.fixed_extent();
        let cells = &mut sc.cells;
        let end = traverse_with(&g, origin, angle, length, ext.as_ref(), |c| {
            cells.push(c);
            true
        });
        sc.mhat.clear();
        sc.ids.clear();
        if batch {
            for c in sc.cells.iter() {
                let id = sc.scan.id(&self.grid, &self.mu, c.ix, c.iy);
                sc.ids.push(id);
                sc.mhat.push(sc.scan.mean(id));
            }
        } else {
            for c in sc.cells.iter() {
                sc.mhat.push(self.mean_at(c.ix, c.iy));
            }
        }
        end
    }

    /// A hit beyond where a fixed extent cut the ray is a no-return over the cut ray (2.1).
    pub(super) fn truncation_to_no_return(&self, plan: &mut BeamPlan, end: f64) {
        if self.grid.fixed_extent().is_some() && !plan.no_return && end + 1e-9 < plan.z {
            plan.no_return = true;
        }
    }

    /// Computes α for the gathered ray into `sc.alpha` and returns log η (−∞ if unexplained).
    pub(super) fn beam_alpha(
        &self,
        model: &SensorModel,
        plan: &BeamPlan,
        sc: &mut CrmScratch,
        need_alpha: bool,
    ) -> f64 {
        let n = sc.cells.len();
        sc.alpha.clear();
        sc.alpha.resize(n, 0.0);
        let z = if plan.no_return {
            f64::INFINITY
        } else {
            plan.z
        };
        if model.kind == SensorModelKind::AuthorsCode {
            return self.authors_alpha(model, plan, sc);
        }
        model.on_ray_cells(z, &sc.cells, &mut sc.like);
        let like_inf = model.infinity(z);
        let alpha = if need_alpha {
            Some(&mut sc.alpha[..])
        } else {
            None
        };
        let eta = cause_sweep(&sc.mhat, &sc.like, like_inf, &mut sc.s, alpha);
        if eta >= LINEAR_ETA_MIN && eta.is_finite() {
            return eta.ln();
        }
        // Far-off Gaussians underflowed: redo the sweep in logs (crm-spec 4.2).
        for (l, c) in sc.like.iter_mut().zip(sc.cells.iter()) {
            *l = model.log_on_ray_cell(z, c.t_in, c.t_out);
        }
        let alpha = if need_alpha {
            Some(&mut sc.alpha[..])
        } else {
            None
        };
        let mut s = std::mem::take(&mut sc.s);
        let log_eta = cause_sweep_log(&sc.mhat, &sc.like, like_inf.ln(), &mut s, alpha);
        sc.s = s;
        log_eta
    }

    /// The authors' MATLAB update restated (crm-spec 3.4): reach scaled by (1 − Δ·m̂), grid-index
    /// distances, no ∞ cause for hits. Returns log η and the equivalent α per cell.
    pub(super) fn authors_alpha(
        &self,
        model: &SensorModel,
        plan: &BeamPlan,
        sc: &mut CrmScratch,
    ) -> f64 {
        let g = self.grid.geometry();
        let res = g.resolution;
        let (rx, ry) = g.cell_of(plan.origin[0], plan.origin[1]);
        let n = sc.cells.len();
        sc.like.clear();
        let mut pass = 1.0;
        for (l, c) in sc.cells.iter().enumerate() {
            let m = sc.mhat[l];
            let w = if plan.no_return {
                pass *= 1.0 - res * m;
                pass / model.z_max
            } else {
                let dist = res * (((c.ix - rx).pow(2) + (c.iy - ry).pow(2)) as f64).sqrt();
                let w = model.authors_bsm(dist, plan.z) * m * pass;
                pass *= 1.0 - res * m;
                w
            };
            sc.like.push(w.max(0.0));
        }
        let total: f64 = sc.like.iter().sum();
        let eta = if plan.no_return {
            total + 1.0 / model.z_max
        } else {
            total
        };
        if !(eta > 0.0 && eta.is_finite()) {
            return f64::NEG_INFINITY;
        }
        let mut after = total;
        for l in 0..n {
            let p_on = sc.like[l] / eta;
            after -= sc.like[l];
            let p_after = after.max(0.0) / eta;
            let m = sc.mhat[l];
            // α = P_on/m̂ − P_after/(1 − m̂), so that the factor αμ + β equals 1 + α(μ − m̂).
            sc.alpha[l] = p_on / m - p_after / (1.0 - m).max(1e-300);
        }
        eta.ln()
    }

    /// Predictive log-likelihood Σ_beams log η of a scan under the current beliefs (crm-spec
    /// 4.1), without changing the map. Returns (sum, beams used); dropped readings add nothing.
    pub fn scan_log_likelihood(
        &self,
        pose: [f64; 3],
        angles: &[f64],
        ranges: &[f64],
        model: &SensorModel,
        opts: &ScanOptions,
        sc: &mut CrmScratch,
    ) -> Result<(f64, usize)> {
        check_scan(angles, ranges, model, opts)?;
        check_pose(pose)?;
        self.check_ray_reach(model.z_max)?;
        let res = self.grid.geometry().resolution;
        let mut total = 0.0;
        let mut used = 0;
        for b in (0..angles.len()).step_by(opts.beam_stride) {
            let Ok(mut plan) = plan_beam(
                model,
                opts,
                res,
                [pose[0], pose[1]],
                pose[2] + angles[b],
                ranges[b],
            ) else {
                continue;
            };
            used += 1;
            let z = if plan.no_return {
                f64::INFINITY
            } else {
                plan.z
            };
            let forward = MixtureReading::new(model, z)
                .and_then(|r| mixture_log_eta_forward(self, &r, &plan));
            if let Some(log_eta) = forward {
                total += log_eta;
                continue;
            }
            self.gather_ray(&mut plan, sc, false);
            total += self.beam_alpha(model, &plan, sc, false);
        }
        Ok((total, used))
    }

    /// Updates the map with one scan taken from the sensor pose `pose` (x, y, θ); beam b points
    /// at θ + `angles[b]` and read `ranges[b]` (crm-spec 3.1, 3.3).
    pub fn update_scan(
        &mut self,
        pose: [f64; 3],
        angles: &[f64],
        ranges: &[f64],
        model: &SensorModel,
        opts: &ScanOptions,
        sc: &mut CrmScratch,
    ) -> Result<ScanStats> {
        if opts.mode == ScanUpdateMode::Batch {
            return Ok(self
                .batch_scan(pose, angles, ranges, None, model, opts, sc, true)?
                .2);
        }
        check_scan(angles, ranges, model, opts)?;
        self.grid.prepare_scan(pose, model.z_max)?;
        let res = self.grid.geometry().resolution;
        let mut st = ScanStats::default();
        for b in (0..angles.len()).step_by(opts.beam_stride) {
            st.n_beams += 1;
            let mut plan = match plan_beam(
                model,
                opts,
                res,
                [pose[0], pose[1]],
                pose[2] + angles[b],
                ranges[b],
            ) {
                Ok(p) => p,
                Err(_) => {
                    st.n_dropped_short += 1;
                    continue;
                }
            };
            self.gather_ray(&mut plan, sc, false);
            if sc.cells.is_empty() {
                st.n_empty_ray += 1;
                continue;
            }
            let log_eta = self.beam_alpha(model, &plan, sc, true);
            if !log_eta.is_finite() {
                st.n_skipped_eta += 1;
                continue;
            }
            st.n_used += 1;
            st.n_no_return += usize::from(plan.no_return);
            for l in 0..sc.cells.len() {
                let (ix, iy) = (sc.cells[l].ix, sc.cells[l].iy);
                let ok = self.apply_to_cell(ix, iy, sc.alpha[l], sc.mhat[l])?;
                st.n_cell_updates += usize::from(ok);
                st.n_frozen += usize::from(!ok);
            }
        }
        Ok(st)
    }

    pub(super) fn apply_to_cell(
        &mut self,
        ix: i64,
        iy: i64,
        alpha: f64,
        mhat: f64,
    ) -> Result<bool> {
        let k = self.mu.len();
        let mut p = [0.0f64; 65];
        let stored = self.grid.get(ix, iy);
        let mut s = 0.0;
        for i in 0..k {
            p[i] = stored[i] as f64;
            s += p[i];
        }
        for x in p[..k].iter_mut() {
            *x /= s;
        }
        if !apply_factor(&mut p[..k], &self.mu, alpha, mhat, self.floor) {
            return Ok(false);
        }
        self.means.invalidate();
        let dst = self.grid.get_mut(ix, iy)?;
        for i in 0..k {
            dst[i] = p[i] as f32;
        }
        Ok(true)
    }
}
