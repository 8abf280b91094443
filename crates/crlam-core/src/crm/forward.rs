//! The predictive likelihood η of one beam (crm-spec 4.1) by a forward walk that stops as soon
//! as the rest of the ray cannot change η in double precision.
//!
//! η = Σ_l R_l m̂_l L_l + R_N L_∞ with R_l = Π_{i<l} (1 − m̂_i), the probability that the beam
//! reaches cell l. The terms still ahead of cell l sum to at most R_l · sup L (their cause
//! probabilities sum to at most 1), so once R_l times a bound on every later L_j and on L_∞ is
//! below 2^-60 η the walk ends. With the mixture model every beam runs to z_max, so on long
//! ranges (Intel at 80 m: 800 cells of 0.1 m) this ends most walks a few cells past the wall
//! that returned the beam.
//!
//! Every L_l is at least the floor w_r/z_max, so η is too, and a cause more than
//! [`SensorModel::negligible_hit_distance`] from the reading has a hit term below 2^-60 of η:
//! before that distance a cause's L is the floor alone (its short term is 0 before the reading),
//! and the causes there contribute (1 − R_a)·w_r/z_max together, R_a being the reach where the
//! hit window starts (for the chord kernel, a cell is far if its whole chord is). Only the
//! window and the cells past the reading evaluate likelihoods. The
//! means come from the map's shared block means ([`super::mean_cache::TileMeans`]): a proposal's
//! hill climb reads the same cells dozens of times. The result equals the backward sweep of
//! [`super::update::cause_sweep`] to rounding (the sums run in the other order and the
//! exponentials are [`crate::numeric::fastmath::exp_table`]'s), not bit for bit.
//!
//! [`SensorModel::negligible_hit_distance`]: crate::sensor::SensorModel::negligible_hit_distance

use crate::crm::beam::BeamPlan;
use crate::crm::map::CrmMap;
use crate::crm::update::LINEAR_ETA_MIN;
use crate::raycast::FastWalk;
use crate::sensor::{CauseKernel, MixtureReading};

/// Relative size of the ignored rest of the ray: far below half an ulp (2^-53).
const TAIL_EPS: f64 = 1.0 / (1u64 << 60) as f64;

/// log η of the beam `plan` under `map`'s beliefs, or `None` when the linear sums underflow
/// (η < [`LINEAR_ETA_MIN`]; the caller redoes the beam in log space) or the map has a fixed
/// extent (which can turn a hit into a no-return only known at the end of the walk).
pub(crate) fn mixture_log_eta_forward(
    map: &CrmMap,
    reading: &MixtureReading,
    plan: &BeamPlan,
) -> Option<f64> {
    let tm = map.tile_means()?;
    let model = reading.model();
    let g = *map.geometry();
    let no_return = reading.is_no_return();
    let z = reading.z();
    let hit_reach = model.negligible_hit_distance();
    let lo = z - hit_reach;
    let far_like = reading.far_before();
    // Past `stop_from` every later cause's L and L_∞ are below `sup`.
    let (stop_from, sup) = if no_return {
        (0.0, reading.bound_beyond(0.0))
    } else {
        (z + hit_reach, reading.bound_beyond(z + hit_reach))
    };
    // L of a cause in the window or past it: the chord kernel needs the chord, the midpoint
    // kernel's hit term is left out beyond `hit_reach`.
    let chord = model.kernel == CauseKernel::Chord;
    let like = |t_in: f64, t_out: f64, d: f64| {
        if chord {
            reading.cell(t_in, t_out)
        } else {
            let hit = if (d - z).abs() <= hit_reach {
                model.hit_density_fast(z, d)
            } else {
                0.0
            };
            reading.range_cell_fast(d, hit)
        }
    };
    let (mut reach, mut eta_near) = (1.0f64, 0.0f64);
    let mut reach_far: Option<f64> = None;
    let mut stopped = false;
    let mut block: (i64, Option<&[f64]>) = (i64::MIN, None);
    for wc in FastWalk::new(&g, plan.origin, plan.angle, plan.length, (0, 0, 0)) {
        let c = wc.cell;
        // Consecutive cells mostly share a block: look it up again only when the key changes.
        let key = tm.key(c.ix, c.iy);
        if key != block.0 {
            block = map.mean_block(tm, c.ix, c.iy);
        }
        let m = match block.1 {
            Some(b) => b[tm.offset(c.ix, c.iy)],
            None => tm.outside(),
        };
        let d = 0.5 * (c.t_in + c.t_out);
        // A chord-kernel cause spreads over its chord: it is far only if all of it is.
        let far = no_return || if chord { c.t_out < lo } else { d < lo };
        if !far {
            reach_far.get_or_insert(reach);
            eta_near += reach * m * like(c.t_in, c.t_out, d);
        }
        reach *= 1.0 - m;
        if c.t_out >= stop_from {
            let eta = (1.0 - reach_far.unwrap_or(reach)) * far_like + eta_near;
            if reach * sup <= eta * TAIL_EPS {
                stopped = true;
                break;
            }
        }
    }
    let mut eta = (1.0 - reach_far.unwrap_or(reach)) * far_like + eta_near;
    if !stopped {
        eta += reach * reading.infinity();
    }
    (eta >= LINEAR_ETA_MIN && eta.is_finite()).then(|| eta.ln())
}
