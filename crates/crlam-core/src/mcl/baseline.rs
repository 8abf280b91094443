//! AMCL's two laser models (`nav2_amcl`'s `likelihood_field` and `beam`, Thrun, Burgard, Fox,
//! *Probabilistic Robotics*, Tables 6.1 and 6.3) as alternatives to the CRM likelihood on the
//! same filter, so that a comparison isolates the measurement model.
//!
//! Both read the map as AMCL reads an occupancy grid, from the expected occupancy m̂ alone (the
//! map's confidence plays no part: that is what the comparison measures). AMCL's beam model stops
//! its ray at occupied and at unknown cells, and its likelihood field measures distances to the
//! occupied cells only; a Nav2 map's unknown cells become m̂ = 0.5 (the uniform pmf), so here the
//! ray stops at m̂ ≥ [`OCCUPIED`] and the field's obstacles are the cells with m̂ > [`OCCUPIED`].
//!
//! Per beam, with the reading z (m) and the laser's z_max:
//!
//! - likelihood field: readings at or beyond z_max (and at or below z_min, which AMCL's node
//!   turns into z_max) are left out; the endpoint's distance d to the nearest obstacle cell
//!   (centre to centre, capped at `max_dist`, and `max_dist` for an endpoint off the map) gives
//!   p = z_hit · exp(−d² / 2σ²) + z_rand / z_max;
//! - beam: the expected range r* is where the ray enters the first obstacle cell (or leaves the
//!   map, or z_max); readings at or below z_min, and no-returns, read z_max; with e = z − r*,
//!   p = z_hit · exp(−e² / 2σ²) + \[e < 0\] · z_short · λ · exp(−λ z) + \[z = z_max\] · z_max_w
//!   + \[z < z_max\] · z_rand / z_max.
//!
//! The Gaussian is AMCL's, unnormalised (peak 1). The scan's log-likelihood is Σ log p over the
//! beams: AMCL's `likelihood_field_prob` combines beams so (its plain models use the heuristic
//! 1 + Σ p³, which is no likelihood and could not share the filter's tempering). The share a
//! beam's hit term holds of p is its [`ScanFit::explained`] part, the fit measure of recovery.

use crate::error::{config_err, CrlamError, Result};
use crate::grid::{floor_to_i64, CellRect, GridGeometry};
use crate::mcl::field::MeanField;
use crate::mcl::likelihood::ScanFit;
use crate::pose::Pose;
use crate::raycast::traverse_with;

/// m̂ from which a cell stops the beam model's ray, and above which it is an obstacle of the
/// likelihood field.
pub const OCCUPIED: f64 = 0.5;

/// AMCL's likelihood-field model (defaults: `nav2_amcl`'s).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LikelihoodFieldParams {
    pub z_hit: f64,
    pub z_rand: f64,
    /// σ of the hit term (m).
    pub sigma_hit: f64,
    /// Distances are capped here (m): AMCL's `laser_likelihood_max_dist`.
    pub max_dist: f64,
}

impl Default for LikelihoodFieldParams {
    fn default() -> Self {
        Self {
            z_hit: 0.95,
            z_rand: 0.05,
            sigma_hit: 0.2,
            max_dist: 2.0,
        }
    }
}

/// AMCL's beam model (defaults: `nav2_amcl`'s).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeamParams {
    pub z_hit: f64,
    pub z_short: f64,
    pub z_max: f64,
    pub z_rand: f64,
    /// σ of the hit term (m).
    pub sigma_hit: f64,
    /// Rate of the short-reading term (1/m).
    pub lambda_short: f64,
}

impl Default for BeamParams {
    fn default() -> Self {
        Self {
            z_hit: 0.5,
            z_short: 0.05,
            z_max: 0.05,
            z_rand: 0.5,
            sigma_hit: 0.2,
            lambda_short: 0.1,
        }
    }
}

/// The filter's measurement model.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Measurement {
    /// The CRM predictive likelihood ([`super::likelihood`]).
    #[default]
    Crm,
    /// AMCL's likelihood field.
    LikelihoodField(LikelihoodFieldParams),
    /// AMCL's beam model.
    Beam(BeamParams),
}

impl Measurement {
    /// Its name on the command line.
    pub fn name(&self) -> &'static str {
        match self {
            Measurement::Crm => "crm",
            Measurement::LikelihoodField(_) => "likelihood_field",
            Measurement::Beam(_) => "beam",
        }
    }

    /// σ of the hit term of the AMCL models (None for the CRM, whose σ is its mixture's).
    pub fn sigma_hit(&self) -> Option<f64> {
        match self {
            Measurement::Crm => None,
            Measurement::LikelihoodField(p) => Some(p.sigma_hit),
            Measurement::Beam(p) => Some(p.sigma_hit),
        }
    }

    /// Checks the weights and scales: each ≥ 0 and finite, σ, λ and the distance cap > 0, and
    /// every reading a likelihood above 0 (z_rand > 0; for the beam model also z_max > 0).
    pub fn validate(&self) -> Result<()> {
        let ok = |v: f64| v.is_finite() && v >= 0.0;
        let pos = |v: f64| v.is_finite() && v > 0.0;
        match self {
            Measurement::Crm => Ok(()),
            Measurement::LikelihoodField(p) => {
                if !(ok(p.z_hit) && pos(p.z_rand)) {
                    return Err(config_err(
                        "likelihood_field",
                        format!(
                            "z_hit must be >= 0 and z_rand > 0, got {} and {}",
                            p.z_hit, p.z_rand
                        ),
                    ));
                }
                if !(pos(p.sigma_hit) && pos(p.max_dist)) {
                    return Err(config_err(
                        "likelihood_field",
                        format!(
                            "sigma_hit and max_dist must be > 0, got {} and {}",
                            p.sigma_hit, p.max_dist
                        ),
                    ));
                }
                Ok(())
            }
            Measurement::Beam(p) => {
                if !(ok(p.z_hit) && ok(p.z_short) && pos(p.z_max) && pos(p.z_rand)) {
                    return Err(config_err(
                        "beam",
                        format!(
                            "z_hit and z_short must be >= 0, z_max and z_rand > 0, got {}, {}, {}, {}",
                            p.z_hit, p.z_short, p.z_max, p.z_rand
                        ),
                    ));
                }
                if !(pos(p.sigma_hit) && pos(p.lambda_short)) {
                    return Err(config_err(
                        "beam",
                        format!(
                            "sigma_hit and lambda_short must be > 0, got {} and {}",
                            p.sigma_hit, p.lambda_short
                        ),
                    ));
                }
                Ok(())
            }
        }
    }
}

/// The laser's range limits the AMCL models read readings against (m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RangeLimits {
    pub z_min: f64,
    pub z_max: f64,
}

/// The likelihood field's table: per cell of the map's rectangle, the distance (m) from its
/// centre to the nearest obstacle cell's centre (m̂ > [`OCCUPIED`]), capped at `max_dist`.
#[derive(Clone, Debug)]
pub struct DistanceField {
    geometry: GridGeometry,
    rect: CellRect,
    dist: Vec<f32>,
    max_dist: f64,
}

impl DistanceField {
    /// The table of `field` (an exact Euclidean distance transform of its obstacle cells).
    pub fn new(field: &MeanField, max_dist: f64) -> Self {
        // The least double above 0.5: `occupied_distance` counts m̂ ≥ its argument.
        let above = f64::from_bits(OCCUPIED.to_bits() + 1);
        let dist = field
            .occupied_distance(above)
            .into_iter()
            .map(|d| d.min(max_dist) as f32)
            .collect();
        Self {
            geometry: *field.geometry(),
            rect: field.rect(),
            dist,
            max_dist,
        }
    }

    /// The capped distance (m) at a world point: `max_dist` off the map.
    pub fn distance_at(&self, x: f64, y: f64) -> f64 {
        let g = &self.geometry;
        let r = self.rect;
        let ix = floor_to_i64((x - g.origin[0]) / g.resolution) - r.ix0;
        let iy = floor_to_i64((y - g.origin[1]) / g.resolution) - r.iy0;
        if (ix as u64) < r.nx as u64 && (iy as u64) < r.ny as u64 {
            f64::from(self.dist[(iy * r.nx + ix) as usize])
        } else {
            self.max_dist
        }
    }

    /// The cap it was built with (m).
    pub fn max_dist(&self) -> f64 {
        self.max_dist
    }
}

fn check_shape(angles: &[f64], ranges: &[f64], beams: &[usize]) -> Result<()> {
    if angles.len() != ranges.len() {
        return Err(CrlamError::Shape(format!(
            "scan has {} beam angles but {} ranges",
            angles.len(),
            ranges.len()
        )));
    }
    if let Some(&b) = beams.iter().find(|&&b| b >= angles.len()) {
        return Err(CrlamError::Shape(format!(
            "beam {b} of a scan of {} beams",
            angles.len()
        )));
    }
    Ok(())
}

/// One beam's likelihood under the likelihood field: (p, its hit part), at the endpoint's
/// capped distance `d` (m).
pub fn likelihood_field_beam(
    p: &LikelihoodFieldParams,
    sigma: f64,
    z_max: f64,
    d: f64,
) -> (f64, f64) {
    let hit = p.z_hit * (-(d * d) / (2.0 * sigma * sigma)).exp();
    (hit + p.z_rand / z_max, hit)
}

/// The scan's log-likelihood at the sensor pose `sensor` under AMCL's likelihood field with the
/// hit σ `sigma` (the module documentation).
#[allow(clippy::too_many_arguments)]
pub fn likelihood_field_scan(
    table: &DistanceField,
    p: &LikelihoodFieldParams,
    sigma: f64,
    limits: RangeLimits,
    sensor: Pose,
    angles: &[f64],
    ranges: &[f64],
    beams: &[usize],
) -> Result<ScanFit> {
    check_shape(angles, ranges, beams)?;
    let mut fit = ScanFit::default();
    for &b in beams {
        let z = ranges[b];
        // NaN, no-returns, max readings and readings at or below z_min: left out.
        if !(z > limits.z_min && z < limits.z_max) {
            continue;
        }
        let (s, c) = (sensor[2] + angles[b]).sin_cos();
        let d = table.distance_at(sensor[0] + z * c, sensor[1] + z * s);
        let (pz, hit) = likelihood_field_beam(p, sigma, limits.z_max, d);
        fit.log_likelihood += pz.ln();
        fit.explained += hit / pz;
        fit.n_beams += 1;
    }
    Ok(fit)
}

/// One beam's likelihood under the beam model: (p, its hit part), for the reading `z` (already
/// z_max for a no-return) and the expected range `expected` (m).
pub fn beam_model_beam(
    p: &BeamParams,
    sigma: f64,
    z_max: f64,
    z: f64,
    expected: f64,
) -> (f64, f64) {
    let e = z - expected;
    let hit = p.z_hit * (-(e * e) / (2.0 * sigma * sigma)).exp();
    let mut pz = hit;
    if e < 0.0 {
        pz += p.z_short * p.lambda_short * (-p.lambda_short * z).exp();
    }
    if z >= z_max {
        pz += p.z_max;
    } else {
        pz += p.z_rand / z_max;
    }
    (pz, hit)
}

/// The expected range (m) along `angle` from `origin`: where the ray enters the first obstacle
/// cell of `field`, or leaves the map's rectangle, or `z_max`.
pub fn expected_range(field: &MeanField, origin: [f64; 2], angle: f64, z_max: f64) -> f64 {
    let rect = field.rect();
    let mut hit = None;
    let end = traverse_with(field.geometry(), origin, angle, z_max, Some(&rect), |c| {
        if field.mean_at(c.ix, c.iy) >= OCCUPIED {
            hit = Some(c.t_in.max(0.0));
            false
        } else {
            true
        }
    });
    hit.unwrap_or(end).clamp(0.0, z_max)
}

/// The scan's log-likelihood at the sensor pose `sensor` under AMCL's beam model with the hit σ
/// `sigma` (the module documentation).
#[allow(clippy::too_many_arguments)]
pub fn beam_model_scan(
    field: &MeanField,
    p: &BeamParams,
    sigma: f64,
    limits: RangeLimits,
    sensor: Pose,
    angles: &[f64],
    ranges: &[f64],
    beams: &[usize],
) -> Result<ScanFit> {
    check_shape(angles, ranges, beams)?;
    let mut fit = ScanFit::default();
    if !(sensor[0].is_finite() && sensor[1].is_finite() && sensor[2].is_finite()) {
        return Ok(fit);
    }
    for &b in beams {
        let z = ranges[b];
        if z.is_nan() {
            continue;
        }
        let z = if z <= limits.z_min || z >= limits.z_max {
            limits.z_max
        } else {
            z
        };
        let angle = sensor[2] + angles[b];
        let expected = expected_range(field, [sensor[0], sensor[1]], angle, limits.z_max);
        let (pz, hit) = beam_model_beam(p, sigma, limits.z_max, z, expected);
        fit.log_likelihood += pz.ln();
        fit.explained += hit / pz;
        fit.n_beams += 1;
    }
    Ok(fit)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4 m × 4 m room at 0.1 m: walls one cell thick on its border, free inside.
    fn room() -> MeanField {
        let g = GridGeometry::new([0.0, 0.0], 0.1).unwrap();
        let rect = CellRect {
            ix0: 0,
            iy0: 0,
            nx: 40,
            ny: 40,
        };
        let mean = (0..40)
            .flat_map(|iy| (0..40).map(move |ix| (ix, iy)))
            .map(|(ix, iy)| {
                if ix == 0 || iy == 0 || ix == 39 || iy == 39 {
                    0.95
                } else {
                    0.02
                }
            })
            .collect();
        MeanField::from_means(g, rect, mean, 0.5, 0.25, 10).unwrap()
    }

    const LIMITS: RangeLimits = RangeLimits {
        z_min: 0.05,
        z_max: 10.0,
    };

    #[test]
    fn likelihood_field_matches_hand_values() {
        let field = room();
        let p = LikelihoodFieldParams::default();
        let table = DistanceField::new(&field, p.max_dist);
        // The wall's cells have centres at x = 3.95; a sensor at (2.05, 2.05) looking along +x.
        // Reading 1.9 m: endpoint (3.95, 2.05), in a wall cell: d = 0, p = 0.95 + 0.05 / 10.
        // Reading 1.7 m: endpoint (3.75, 2.05), two cells from the wall: d = 0.2,
        // p = 0.95 · exp(−0.04 / 0.08) + 0.005 = 0.95 · e^−0.5 + 0.005.
        // Reading 10 m (z_max): left out. Reading 0.5 m: endpoint (2.55, 2.05), 14 cells from
        // the nearest wall (d = 1.4): 0.95 · exp(−1.96 / 0.08) + 0.005.
        let angles = [0.0, 0.0, 0.0, 0.0];
        let ranges = [1.9, 1.7, 10.0, 0.5];
        let fit = likelihood_field_scan(
            &table,
            &p,
            0.2,
            LIMITS,
            [2.05, 2.05, 0.0],
            &angles,
            &ranges,
            &[0, 1, 2, 3],
        )
        .unwrap();
        let want = [
            0.955f64,
            0.95 * (-0.5f64).exp() + 0.005,
            0.95 * (-24.5f64).exp() + 0.005,
        ];
        assert_eq!(fit.n_beams, 3);
        let ll: f64 = want.iter().map(|v| v.ln()).sum();
        assert!((fit.log_likelihood - ll).abs() < 1e-6, "{fit:?} vs {ll}");
        let explained = 0.95 / 0.955 + (want[1] - 0.005) / want[1] + (want[2] - 0.005) / want[2];
        assert!((fit.explained - explained).abs() < 1e-6);
        // Off the map: d = max_dist = 2: 0.95 · exp(−4 / 0.08) + 0.005.
        let off = likelihood_field_scan(
            &table,
            &p,
            0.2,
            LIMITS,
            [2.05, 2.05, 0.0],
            &[0.0],
            &[5.0],
            &[0],
        )
        .unwrap();
        assert!((off.log_likelihood - (0.95 * (-50.0f64).exp() + 0.005).ln()).abs() < 1e-9);
    }

    #[test]
    fn beam_model_matches_hand_values() {
        let field = room();
        let p = BeamParams::default();
        // From (2.05, 2.05) along +x the ray enters the wall cell at x = 3.9: r* = 1.85.
        let r = expected_range(&field, [2.05, 2.05], 0.0, 10.0);
        assert!((r - 1.85).abs() < 1e-9, "{r}");
        let sensor = [2.05, 2.05, 0.0];
        let angles = [0.0; 4];
        // 1.9: e = 0.05 → 0.5 · exp(−0.0025 / 0.08) + 0.5 / 10.
        // 1.45: e = −0.4 → 0.5 · exp(−0.16 / 0.08) + 0.05 · 0.1 · exp(−0.145) + 0.05.
        // inf (no return): z = z_max = 10, e = 8.15 → 0.5 · exp(−66.4225 / 0.08) + 0.05.
        // 2.25: e = 0.4 → 0.5 · exp(−2) + 0.05.
        let ranges = [1.9, 1.45, f64::INFINITY, 2.25];
        let fit = beam_model_scan(
            &field,
            &p,
            0.2,
            LIMITS,
            sensor,
            &angles,
            &ranges,
            &[0, 1, 2, 3],
        )
        .unwrap();
        let want = [
            0.5 * (-0.0025f64 / 0.08).exp() + 0.05,
            0.5 * (-2.0f64).exp() + 0.005 * (-0.145f64).exp() + 0.05,
            0.5 * (-66.4225f64 / 0.08).exp() + 0.05,
            0.5 * (-2.0f64).exp() + 0.05,
        ];
        let ll: f64 = want.iter().map(|v| v.ln()).sum();
        assert_eq!(fit.n_beams, 4);
        assert!((fit.log_likelihood - ll).abs() < 1e-9, "{fit:?} vs {ll}");
        // A reading past the expected range (r* = 0, z = 3): no short term.
        let (pz, hit) = beam_model_beam(&p, 0.2, 10.0, 3.0, 0.0);
        assert!((pz - (0.5 * (-9.0f64 / 0.08).exp() + 0.05)).abs() < 1e-12);
        assert!(hit < 1e-40);
    }

    #[test]
    fn the_true_pose_is_likelier_under_both_models() {
        let field = room();
        let table = DistanceField::new(&field, 2.0);
        let angles: Vec<f64> = (0..36).map(|i| i as f64 * 0.1745).collect();
        let truth = [1.55, 2.25, 0.3];
        let ranges: Vec<f64> = angles
            .iter()
            .map(|a| expected_range(&field, [truth[0], truth[1]], truth[2] + a, 10.0))
            .collect();
        let beams: Vec<usize> = (0..36).collect();
        let lf = |s: Pose| {
            likelihood_field_scan(
                &table,
                &LikelihoodFieldParams::default(),
                0.2,
                LIMITS,
                s,
                &angles,
                &ranges,
                &beams,
            )
            .unwrap()
            .log_likelihood
        };
        let bm = |s: Pose| {
            beam_model_scan(
                &field,
                &BeamParams::default(),
                0.2,
                LIMITS,
                s,
                &angles,
                &ranges,
                &beams,
            )
            .unwrap()
            .log_likelihood
        };
        for d in [[0.3, 0.0, 0.0], [0.0, -0.3, 0.0], [0.0, 0.0, 0.2]] {
            let off = [truth[0] + d[0], truth[1] + d[1], truth[2] + d[2]];
            assert!(lf(truth) > lf(off) + 1.0);
            assert!(bm(truth) > bm(off) + 1.0);
        }
    }

    #[test]
    fn settings_and_shapes_are_checked() {
        assert!(
            Measurement::LikelihoodField(LikelihoodFieldParams::default())
                .validate()
                .is_ok()
        );
        assert!(Measurement::Beam(BeamParams::default()).validate().is_ok());
        let bad_lf = LikelihoodFieldParams {
            z_rand: 0.0,
            ..Default::default()
        };
        assert!(Measurement::LikelihoodField(bad_lf).validate().is_err());
        let bad_beam = BeamParams {
            sigma_hit: f64::NAN,
            ..Default::default()
        };
        assert!(Measurement::Beam(bad_beam).validate().is_err());
        let field = room();
        let table = DistanceField::new(&field, 2.0);
        let p = LikelihoodFieldParams::default();
        let s = [1.0, 1.0, 0.0];
        assert!(
            likelihood_field_scan(&table, &p, 0.2, LIMITS, s, &[0.0], &[1.0, 2.0], &[0]).is_err()
        );
        assert!(likelihood_field_scan(&table, &p, 0.2, LIMITS, s, &[0.0], &[1.0], &[1]).is_err());
        let b = BeamParams::default();
        assert!(beam_model_scan(&field, &b, 0.2, LIMITS, s, &[0.0], &[1.0], &[3]).is_err());
        // A non-finite or huge pose gives a result, not a panic.
        for s in [
            [f64::NAN, 0.0, 0.0],
            [1e300, -1e300, 1e300],
            [9.3e18, 0.0, 1.0],
        ] {
            let _ = beam_model_scan(&field, &b, 0.2, LIMITS, s, &[0.0], &[1.0], &[0]).unwrap();
            let _ =
                likelihood_field_scan(&table, &p, 0.2, LIMITS, s, &[0.0], &[1.0], &[0]).unwrap();
        }
    }
}
