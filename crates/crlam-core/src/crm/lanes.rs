//! Weighing a group of beams in AVX-512 or AVX2 lanes (by [`crate::simd::level`]): far phase,
//! window and tail ([`super::far_simd`], [`super::window_simd`], [`super::lanes_avx2`]) and the
//! weight's final sum, sixteen beams at a time.
//!
//! Each phase does for its lanes what the windowed kernel's scalar loop ([`super::windowed`])
//! does, in its order, so a beam weighed here has the scalar weight bit for bit. A lane whose
//! window meets a cell the lanes do not handle comes back as a [`LaneStart`], and the scalar
//! kernel walks the rest of that beam from there; a beam whose ray may leave the scan's mean
//! table is left to the scalar kernel altogether.

use crate::crm::beam_job::BeamJob;
use crate::crm::far_simd::{far_phase, tail_phase};
use crate::crm::lane_io::{TailLanesIo, WindowLanesIo, LANES};
use crate::crm::map::{CrmMap, CrmScratch};
use crate::crm::update::LINEAR_ETA_MIN;
use crate::crm::window_simd::window_phase;
use crate::crm::windowed::{LaneStart, WindowedScan};
use crate::raycast::FastWalk;
use crate::sensor::SensorModel;

/// What the lanes made of a beam of the group.
#[derive(Clone, Debug, Default)]
pub(crate) enum LaneOutcome {
    /// Not taken by the lanes: the scalar kernel weighs the whole beam.
    #[default]
    Alone,
    /// The scalar kernel goes on from where the lanes stopped.
    Resume(LaneStart),
    /// Weighed: log η.
    Weighed(f64),
    /// η underflowed: the full sweep weighs the beam (as the scalar kernel would send it there).
    FullSweep,
}

impl CrmMap {
    /// Weighs the beams of `group` (at most [`LANES`]) under `weight` in lanes, as far as the
    /// lanes go; nothing where the scan has no mean table or the level is scalar.
    pub(crate) fn weigh_in_lanes(
        &self,
        k: &WindowedScan,
        weight: &SensorModel,
        group: &[BeamJob],
        sc: &CrmScratch,
    ) -> [LaneOutcome; LANES] {
        let mut out: [LaneOutcome; LANES] = Default::default();
        let level = crate::simd::level();
        if level == crate::simd::SimdLevel::Scalar {
            return out;
        }
        let Some(t) = sc.scan.mean_table() else {
            return out;
        };
        let g = *self.grid.geometry();
        let r = t.rect;
        // On the stack: a group is sixteen beams, and an allocation per group is measurable.
        let mut walks: [FastWalk; LANES] = [const { FastWalk::ended() }; LANES];
        let mut n = 0;
        let mut lane_of = [0usize; LANES];
        // Per lane: where the far phase ends, the reading, the end of the mapping ray (−∞
        // without one: the window lane then stops at once and the scalar kernel has the rest),
        // and the reading's constants.
        let (mut lo, mut z, mut map_length) = ([0.0; LANES], [0.0; LANES], [0.0; LANES]);
        let (mut numerator, mut sup_past, mut infinity) =
            ([0.0; LANES], [0.0; LANES], [0.0; LANES]);
        let mut no_return = [false; LANES];
        for (i, job) in group.iter().enumerate() {
            let (Some(w), Some(c)) = (job.w_plan.as_ref(), job.consts) else {
                continue;
            };
            let length = w.length.max(job.m_plan.map_or(0.0, |p| p.length));
            // Every cell the ray can reach lies in the table (one cell of slack each side).
            let (cx, cy) = g.cell_of(w.origin[0], w.origin[1]);
            let reach_cells = (length / g.resolution).ceil() as i64 + 2;
            let inside = cx - reach_cells >= r.ix0
                && cy - reach_cells >= r.iy0
                && cx + reach_cells < r.ix0 + r.nx
                && cy + reach_cells < r.iy0 + r.ny;
            if !inside || !c.short_numerator.is_finite() {
                continue;
            }
            let j = n;
            n += 1;
            walks[j] = FastWalk::along(&g, w.origin, job.dir, length, (r.ix0, r.iy0, r.nx));
            lo[j] = k.far_end(w);
            lane_of[j] = i;
            z[j] = w.z;
            map_length[j] = job.m_plan.map_or(f64::NEG_INFINITY, |p| p.length);
            (numerator[j], sup_past[j], infinity[j]) = (c.short_numerator, c.sup_past, c.infinity);
            no_return[j] = w.no_return;
        }
        let walks = &mut walks[..n];
        let mut reach = [1.0; LANES];
        if n == 0 || !far_phase(level, walks, &lo[..n], &mut reach[..n], &t.values, None) {
            return out;
        }
        let Some(wm) = k.window_model() else {
            return out;
        };
        let (mut reach_far, mut eta) = ([f64::NAN; LANES], [0.0; LANES]);
        let (mut at_tail, mut bailed) = ([false; LANES], [false; LANES]);
        let io = WindowLanesIo {
            walks,
            reach: &mut reach[..n],
            z: &z[..n],
            map_length: &map_length[..n],
            short_numerator: &numerator[..n],
            reach_far: &mut reach_far[..n],
            eta: &mut eta[..n],
            at_tail: &mut at_tail[..n],
            bailed: &mut bailed[..n],
        };
        if !window_phase(level, io, &t.values, &wm) {
            return out;
        }
        // The tails of the lanes that reached theirs (in place), then every finished lane's η.
        let floor = weight.w_rand / weight.z_max;
        let mut base = [0.0; LANES];
        for j in (0..n).filter(|&j| at_tail[j]) {
            // r_far: the reach at the first cell past the far phase, the tail's first if the
            // window had none.
            let r_far = if reach_far[j].is_nan() {
                reach[j]
            } else {
                reach_far[j]
            };
            base[j] = (1.0 - r_far) * floor + eta[j];
        }
        let tail_start = reach;
        let (mut mass, mut short, mut stopped) = ([0.0; LANES], [0.0; LANES], [false; LANES]);
        if at_tail[..n].iter().any(|&a| a) {
            let io = TailLanesIo {
                enabled: &at_tail[..n],
                walks,
                reach: &mut reach[..n],
                mass: &mut mass[..n],
                short: &mut short[..n],
                base: &base[..n],
                sup_past: &sup_past[..n],
                stopped: &mut stopped[..n],
            };
            if !tail_phase(level, io, &t.values, floor, -weight.lambda_short) {
                return out;
            }
        }
        for (j, walk) in walks.iter().enumerate() {
            let i = lane_of[j];
            let entered = !reach_far[j].is_nan();
            if bailed[j] {
                out[i] = LaneOutcome::Resume(LaneStart {
                    walk: walk.clone(),
                    reach: reach[j],
                    reach_far: entered.then_some(reach_far[j]),
                    eta_w: eta[j],
                });
                continue;
            }
            // The scalar kernel's end of a beam.
            let eta_w = if at_tail[j] {
                let short_scale = weight.w_short * numerator[j];
                eta[j] + (floor * mass[j] + short_scale * short[j])
            } else {
                eta[j]
            };
            // The scalar `reach_far.unwrap_or(reach)`: set at the first cell past the far phase
            // (a window cell, or the tail's first), else the final reach.
            let r_far = match (entered, at_tail[j]) {
                (true, _) => reach_far[j],
                (false, true) => tail_start[j],
                (false, false) => reach[j],
            };
            let far_like = if no_return[j] { weight.w_max } else { floor };
            let mut eta_total = (1.0 - r_far) * far_like + eta_w;
            if !stopped[j] {
                eta_total += reach[j] * infinity[j];
            }
            out[i] = if eta_total >= LINEAR_ETA_MIN && eta_total.is_finite() {
                LaneOutcome::Weighed(eta_total.ln())
            } else {
                LaneOutcome::FullSweep
            };
        }
        out
    }
}
