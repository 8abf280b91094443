//! The authors' two CRMI variants, restated for comparison (crm-spec 5.3, 5.4). Neither is the
//! expected information gain of Eq. 2 (that is [`crate::info::crmi::Crmi`]); both exist so that
//! figures can be set beside the public code's.
//!
//! - [`MlScanBinary`] (R3, CARE/BKIO `action_CRMI`): one CRM update with the most likely scan at
//!   the candidate and the drop of Σ H_b(m̂) over the map.
//! - [`R1Map`] and [`r1_mi_map`] (R1, `CRMI.m` + `update_CRMI.m`): the per-cell Bernoulli "MI
//!   map" along the beams of a scan, with R1's integration, running-product and floor quirks.
//!
//! Interpretations where the description leaves room (all stated in the docs below): R1's
//! `resol` is cells per metre (1/Δ), so its z step is 1/(10 Δ) m and its reach factors are
//! (1 − Δ m̂) as in the `authors_code` update; rays are exact traversals (not Bresenham); R1's
//! pseudo-posterior m̄ is clipped to [0, 1] before its binary entropy, and 0 log 0 = 0 (MATLAB's
//! `max` drops the NaN the unclipped value produces).

use std::collections::HashMap;

use crate::crm::{CrmMap, CrmScratch, ScanOptions, ScanUpdateMode};
use crate::error::Result;
use crate::grid::check_pose;
use crate::info::crmi::{commit_virtual_scan, VirtualScan};
use crate::info::lattice::BeamAngles;
use crate::info::{Candidate, Evaluation, InfoUnits, InformationFunction};
use crate::raycast::traverse_with;
use crate::sensor::{SensorModel, SensorModelKind};

/// Binary entropy in bits (0 log 0 = 0).
fn h_bits(p: f64) -> f64 {
    crate::info::bernoulli_entropy(p) / std::f64::consts::LN_2
}

/// Settings shared by the two variants.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AuthorsCrmiConfig {
    /// The update model (default `authors_code`, the public code's update).
    pub model: SensorModel,
    pub n_beams: usize,
    pub beam_angles: BeamAngles,
    /// March step of the most likely scan, as a fraction of the cell size (R3: 0.1).
    pub march_fraction: f64,
    /// Cells with m̂ above this stop the most likely scan (R3: 0.5).
    pub hit_threshold: f64,
}

impl AuthorsCrmiConfig {
    /// R3's settings for a sensor range `z_max` (m) on a grid of `resolution` (m).
    pub fn new(z_max: f64, resolution: f64) -> Self {
        Self {
            model: SensorModel::with_defaults(SensorModelKind::AuthorsCode, z_max, resolution),
            n_beams: 10,
            beam_angles: BeamAngles::Distinct,
            march_fraction: 0.1,
            hit_threshold: 0.5,
        }
    }

    pub fn validate(&self) -> Result<()> {
        self.model.validate()?;
        if self.n_beams == 0 || self.n_beams > 100_000 {
            return Err(crate::error::config_err(
                "n_beams",
                format!("must be in [1, 100000], got {}", self.n_beams),
            ));
        }
        if !(self.march_fraction > 0.0 && self.march_fraction <= 1.0) {
            return Err(crate::error::config_err(
                "march_fraction",
                format!("must be in (0, 1], got {}", self.march_fraction),
            ));
        }
        if !(self.hit_threshold > 0.0 && self.hit_threshold < 1.0) {
            return Err(crate::error::config_err(
                "hit_threshold",
                format!("must be in (0, 1), got {}", self.hit_threshold),
            ));
        }
        Ok(())
    }

    /// R3's most likely scan: march each beam at `march_fraction`·Δ and stop at the first point
    /// whose cell has m̂ above the threshold; the range is rounded to whole cells. No hit within
    /// z_max is a no-return.
    pub fn most_likely_scan(&self, map: &CrmMap, pose: [f64; 3]) -> VirtualScan {
        let g = map.geometry();
        let res = g.resolution;
        let step = self.march_fraction * res;
        let z_max = self.model.z_max;
        let angles = self.beam_angles.angles(self.n_beams, pose[2]);
        let n_steps = (z_max / step).floor() as usize;
        let ranges = angles
            .iter()
            .map(|&a| {
                let (s, c) = a.sin_cos();
                (1..=n_steps)
                    .map(|k| k as f64 * step)
                    .find(|&r| {
                        let (ix, iy) = g.cell_of(pose[0] + r * c, pose[1] + r * s);
                        map.mean_at(ix, iy) > self.hit_threshold
                    })
                    .map_or(z_max, |r| ((r / res).round() * res).clamp(res, z_max))
            })
            .collect();
        VirtualScan {
            pose,
            angles: angles.iter().map(|a| a - pose[2]).collect(),
            ranges,
        }
    }
}

/// Cells (and their binary entropy in bits) that a scan's rays cross, each once.
fn ray_cells(map: &CrmMap, scan: &VirtualScan, z_max: f64) -> Vec<(i64, i64)> {
    let g = *map.geometry();
    let ext = map.grid().fixed_extent();
    let mut cells = Vec::new();
    for &a in &scan.angles {
        traverse_with(
            &g,
            [scan.pose[0], scan.pose[1]],
            scan.pose[2] + a,
            z_max,
            ext.as_ref(),
            |c| {
                cells.push((c.ix, c.iy));
                true
            },
        );
    }
    cells.sort_unstable();
    cells.dedup();
    cells
}

/// R3's `action_CRMI` (crm-spec 5.4): Σ H_b(m̂) before − after one CRM update with the most likely
/// scan at the candidate, in bits. Cells off the scan's rays do not change, so the sum runs over
/// the rays' cells.
#[derive(Clone, Debug)]
pub struct MlScanBinary {
    cfg: AuthorsCrmiConfig,
}

impl MlScanBinary {
    pub fn new(cfg: AuthorsCrmiConfig) -> Result<Self> {
        cfg.validate()?;
        Ok(Self { cfg })
    }
}

impl InformationFunction for MlScanBinary {
    type Map = CrmMap;
    type Belief = ();
    type Update = VirtualScan;

    fn name(&self) -> &'static str {
        "crmi_ml_scan_binary"
    }

    fn units(&self) -> InfoUnits {
        InfoUnits::Bits
    }

    fn evaluate(
        &self,
        map: &CrmMap,
        _parent: &(),
        candidate: &Candidate,
        _seed: u64,
    ) -> Result<Evaluation<(), VirtualScan>> {
        check_pose(candidate.pose)?;
        map.check_ray_reach(self.cfg.model.z_max)?;
        let scan = self.cfg.most_likely_scan(map, candidate.pose);
        let cells = ray_cells(map, &scan, self.cfg.model.z_max);
        let before: f64 = cells.iter().map(|&(x, y)| h_bits(map.mean_at(x, y))).sum();
        // Copy-on-write: the copy pays only for the tiles the scan touches.
        let mut after_map = map.clone();
        commit_virtual_scan(&mut after_map, &scan, &self.cfg.model)?;
        let after: f64 = cells
            .iter()
            .map(|&(x, y)| h_bits(after_map.mean_at(x, y)))
            .sum();
        Ok(Evaluation {
            gain: before - after,
            belief: (),
            update: scan,
        })
    }

    fn commit(&self, map: &mut CrmMap, update: &VirtualScan) -> Result<()> {
        commit_virtual_scan(map, update, &self.cfg.model)
    }
}

/// R1's per-cell MI map of one scan (crm-spec 5.3), in bits: every cell the scan's rays cross,
/// with I = H_b(m̂ before the scan) minus R1's integrated expected binary entropy, accumulated
/// beam by beam after each beam's sequential CRM update, floored at 0.01 per beam. `map` is
/// updated with the scan (sequentially, with `model`), as R1 does.
///
/// Per beam and cell j of its ray, for z = k/res_z ≤ min(z_meas, z_max) (res_z = 10 Δ⁻¹... i.e.
/// steps of 1/(10 Δ) m with R1's `resol` = 1/Δ):
/// ξ(z) = (1/(Δ z_max)) Π_ray(1 − m̂) + BSM(z, z_meas) Σ_k m̂_k Π_{i<k}(1 − Δ m̂_i),
/// m̄_j(z) = BSM(z, z_meas) · reach_j^t · m̂_j / ξ(z) at the t-th step (R1's running product is
/// not reset between steps), I_j += (1/res_z) ξ [m̄ log2 m̄ + (1 − m̄) log2(1 − m̄)].
pub fn r1_mi_map(
    map: &mut CrmMap,
    pose: [f64; 3],
    angles: &[f64],
    ranges: &[f64],
    model: &SensorModel,
) -> Result<Vec<((i64, i64), f64)>> {
    check_pose(pose)?;
    if angles.len() != ranges.len() {
        return Err(crate::error::CrlamError::Shape(format!(
            "{} angles and {} ranges",
            angles.len(),
            ranges.len()
        )));
    }
    let g = *map.geometry();
    let res = g.resolution;
    let z_max = model.z_max;
    let step = 1.0 / (10.0 * res);
    let ext = map.grid().fixed_extent();
    let mut mi: HashMap<(i64, i64), f64> = HashMap::new();
    let mut sc = CrmScratch::default();
    let opts = ScanOptions {
        mode: ScanUpdateMode::Sequential,
        ..ScanOptions::default()
    };
    let mut cells: Vec<(i64, i64)> = Vec::new();
    for (&a, &z_meas) in angles.iter().zip(ranges) {
        // Cells first seen in this scan start from the entropy of the map before the scan.
        cells.clear();
        traverse_with(
            &g,
            [pose[0], pose[1]],
            pose[2] + a,
            z_max,
            ext.as_ref(),
            |c| {
                cells.push((c.ix, c.iy));
                true
            },
        );
        for &c in &cells {
            mi.entry(c).or_insert_with(|| h_bits(map.mean_at(c.0, c.1)));
        }
        map.update_scan(pose, &[a], &[z_meas], model, &opts, &mut sc)?;
        let mhat: Vec<f64> = cells.iter().map(|&(x, y)| map.mean_at(x, y)).collect();
        let pass_all: f64 = mhat.iter().map(|m| 1.0 - m).product();
        let p1 = pass_all / (res * z_max);
        let mut reach = Vec::with_capacity(mhat.len());
        let mut bounce_sum = 0.0;
        let mut r = 1.0;
        for &m in &mhat {
            reach.push(r);
            bounce_sum += m * r;
            r *= 1.0 - res * m;
        }
        let z_end = if z_meas.is_finite() {
            z_meas.min(z_max)
        } else {
            z_max
        };
        let n_steps = (z_end / step + 1e-9).floor() as i32;
        for (j, &c) in cells.iter().enumerate() {
            let mut acc = 0.0;
            for t in 1..=n_steps {
                let z = t as f64 * step;
                let bsm = model.authors_bsm(z, z_meas.min(z_max));
                let xi = p1 + bsm * bounce_sum;
                if !(xi > 0.0 && xi.is_finite()) {
                    continue;
                }
                let m_bar = (bsm * reach[j].powi(t) * mhat[j] / xi).clamp(0.0, 1.0);
                acc += step * xi * -h_bits(m_bar);
            }
            let e = mi.get_mut(&c).expect("initialised above");
            *e = (*e + acc).max(0.01);
        }
    }
    let mut out: Vec<_> = mi.into_iter().collect();
    out.sort_unstable_by_key(|&(c, _)| c);
    Ok(out)
}

/// R1's MI map as a candidate score (crm-spec 5.3, for visual comparison only): the most likely
/// scan at the candidate, [`r1_mi_map`] on a copy of the map, and the sum of the map over the
/// cells the scan crosses (bits).
#[derive(Clone, Debug)]
pub struct R1Map {
    cfg: AuthorsCrmiConfig,
}

impl R1Map {
    pub fn new(cfg: AuthorsCrmiConfig) -> Result<Self> {
        cfg.validate()?;
        Ok(Self { cfg })
    }
}

impl InformationFunction for R1Map {
    type Map = CrmMap;
    type Belief = ();
    type Update = VirtualScan;

    fn name(&self) -> &'static str {
        "crmi_r1_map"
    }

    fn units(&self) -> InfoUnits {
        InfoUnits::Bits
    }

    fn evaluate(
        &self,
        map: &CrmMap,
        _parent: &(),
        candidate: &Candidate,
        _seed: u64,
    ) -> Result<Evaluation<(), VirtualScan>> {
        check_pose(candidate.pose)?;
        map.check_ray_reach(self.cfg.model.z_max)?;
        let scan = self.cfg.most_likely_scan(map, candidate.pose);
        let mut copy = map.clone();
        let cells = r1_mi_map(
            &mut copy,
            scan.pose,
            &scan.angles,
            &scan.ranges,
            &self.cfg.model,
        )?;
        Ok(Evaluation {
            gain: cells.iter().map(|c| c.1).sum(),
            belief: (),
            update: scan,
        })
    }

    fn commit(&self, map: &mut CrmMap, update: &VirtualScan) -> Result<()> {
        commit_virtual_scan(map, update, &self.cfg.model)
    }
}
