//! The batch scan (crm-spec 3.3, 4.3): weight and update of every beam from the pre-scan beliefs,
//! one walk per beam, through the windowed kernel (sixteen beams at a time in lanes when only
//! weighing, [`super::lanes`]) or the full sweep, and the factors written back once.

use std::sync::Arc;

use crate::crm::beam::{
    check_scan, plan_beam, BatchKernel, BeamPlan, ScanOptions, ScanStats, ScanUpdateMode,
};
use crate::crm::beam_job::BeamJob;
use crate::crm::lane_io::LANES;
use crate::crm::lanes::LaneOutcome;
use crate::crm::map::{CrmMap, CrmScratch};
use crate::crm::mean_cache::MeanTable;
use crate::crm::scan_cells::scan_window;
use crate::crm::windowed::{LaneStart, WindowedBeam, WindowedScan};
use crate::error::Result;
use crate::sensor::SensorModel;

/// Scan windows up to this many cells (8 m at 0.05 m, 25 m at 0.2 m) get a mean table of their
/// own even when the map is not shared.
const SMALL_WINDOW_CELLS: usize = 1 << 17;

/// A beam's part of a scan's weight.
#[derive(Clone, Copy, Debug)]
enum BeamOutcome {
    /// Weighed: its log η.
    Weighed(f64),
    Unweighed,
}

impl From<Option<f64>> for BeamOutcome {
    fn from(log_eta: Option<f64>) -> Self {
        log_eta.map_or(Self::Unweighed, Self::Weighed)
    }
}

impl BeamOutcome {
    /// The full sweep's (log η, weighed); its log η is 0 when not weighed.
    fn from_full_ray(ll: f64, weighed: bool) -> Self {
        if weighed {
            Self::Weighed(ll)
        } else {
            Self::Unweighed
        }
    }
}

impl CrmMap {
    /// Weighs a scan under the pre-update beliefs (Σ log η with `weight_model` over every
    /// `weight_stride`-th beam, crm-spec 4.1) and then updates the map with `mapping_model`
    /// (`opts`), walking each beam once. The result equals [`Self::scan_log_likelihood`] followed
    /// by [`Self::update_scan`]; in batch mode both use the pre-scan beliefs, so one traversal
    /// serves both (sequential mode falls back to the two calls). Returns (Σ log η, beams
    /// weighed, update counters).
    #[allow(clippy::too_many_arguments)]
    pub fn weigh_and_update_scan(
        &mut self,
        pose: [f64; 3],
        angles: &[f64],
        ranges: &[f64],
        weight_model: &SensorModel,
        weight_stride: usize,
        mapping_model: &SensorModel,
        opts: &ScanOptions,
        sc: &mut CrmScratch,
    ) -> Result<(f64, usize, ScanStats)> {
        let wopts = ScanOptions {
            beam_stride: weight_stride,
            ..*opts
        };
        if opts.mode != ScanUpdateMode::Batch {
            let (ll, used) =
                self.scan_log_likelihood(pose, angles, ranges, weight_model, &wopts, sc)?;
            let st = self.update_scan(pose, angles, ranges, mapping_model, opts, sc)?;
            return Ok((ll, used, st));
        }
        check_scan(angles, ranges, weight_model, &wopts)?;
        self.batch_scan(
            pose,
            angles,
            ranges,
            Some((weight_model, weight_stride)),
            mapping_model,
            opts,
            sc,
            true,
        )
    }

    /// The weight of [`Self::weigh_and_update_scan`] with the same arguments, bit for bit,
    /// without updating the map: (Σ log η, beams weighed). A particle filter weighs every
    /// particle this way and updates only the maps that resampling keeps (most of them are
    /// dropped when the weights are peaked). The map is not changed (its storage may grow to
    /// cover the scan, which changes no belief).
    #[allow(clippy::too_many_arguments)]
    pub fn weigh_scan(
        &mut self,
        pose: [f64; 3],
        angles: &[f64],
        ranges: &[f64],
        weight_model: &SensorModel,
        weight_stride: usize,
        mapping_model: &SensorModel,
        opts: &ScanOptions,
        sc: &mut CrmScratch,
    ) -> Result<(f64, usize)> {
        let wopts = ScanOptions {
            beam_stride: weight_stride,
            ..*opts
        };
        if opts.mode != ScanUpdateMode::Batch {
            return self.scan_log_likelihood(pose, angles, ranges, weight_model, &wopts, sc);
        }
        check_scan(angles, ranges, weight_model, &wopts)?;
        let (ll, used, _) = self.batch_scan(
            pose,
            angles,
            ranges,
            Some((weight_model, weight_stride)),
            mapping_model,
            opts,
            sc,
            false,
        )?;
        Ok((ll, used))
    }

    /// True if [`Self::weigh_scan`] with `opts` and reach `z_max` runs the windowed kernel on a
    /// window mean table of its own (at most [`SMALL_WINDOW_CELLS`] cells: 8 m at 0.05 m), so
    /// that a caller weighing many nearby poses on one copy of the map reads one table. Long
    /// ranges on fine grids (80 m at 0.1 m: 2.6 M cells a table) are better served by
    /// [`Self::scan_log_likelihood`], which reads the map's block means only where beams go.
    pub(crate) fn weighs_in_a_small_window(&self, z_max: f64, opts: &ScanOptions) -> bool {
        // The window's size depends on the reach and the cell size only, not on the position.
        let g = self.grid.geometry();
        let window = scan_window(g, g.origin, z_max);
        opts.mode == ScanUpdateMode::Batch
            && opts.kernel == BatchKernel::Windowed
            && self.grid.fixed_extent().is_none()
            && window.nx > 0
            && window.n_cells() <= SMALL_WINDOW_CELLS
    }

    /// The batch scan (crm-spec 3.3) with an optional weight: every beam's coefficients from
    /// the pre-scan beliefs, one walk per beam for the weight and the update, factors multiplied
    /// per cell and written back once. `opts.kernel` picks the windowed kernel where it applies.
    /// With `update = false` only the weight is computed (the same, bit for bit).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn batch_scan(
        &mut self,
        pose: [f64; 3],
        angles: &[f64],
        ranges: &[f64],
        weight: Option<(&SensorModel, usize)>,
        mapping_model: &SensorModel,
        opts: &ScanOptions,
        sc: &mut CrmScratch,
        update: bool,
    ) -> Result<(f64, usize, ScanStats)> {
        check_scan(angles, ranges, mapping_model, opts)?;
        let z_max = weight.map_or(mapping_model.z_max, |(w, _)| {
            w.z_max.max(mapping_model.z_max)
        });
        self.grid.prepare_scan(pose, z_max)?;
        let res = self.grid.geometry().resolution;
        let origin = [pose[0], pose[1]];
        let mut st = ScanStats::default();
        let windowed = if opts.kernel == BatchKernel::Windowed && self.grid.fixed_extent().is_none()
        {
            WindowedScan::new(mapping_model, weight.map(|(w, _)| w))
        } else {
            None
        };
        // The window's means in one table: read row by row, they cost less than the cells' first
        // reads from the tiles (scattered along the beams) unless the window is much larger
        // than what the scan touches (long ranges on fine grids); there only a table other
        // copies of the map share pays for itself.
        let window = scan_window(self.grid.geometry(), origin, z_max);
        let small = window.n_cells() <= SMALL_WINDOW_CELLS;
        let means = (windowed.is_some() && window.nx > 0 && (small || self.means.is_shared()))
            .then(|| {
                self.means.table(window, |rect, out| {
                    // The rectangle is valid and `out` sized for it, so this cannot fail.
                    let _ = self.means_into(rect, out);
                })
            });
        sc.scan
            .begin(self.grid.geometry(), origin, z_max, means, opts.hits_first);
        // Beam directions by the angle-sum rule from the scan's (cos, sin) table, which every
        // particle of a filter shares: one sin/cos pair per beam and scan instead of per particle.
        sc.directions.prepare(angles);
        let (s0, c0) = pose[2].sin_cos();
        // Likewise the readings' pose-independent constants, for the windowed kernel's weights.
        let readings = match (&windowed, weight) {
            (Some(_), Some((w, stride))) => {
                let wopts = ScanOptions {
                    beam_stride: stride,
                    ..*opts
                };
                sc.readings
                    .prepare(w, &wopts, mapping_model, opts, res, ranges);
                Some(&sc.readings)
            }
            _ => None,
        };
        let mut jobs = std::mem::take(&mut sc.jobs);
        jobs.clear();
        for b in 0..angles.len() {
            let angle = pose[2] + angles[b];
            let w_plan = match weight {
                Some((w, stride)) if b % stride == 0 => {
                    let wopts = ScanOptions {
                        beam_stride: stride,
                        ..*opts
                    };
                    plan_beam(w, &wopts, res, origin, angle, ranges[b]).ok()
                }
                _ => None,
            };
            let m_plan = if b % opts.beam_stride == 0 {
                st.n_beams += 1;
                let p = plan_beam(mapping_model, opts, res, origin, angle, ranges[b]).ok();
                st.n_dropped_short += usize::from(p.is_none());
                p
            } else {
                None
            };
            if (w_plan.is_none() && m_plan.is_none()) || (!update && w_plan.is_none()) {
                continue;
            }
            jobs.push(BeamJob {
                w_plan,
                m_plan,
                dir: sc.directions.rotated(b, c0, s0),
                consts: readings.and_then(|t| t.get(b)),
            });
        }
        let weight_model = weight.map(|(w, _)| w);
        let mut sums = (0.0, 0);
        let mut add = |out: BeamOutcome| {
            if let BeamOutcome::Weighed(l) = out {
                sums.0 += l;
                sums.1 += 1;
            }
        };
        match (&windowed, weight_model) {
            // Weighing only: sixteen beams at a time in lanes, each beam the lanes hand back (or
            // did not take) by the scalar kernel; the weights are summed in beam order.
            (Some(k), Some(w)) if !update && sc.scan.mean_table().is_some() => {
                for group in jobs.chunks(LANES) {
                    let lanes = self.weigh_in_lanes(k, w, group, sc);
                    for (job, lane) in group.iter().zip(lanes) {
                        // Without a kernel, `finish_beam` is the full sweep.
                        let (kernel, start) = match lane {
                            LaneOutcome::Weighed(l) => {
                                add(BeamOutcome::Weighed(l));
                                continue;
                            }
                            LaneOutcome::FullSweep => (None, None),
                            LaneOutcome::Resume(s) => (Some(k), Some(s)),
                            LaneOutcome::Alone => (Some(k), None),
                        };
                        let out = self.finish_beam(
                            kernel,
                            weight_model,
                            mapping_model,
                            job,
                            start,
                            update,
                            sc,
                            &mut st,
                        );
                        add(out);
                    }
                }
            }
            (k, _) => {
                for job in &jobs {
                    let out = self.finish_beam(
                        k.as_ref(),
                        weight_model,
                        mapping_model,
                        job,
                        None,
                        update,
                        sc,
                        &mut st,
                    );
                    add(out);
                }
            }
        }
        sc.jobs = jobs;
        let (total, used) = sums;
        if update {
            // The window table of the pre-scan map, carried over the write: the scan changes only
            // the cells it touched, so refreshing those gives the new map's table, bit for bit
            // what a fresh fill would hold, at a small part of its cost (a particle's next scan,
            // 0.5 m on, usually lies within the table's margin). The other copies of the pre-scan
            // map keep the pre-scan table; the written map's is a copy unless no other holds it.
            let carried = self.means.window_table();
            self.means.invalidate();
            sc.scan.release_mean_table();
            sc.scan.write_back(&mut self.grid, &self.mu, self.floor)?;
            if let Some(table) = carried {
                let mut table = Arc::try_unwrap(table).unwrap_or_else(|shared| MeanTable {
                    rect: shared.rect,
                    values: shared.values.clone(),
                });
                sc.scan.refresh_means(&self.grid, &self.mu, &mut table);
                self.means.set_window_table(table);
            }
        }
        Ok((total, used, st))
    }

    /// Weighs and (with `update`) updates one beam: the windowed kernel `k` where it can (from
    /// where the lanes left it when `start` is given), the full sweep where it cannot.
    #[allow(clippy::too_many_arguments)]
    fn finish_beam(
        &self,
        k: Option<&WindowedScan>,
        weight_model: Option<&SensorModel>,
        mapping_model: &SensorModel,
        job: &BeamJob,
        start: Option<LaneStart>,
        update: bool,
        sc: &mut CrmScratch,
        st: &mut ScanStats,
    ) -> BeamOutcome {
        if let Some(k) = k {
            let out = k.beam(
                &self.grid,
                &self.mu,
                &mut sc.scan,
                &mut sc.window,
                job,
                update,
                start,
                st,
            );
            match out {
                WindowedBeam::Done(log_eta) => return BeamOutcome::from(log_eta),
                WindowedBeam::MapFullSweep(log_eta) => {
                    self.full_ray_beam(None, None, mapping_model, job.m_plan, 0.0, sc, st);
                    return BeamOutcome::from(log_eta);
                }
                WindowedBeam::FullSweep => {}
            }
        }
        let (ll, weighed) = self.full_ray_beam(
            weight_model,
            job.w_plan,
            mapping_model,
            if update { job.m_plan } else { None },
            job.m_plan.map_or(0.0, |p| p.length),
            sc,
            st,
        );
        BeamOutcome::from_full_ray(ll, weighed)
    }

    /// One beam of a batch scan by the full sweep ([`BatchKernel::FullRay`]): its weight (log η,
    /// and whether it was weighed) and its factors into the scan table.
    /// `walk_at_least` (m) lengthens the gathered ray as an update would (so that a weight-only
    /// call sees the cells the updating one sees).
    #[allow(clippy::too_many_arguments)]
    fn full_ray_beam(
        &self,
        weight_model: Option<&SensorModel>,
        w_plan: Option<BeamPlan>,
        mapping_model: &SensorModel,
        m_plan: Option<BeamPlan>,
        walk_at_least: f64,
        sc: &mut CrmScratch,
        st: &mut ScanStats,
    ) -> (f64, bool) {
        let Some(any) = w_plan.or(m_plan) else {
            return (0.0, false);
        };
        let length = w_plan
            .map_or(0.0, |p| p.length)
            .max(m_plan.map_or(0.0, |p| p.length))
            .max(walk_at_least);
        let end = self.gather_cells(any.origin, any.angle, length, sc, true);
        let (mut total, mut weighed) = (0.0, false);
        // The longer ray is evaluated first; the shorter one is then a prefix of it.
        let weight_first = w_plan.map_or(0.0, |p| p.length) >= m_plan.map_or(0.0, |p| p.length);
        for stage in 0..2 {
            let is_weight = (stage == 0) == weight_first;
            let Some(mut plan) = (if is_weight { w_plan } else { m_plan }) else {
                continue;
            };
            truncate_ray(sc, plan.length);
            let cut = end.min(plan.length);
            self.truncation_to_no_return(&mut plan, cut);
            if is_weight {
                if let Some(w) = weight_model {
                    total += self.beam_alpha(w, &plan, sc, false);
                    weighed = true;
                }
                continue;
            }
            if sc.cells.is_empty() {
                st.n_empty_ray += 1;
                continue;
            }
            let log_eta = self.beam_alpha(mapping_model, &plan, sc, true);
            if !log_eta.is_finite() {
                st.n_skipped_eta += 1;
                continue;
            }
            st.n_used += 1;
            st.n_no_return += usize::from(plan.no_return);
            for l in 0..sc.cells.len() {
                sc.scan
                    .apply(&self.grid, sc.ids[l], sc.alpha[l], sc.mhat[l], &self.mu, st);
            }
        }
        (total, weighed)
    }
}

/// Cuts a gathered ray to `length`: drops cells that start at or beyond it and ends the last
/// chord there, exactly as a traversal of that length would have reported them.
fn truncate_ray(sc: &mut CrmScratch, length: f64) {
    let keep = sc
        .cells
        .iter()
        .take_while(|c| c.t_in < length && length - c.t_in >= crate::raycast::MIN_CHORD)
        .count();
    sc.cells.truncate(keep);
    sc.mhat.truncate(keep);
    sc.ids.truncate(keep);
    if let Some(last) = sc.cells.last_mut() {
        last.t_out = last.t_out.min(length);
    }
}

#[cfg(test)]
mod tests {
    use crate::crm::beam::{BatchKernel, ScanOptions};
    use crate::crm::map::{CrmConfig, CrmMap, CrmScratch};
    use crate::grid::GridGeometry;
    use crate::sensor::{SensorModel, SensorModelKind};

    /// With hits first, a cell that one beam of the scan ends in keeps that beam's update alone
    /// when another beam of the scan passes through it on its way to a farther hit; cells that
    /// no beam hits take every factor as before. Without it the passing beam erodes the hit.
    /// The windowed kernel and the full sweep agree either way; a sequential update refuses it.
    #[test]
    fn hits_first_keeps_a_hit_that_another_beam_of_the_scan_passes() {
        use crate::crm::beam::ScanUpdateMode;
        let g = GridGeometry::new([0.0123, -0.0271], 0.1).unwrap();
        let fresh = || CrmMap::new(&CrmConfig::new(g)).unwrap();
        let model = SensorModel::with_defaults(SensorModelKind::Ijrr, 8.0, 0.1);
        let mut sc = CrmScratch::default();
        // Two beams along +x: one ends at 2.05 m, the other passes there and ends at 4.05 m.
        let (near, far) = ([0.0], [2.05]);
        let both = ([0.0, 0.0], [2.05, 4.05]);
        let hit = g.cell_of(2.05, 0.0);
        let passed = g.cell_of(3.05, 0.0);
        let update = |angles: &[f64], ranges: &[f64], opts: &ScanOptions, sc: &mut CrmScratch| {
            let mut m = fresh();
            m.update_scan([0.0, 0.0, 0.0], angles, ranges, &model, opts, sc)
                .unwrap();
            m
        };
        for kernel in [BatchKernel::Windowed, BatchKernel::FullRay] {
            let plain = ScanOptions {
                kernel,
                ..ScanOptions::default()
            };
            let first = ScanOptions {
                hits_first: true,
                ..plain
            };
            let alone = update(&near, &far, &plain, &mut sc);
            let passing_alone = update(&[0.0], &[4.05], &plain, &mut sc);
            let eroded = update(&both.0, &both.1, &plain, &mut sc);
            let kept = update(&both.0, &both.1, &first, &mut sc);
            let m0 = alone.mean_at(hit.0, hit.1);
            assert!(m0 > 0.6, "{kernel:?}: the hit cell's mean {m0}");
            assert!(eroded.mean_at(hit.0, hit.1) < m0 - 0.1, "{kernel:?}");
            for (a, b) in kept.cell(hit.0, hit.1).iter().zip(alone.cell(hit.0, hit.1)) {
                assert!((a - b).abs() <= 1e-7, "{kernel:?}: {a} vs {b}");
            }
            // A cell only the far beam reaches takes its factors with or without hits first.
            assert_eq!(
                kept.cell(passed.0, passed.1),
                passing_alone.cell(passed.0, passed.1)
            );
        }
        let windowed = ScanOptions {
            hits_first: true,
            ..ScanOptions::default()
        };
        let full = ScanOptions {
            kernel: BatchKernel::FullRay,
            ..windowed
        };
        let (a, b) = (
            update(&both.0, &both.1, &windowed, &mut sc),
            update(&both.0, &both.1, &full, &mut sc),
        );
        for c in [hit, passed, g.cell_of(1.05, 0.0)] {
            assert!((a.mean_at(c.0, c.1) - b.mean_at(c.0, c.1)).abs() < 1e-9);
        }
        let sequential = ScanOptions {
            mode: ScanUpdateMode::Sequential,
            ..windowed
        };
        let mut m = fresh();
        let err = m
            .update_scan([0.0; 3], &both.0, &both.1, &model, &sequential, &mut sc)
            .unwrap_err();
        assert!(err.to_string().contains("hits_first"), "{err}");
    }

    /// The window table a batch update carries over equals a fresh fill of the written map's
    /// means bit for bit, whether the pre-scan table was the map's alone or shared with a copy
    /// (which keeps the pre-scan means).
    #[test]
    fn the_carried_window_table_equals_a_fresh_fill() {
        let g = GridGeometry::new([0.0123, -0.0271], 0.1).unwrap();
        let mut map = CrmMap::new(&CrmConfig::new(g)).unwrap();
        let model = SensorModel::with_defaults(SensorModelKind::Ijrr, 8.0, 0.1);
        let weight = SensorModel::with_defaults(SensorModelKind::Mixture, 8.0, 0.1);
        let opts = ScanOptions {
            kernel: BatchKernel::Windowed,
            ..ScanOptions::default()
        };
        let angles: Vec<f64> = (0..181).map(|i| (i as f64 - 90.0).to_radians()).collect();
        let mut sc = CrmScratch::default();
        let mut copy = None;
        for k in 0..8 {
            // A room-like scan: readings between 1 and 9 m, some beyond z_max.
            let ranges: Vec<f64> = (0..angles.len())
                .map(|b| 1.0 + ((b * 37 + k * 11) % 80) as f64 / 10.0)
                .collect();
            let pose = [0.3 * k as f64, 0.1 * k as f64, 0.05 * k as f64];
            map.weigh_scan(pose, &angles, &ranges, &weight, 1, &model, &opts, &mut sc)
                .unwrap();
            let before = map.window_means().expect("the weight fills a window table");
            if k == 3 {
                // A copy shares the table: the update must not write into it.
                copy = Some((map.clone(), before.values.clone()));
            }
            map.update_scan(pose, &angles, &ranges, &model, &opts, &mut sc)
                .unwrap();
            let carried = map
                .window_means()
                .expect("the update carries the table over");
            assert_eq!(carried.rect, before.rect);
            let mut fresh = vec![0.0; carried.rect.n_cells()];
            map.means_into(carried.rect, &mut fresh).unwrap();
            let same = carried
                .values
                .iter()
                .zip(&fresh)
                .all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(
                same,
                "scan {k}: the carried table differs from a fresh fill"
            );
            assert!(
                carried.values != before.values,
                "scan {k}: the update changed no mean"
            );
        }
        let (copy, kept) = copy.unwrap();
        assert_eq!(copy.window_means().unwrap().values, kept);
    }
}
