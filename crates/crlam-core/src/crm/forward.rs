//! The predictive likelihood η of one beam (crm-spec 4.1) by a forward walk that stops as soon
//! as the rest of the ray cannot change η in double precision.
//!
//! η = Σ_l R_l m̂_l L_l + R_N L_∞ with R_l = Π_{i<l} (1 − m̂_i), the probability that the beam
//! reaches cell l. The terms still ahead of cell l sum to at most R_l · sup L (their cause
//! probabilities sum to at most 1), so once R_l times a bound on every later L_j and on L_∞ is
//! below 2^-60 η the walk ends. With the mixture model every beam runs to z_max, so on long
//! ranges (Intel at 80 m: 800 cells of 0.1 m) this ends most walks a few cells past the wall
//! that returned the beam. The result equals the backward sweep of [`super::update::cause_sweep`]
//! to rounding (the sums run in the other order), not bit for bit.

use crate::crm::beam::BeamPlan;
use crate::crm::map::CrmMap;
use crate::crm::update::LINEAR_ETA_MIN;
use crate::raycast::traverse_with;
use crate::sensor::MixtureReading;

/// Relative size of the ignored rest of the ray: far below half an ulp (2^-53).
const TAIL_EPS: f64 = 1.0 / (1u64 << 60) as f64;

/// The bound (an exp and an expm1) is checked on every `CHECK_EVERY`-th cell only.
const CHECK_EVERY: u32 = 4;

/// log η of the beam `plan` under `map`'s beliefs, or `None` when the linear sums underflow
/// (η < [`LINEAR_ETA_MIN`]; the caller redoes the beam in log space) or the map has a fixed
/// extent (which can turn a hit into a no-return only known at the end of the walk).
pub(crate) fn mixture_log_eta_forward(
    map: &CrmMap,
    reading: &MixtureReading,
    plan: &BeamPlan,
) -> Option<f64> {
    if map.grid().fixed_extent().is_some() {
        return None;
    }
    let g = *map.geometry();
    let (mut eta, mut reach) = (0.0f64, 1.0f64);
    let mut n = 0u32;
    let mut stopped = false;
    traverse_with(&g, plan.origin, plan.angle, plan.length, None, |c| {
        let m = map.mean_at(c.ix, c.iy);
        eta += reach * m * reading.cell(c.t_in, c.t_out);
        reach *= 1.0 - m;
        n += 1;
        if n.is_multiple_of(CHECK_EVERY) && reach * reading.bound_beyond(c.t_out) <= eta * TAIL_EPS
        {
            stopped = true;
            return false;
        }
        true
    });
    if !stopped {
        eta += reach * reading.infinity();
    }
    (eta >= LINEAR_ETA_MIN && eta.is_finite()).then(|| eta.ln())
}
