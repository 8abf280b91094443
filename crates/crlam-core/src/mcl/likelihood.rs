//! The CRM predictive likelihood of a scan on a fixed map (crm-spec 4.1), read from a
//! [`MeanField`].
//!
//! For one beam, η = Σ_l R_l m̂_l L_l(z) + R_{N+1} L_∞(z) with R_l = Π_{j<l} (1 − m̂_j): the
//! probability that the beam is returned by cell l times the likelihood of the reading if it is,
//! summed over the cells of the ray and the "nothing in range" cause. It is the exact predictive
//! likelihood of the reading under the map's beliefs, and it needs only m̂ along the ray, which
//! the field holds. The walk is the forward walk of the SLAM filters
//! (`crm::forward`), with two differences:
//!
//! - the means come from the field's flat array (no tiles, no pmf sums);
//! - it stops once the rest of the ray can change η by at most a relative `tail_tolerance`:
//!   every cause still ahead of cell l has a likelihood at most `sup` (a bound that holds beyond
//!   the reading's hit window, [`MixtureReading::bound_beyond`]) and they share a probability
//!   of at most R_l, so stopping when R_l · sup ≤ tolerance · η_so_far leaves out less than
//!   that fraction of η. Each beam's log η is then low by less than `tail_tolerance` (and never
//!   high). With 2^-60 the result is the SLAM filter's to rounding;
//! - with a tail tolerance of at least [`HIT_TABLE_ERROR`] (1e-7; the default is 1e-6) the hit
//!   density's truncation normaliser comes from a table of Φ ([`crate::mcl::hit_table`]), which
//!   moves each beam's log η by less than 1e-7 either way;
//! - the hit window around the reading is as wide as the tolerance needs (`hit_reach`): causes
//!   whose hit term is below `tail_tolerance` times the likelihood floor w_r/z_max (which
//!   bounds every cause's likelihood from below) have it left out, which leaves out less than
//!   `tail_tolerance` of η. At 2^-60 the window is the SLAM filters'
//!   ([`SensorModel::negligible_hit_distance`]); at the default 1e-6 it is about 6 σ either side
//!   instead of about 9 σ.
//!
//! The stated error of the localizer's likelihood: each beam's log η lies within
//! [−2·tail_tolerance − 1e-7, +1e-7] of the exact one (tested on random maps and scans).
//!
//! Causes before the window have no short term and, at the window's reach, no hit term, so
//! together they contribute (1 − R_a)·w_r/z_max, R_a being the reach where the window starts:
//! only the cells of the window and past it evaluate likelihoods.

use crate::crm::beam::{plan_beam, ScanOptions};
use crate::crm::far_simd::{far_phase, FarStop};
use crate::crm::lane_io::LANES;
use crate::error::{config_err, CrlamError, Result};
use crate::mcl::field::MeanField;
use crate::mcl::hit_table::{hit_density_table, HIT_TABLE_ERROR};
use crate::pose::Pose;
use crate::raycast::{FastWalk, WalkCell};
use crate::sensor::{CauseKernel, MixtureReading, SensorModel, SensorModelKind};

/// How the localizer's likelihood is computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LikelihoodSettings {
    /// The beam model: Thrun's mixture (the SLAM filters' weight model) with w_rand > 0 and
    /// w_max > 0, so that every reading has a likelihood of at least w_rand/z_max or w_max.
    pub model: SensorModel,
    /// Relative part of η a walk may leave out (see the module documentation), in (0, 0.01].
    pub tail_tolerance: f64,
    /// Leave no-returns out of the likelihood (AMCL's likelihood field does; for lasers whose
    /// failed readings come as no-returns, e.g. on dark surfaces).
    pub skip_no_returns: bool,
}

impl LikelihoodSettings {
    /// Checks the model and the tolerance.
    pub fn validate(&self) -> Result<()> {
        self.model.validate()?;
        if self.model.kind != SensorModelKind::Mixture {
            return Err(config_err(
                "weight_model",
                format!(
                    "localization weighs with the mixture model, got {}",
                    self.model.kind.name()
                ),
            ));
        }
        if !(self.model.w_rand > 0.0 && self.model.w_max > 0.0) {
            return Err(config_err(
                "weight_model",
                "localization needs w_rand > 0 and w_max > 0 (every reading must have a likelihood)",
            ));
        }
        if !(self.tail_tolerance > 0.0 && self.tail_tolerance <= 0.01) {
            return Err(config_err(
                "tail_tolerance",
                format!("must be in (0, 0.01], got {}", self.tail_tolerance),
            ));
        }
        Ok(())
    }
}

/// One beam's likelihood and how much of it the map explains.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeamEta {
    /// log η.
    pub log_eta: f64,
    /// The part of η from the w_hit terms of the cells the map holds occupied (m̂ > 0.5)
    /// returning the beam at the reading (or, for a no-return, of nothing in range), over η: the
    /// posterior probability that the mapped walls, not noise or cells the map knows little about,
    /// explain the reading.
    pub explained: f64,
}

/// log η of one beam from `origin` along `angle` with the reading `reading` (a mixture reading
/// of `ray_length` metres of ray: z_max for the mixture).
pub fn beam_log_eta(
    field: &MeanField,
    reading: &MixtureReading,
    origin: [f64; 2],
    angle: f64,
    ray_length: f64,
    tail_tolerance: f64,
) -> BeamEta {
    let mut walk = FastWalk::new(field.geometry(), origin, angle, ray_length, field.window());
    // m̂ read at the walk's index when the whole ray is stored (the common case), else by cell
    // with a bounds check.
    if field.holds_ray(origin, ray_length) {
        let values = field.values();
        // holds_ray: every index of this walk lies in `values`.
        let mean = |wc: &WalkCell| values[wc.index as usize];
        let far = far_phase_scalar(&mut walk, &mean, reading, tail_tolerance);
        finish_beam(walk, far, &mean, reading, tail_tolerance)
    } else {
        let mean = |wc: &WalkCell| field.mean_at(wc.cell.ix, wc.cell.iy);
        let far = far_phase_scalar(&mut walk, &mean, reading, tail_tolerance);
        finish_beam(walk, far, &mean, reading, tail_tolerance)
    }
}

/// Where a beam's far phase ended.
#[derive(Clone, Copy, Debug)]
struct FarEnd {
    /// R at the first cause past the far phase.
    reach: f64,
    /// That cause's cell, taken from the walk (the lanes leave it in the walk instead).
    first_near: Option<WalkCell>,
    /// η, when the far phase found that the rest of the ray cannot matter.
    done: Option<f64>,
}

/// Where the far phase of a reading ends: causes whose distance (chord midpoint, or the chord's
/// end for the chord kernel) lies below this are far.
fn far_end(reading: &MixtureReading, tail_tolerance: f64) -> f64 {
    if reading.is_no_return() {
        f64::NEG_INFINITY
    } else {
        reading.z() - hit_reach(reading.model(), tail_tolerance)
    }
}

/// Distance (m) from a reading beyond which a cause's hit term w_h φ̃ is below `tail_tolerance`
/// times the likelihood floor w_r/z_max, which bounds every cause's likelihood from below:
/// leaving those hit terms out (the far phase before the window, no hit term past it) leaves
/// out less than `tail_tolerance` of η. At most [`SensorModel::negligible_hit_distance`] (the
/// 2^-60 reach of the SLAM filters, which the exact likelihood keeps).
fn hit_reach(model: &SensorModel, tail_tolerance: f64) -> f64 {
    let full = model.negligible_hit_distance();
    let floor = model.w_rand / model.z_max;
    // The truncation normaliser is at least 1/2, so φ̃ ≤ 2 φ_peak e^{−u²/2}.
    let peak2 = 2.0 / (model.sigma_hit * crate::sensor::SQRT_2PI);
    let ratio = model.w_hit * peak2 / (tail_tolerance * floor);
    if !(ratio.is_finite() && floor > 0.0) {
        return full;
    }
    let sigmas = if ratio > 1.0 {
        (2.0 * ratio.ln()).sqrt()
    } else {
        0.0
    };
    (sigmas * model.sigma_hit).min(full)
}

/// The far phase of a range reading, one cell at a time: R = Π (1 − m̂) over the causes far
/// before the reading (those before [`far_end`] at the tail tolerance `tol`). Every 16 cells:
/// every cause past here has a likelihood below `sup_all`, so once R · sup_all is below the
/// tolerance times what the far causes already give, (1 − R)·far_like, the rest of the ray
/// cannot matter (a particle whose beam runs into walls before its reading). The lanes stop by
/// the same rule (`crm::far_simd::FarStop`).
#[inline(always)]
fn far_phase_scalar<M: Fn(&WalkCell) -> f64>(
    walk: &mut FastWalk,
    mean: &M,
    reading: &MixtureReading,
    tol: f64,
) -> FarEnd {
    let mut out = FarEnd {
        reach: 1.0,
        first_near: None,
        done: None,
    };
    if reading.is_no_return() {
        return out;
    }
    let lo = far_end(reading, tol);
    let chord = reading.model().kernel == CauseKernel::Chord;
    let far_like = reading.far_before();
    let sup_all = reading_bound(reading);
    let mut count = 0u32;
    let mut reach = 1.0f64;
    for wc in walk.by_ref() {
        let c = wc.cell;
        let far = if chord {
            c.t_out < lo
        } else {
            0.5 * (c.t_in + c.t_out) < lo
        };
        if !far {
            out.first_near = Some(wc);
            break;
        }
        reach *= 1.0 - mean(&wc);
        count += 1;
        if count.is_multiple_of(16) && reach * sup_all <= tol * (1.0 - reach) * far_like {
            out.done = Some((1.0 - reach) * far_like);
            break;
        }
    }
    out.reach = reach;
    out
}

/// The window and the tail of a beam after its far phase: every cause's likelihood, until the
/// stop rule holds or the ray ends.
#[inline(always)]
fn finish_beam<M: Fn(&WalkCell) -> f64>(
    walk: FastWalk,
    far: FarEnd,
    mean: &M,
    reading: &MixtureReading,
    tail_tolerance: f64,
) -> BeamEta {
    if let Some(eta) = far.done {
        return BeamEta {
            log_eta: eta.ln(),
            explained: 0.0,
        };
    }
    let model = reading.model();
    let no_return = reading.is_no_return();
    let z = reading.z();
    let hit_reach = hit_reach(model, tail_tolerance);
    let far_like = reading.far_before();
    let chord = model.kernel == CauseKernel::Chord;
    // The hit density's truncation normaliser from the table of Φ (`hit_table`) when the
    // tolerance admits its error, else computed.
    let table = tail_tolerance >= HIT_TABLE_ERROR;
    // (L, its w_hit part) of a cause in the window or past it.
    let like = |t_in: f64, t_out: f64, d: f64| {
        if chord {
            (
                reading.cell(t_in, t_out),
                model.w_hit * model.chord_hit_density(z, t_in, t_out),
            )
        } else {
            let hit = if (d - z).abs() > hit_reach {
                0.0
            } else if table {
                hit_density_table(model, z, d)
            } else {
                model.hit_density_fast(z, d)
            };
            (reading.range_cell_fast(d, hit), model.w_hit * hit)
        }
    };
    // Past `stop_from` every later cause's L and L_∞ are below `sup`.
    let (stop_from, sup) = if no_return {
        (0.0, reading.bound_beyond(0.0))
    } else {
        (z + hit_reach, reading.bound_beyond(z + hit_reach))
    };
    let reach_far = far.reach;
    let mut reach = far.reach;
    let (mut eta_near, mut eta_hit) = (0.0f64, 0.0f64);
    let mut stopped = false;
    for wc in far.first_near.into_iter().chain(walk) {
        let c = wc.cell;
        let m = mean(&wc);
        if !no_return {
            let (l, hit) = like(c.t_in, c.t_out, 0.5 * (c.t_in + c.t_out));
            eta_near += reach * m * l;
            if m > 0.5 {
                eta_hit += reach * m * hit;
            }
        }
        reach *= 1.0 - m;
        if c.t_out >= stop_from {
            // A no-return's causes are all far: (1 − R)·w_max so far.
            let eta = if no_return {
                (1.0 - reach) * far_like
            } else {
                (1.0 - reach_far) * far_like + eta_near
            };
            if reach * sup <= eta * tail_tolerance {
                stopped = true;
                break;
            }
        }
    }
    let mut eta = if no_return {
        (1.0 - reach) * far_like
    } else {
        (1.0 - reach_far) * far_like + eta_near
    };
    if !stopped {
        eta += reach * reading.infinity();
        if no_return {
            eta_hit += reach * model.w_hit;
        }
    }
    BeamEta {
        log_eta: eta.ln(),
        explained: (eta_hit / eta).clamp(0.0, 1.0),
    }
}

/// An upper bound of L_l(z) for every on-ray cause and of L_∞(z), for a range reading z: the
/// hit density at most twice its untruncated peak (the truncation normaliser is at least 1/2),
/// the short density at its largest (a cause at the reading), the floor.
fn reading_bound(reading: &MixtureReading) -> f64 {
    let m = reading.model();
    let hit = 2.0 / (m.sigma_hit * crate::sensor::SQRT_2PI);
    let short = reading.short_numerator() / -(-m.lambda_short * reading.z()).exp_m1();
    let short = if short.is_finite() {
        short
    } else {
        f64::INFINITY
    };
    m.w_hit * hit + m.w_short * short + reading.rand_floor()
}

/// The beams of a scan the localizer reads: every `stride`-th, then at most `max_beams` of
/// those spread evenly (AMCL's `laser_max_beams`; 0 keeps all).
pub fn select_beams(n_beams: usize, stride: usize, max_beams: usize) -> Vec<usize> {
    let strided: Vec<usize> = (0..n_beams).step_by(stride.max(1)).collect();
    if max_beams == 0 || strided.len() <= max_beams {
        return strided;
    }
    if max_beams == 1 {
        return vec![strided[0]];
    }
    // Evenly spread, first and last included.
    let step = (strided.len() - 1) as f64 / (max_beams - 1) as f64;
    (0..max_beams)
        .map(|i| strided[((i as f64 * step).round() as usize).min(strided.len() - 1)])
        .collect()
}

/// A scan's likelihood at one pose.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ScanFit {
    /// Σ log η over the beams used.
    pub log_likelihood: f64,
    /// Σ of the beams' explained parts ([`BeamEta::explained`]).
    pub explained: f64,
    /// Beams used (readings below z_min, or ≤ 0, are dropped as in the map update).
    pub n_beams: usize,
}

/// A range beam whose far phase runs in lanes: its walk, reading and place in the scan.
struct LaneBeam<'a> {
    walk: FastWalk,
    reading: MixtureReading<'a>,
    slot: usize,
}

/// The likelihood of the beams `beams` of a scan seen from the sensor pose `sensor`.
///
/// Range readings of the midpoint kernel whose rays the field holds run their far phase sixteen
/// beams at a time in vector lanes (`crm::far_simd`, the SLAM filters' kernel, at the level of
/// [`crate::simd::level`]), with the scalar loop's stop rule (a lane whose reach has fallen so
/// far that the rest of its ray cannot matter stops, as a beam of a particle that sees a wall
/// before its reading does); the lanes end every walk as the scalar loop would, bit for bit, and
/// the beams are summed in scan order, so the result does not depend on the level.
pub fn scan_log_likelihood(
    field: &MeanField,
    settings: &LikelihoodSettings,
    sensor: Pose,
    angles: &[f64],
    ranges: &[f64],
    beams: &[usize],
) -> Result<ScanFit> {
    scan_log_likelihood_at(
        crate::simd::level(),
        field,
        settings,
        sensor,
        angles,
        ranges,
        beams,
    )
}

/// [`scan_log_likelihood`] with the lanes at `level` (lowered to what the CPU runs).
fn scan_log_likelihood_at(
    level: crate::simd::SimdLevel,
    field: &MeanField,
    settings: &LikelihoodSettings,
    sensor: Pose,
    angles: &[f64],
    ranges: &[f64],
    beams: &[usize],
) -> Result<ScanFit> {
    if angles.len() != ranges.len() {
        return Err(CrlamError::Shape(format!(
            "scan has {} beam angles but {} ranges",
            angles.len(),
            ranges.len()
        )));
    }
    let model = &settings.model;
    let tol = settings.tail_tolerance;
    let opts = ScanOptions::default();
    let g = field.geometry();
    let res = g.resolution;
    let midpoint = model.kernel == CauseKernel::Midpoint;
    let values = field.values();
    let mean = |wc: &WalkCell| values[wc.index as usize];
    // One result per beam, summed in order at the end.
    let mut per_beam: Vec<Option<BeamEta>> = vec![None; beams.len()];
    let mut lanes: Vec<LaneBeam> = Vec::with_capacity(LANES);
    let flush = |lanes: &mut Vec<LaneBeam>, per_beam: &mut [Option<BeamEta>]| {
        let mut walks: [FastWalk; LANES] = [const { FastWalk::ended() }; LANES];
        let (mut lo, mut reach) = ([0.0; LANES], [1.0; LANES]);
        let (mut sup, mut far_like) = ([0.0; LANES], [0.0; LANES]);
        let mut stopped = [false; LANES];
        let n = lanes.len();
        for (i, b) in lanes.iter().enumerate() {
            walks[i] = b.walk.clone();
            lo[i] = far_end(&b.reading, tol);
            sup[i] = reading_bound(&b.reading);
            far_like[i] = b.reading.far_before();
        }
        // The far phase's stop rule, as the scalar loop's (`far_phase_scalar`).
        let stop = FarStop {
            sup: &sup[..n],
            far_like: &far_like[..n],
            tol,
            stopped: &mut stopped[..n],
        };
        let in_lanes = far_phase(
            level,
            &mut walks[..n],
            &lo[..n],
            &mut reach[..n],
            values,
            Some(stop),
        );
        for (i, b) in lanes.drain(..).enumerate() {
            let (walk, far) = if in_lanes {
                let far = FarEnd {
                    reach: reach[i],
                    first_near: None,
                    done: stopped[i].then(|| (1.0 - reach[i]) * far_like[i]),
                };
                (walks[i].clone(), far)
            } else {
                let mut walk = b.walk;
                let far = far_phase_scalar(&mut walk, &mean, &b.reading, tol);
                (walk, far)
            };
            per_beam[b.slot] = Some(finish_beam(walk, far, &mean, &b.reading, tol));
        }
    };
    for (slot, &b) in beams.iter().enumerate() {
        let (Some(&a), Some(&r)) = (angles.get(b), ranges.get(b)) else {
            return Err(CrlamError::Shape(format!(
                "beam {b} of a scan of {} beams",
                angles.len()
            )));
        };
        let Ok(plan) = plan_beam(model, &opts, res, [sensor[0], sensor[1]], sensor[2] + a, r)
        else {
            continue;
        };
        if plan.no_return && settings.skip_no_returns {
            continue;
        }
        let z = if plan.no_return {
            f64::INFINITY
        } else {
            plan.z
        };
        let Some(reading) = MixtureReading::new(model, z) else {
            return Err(config_err("weight_model", "must be the mixture model"));
        };
        if midpoint && !plan.no_return && field.holds_ray(plan.origin, plan.length) {
            let walk = FastWalk::new(g, plan.origin, plan.angle, plan.length, field.window());
            lanes.push(LaneBeam {
                walk,
                reading,
                slot,
            });
            if lanes.len() == LANES {
                flush(&mut lanes, &mut per_beam);
            }
        } else {
            per_beam[slot] = Some(beam_log_eta(
                field,
                &reading,
                plan.origin,
                plan.angle,
                plan.length,
                tol,
            ));
        }
    }
    if !lanes.is_empty() {
        flush(&mut lanes, &mut per_beam);
    }
    let mut fit = ScanFit::default();
    for beam in per_beam.into_iter().flatten() {
        fit.log_likelihood += beam.log_eta;
        fit.explained += beam.explained;
        fit.n_beams += 1;
    }
    Ok(fit)
}

#[cfg(test)]
#[path = "likelihood_tests.rs"]
mod tests;
