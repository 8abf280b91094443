//! The IIG reference 'mi' information heuristic (planner-spec 4.3), for figure parity with the
//! reference planner's "OGMI" curves. In nats; it mutates the occupancy lattice as it integrates.

use crate::error::{config_err, Result};
use crate::info::fsmi::{commit_probabilities, lattice_origin, ProbabilityUpdate};

const SQRT_2PI: f64 = 2.506_628_274_631_000_7;
use crate::info::lattice::{march_beam, BeamAngles, MarchStep, OccupancyLattice};
use crate::info::{bernoulli_entropy, Candidate, Evaluation, InfoUnits, InformationFunction};

// The reference 'mi' sensor mixture and map update (planner-spec 4.3).
const Z_HIT: f64 = 0.7;
const Z_SHORT: f64 = 0.1;
const Z_MAX_WEIGHT: f64 = 0.1;
const Z_RAND: f64 = 0.1;
const LAMBDA_SHORT: f64 = 0.2;
const SIGMA_HIT: f64 = 0.05;
const P_RAND: f64 = 0.2;
const MAX_SPIKE_HALF_WIDTH: f64 = 0.05;
const PROB_FREE: f64 = 0.35;
const B_FREE: f64 = 0.6;
const B_OCC: f64 = 1.6667;
const P_FLOOR: f64 = 0.049;
const P_CEIL: f64 = 0.951;
/// Nodes with entropy below h(P_SAT) = 0.1985 nats are saturated.
const P_SAT: f64 = 0.05;

/// The IIG reference 'mi' heuristic (planner-spec 4.3), name `"iig_mi"`, or with `upper_bound`
/// its 'miub' companion (`"iig_miub"`: the prior entropy along the beams minus that of saturated
/// nodes). Nats.
///
/// All beams are marched (`march_beam`) on the map as it is at the start of the call, as the
/// reference does. The reference's multiplicative map updates compound within the call: they are
/// kept in a local overlay that later saturation checks and updates read, and the overlay's
/// final (id, probability) values are the update that `commit` writes. Both variants make the
/// same updates. ΔI = max(total, 0); the reference leaves 'miub' unclamped, we clamp it too (it
/// can only go below 0 when the floor 0.049 raises a saturated node's entropy).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IigMi {
    /// Return 'miub' instead of 'mi'.
    pub upper_bound: bool,
    /// Beams per scan (10).
    pub n_beams: usize,
    /// Beam directions (default [`BeamAngles::Reference`]).
    pub beam_angles: BeamAngles,
    /// Beam length (m), also the mixture's maximum range (5).
    pub z_max: f64,
    /// Hit threshold of the march (0.65).
    pub p_occ: f64,
    /// Spacing (m) of the integration points (0.5).
    pub int_res: f64,
}

impl Default for IigMi {
    fn default() -> Self {
        Self {
            upper_bound: false,
            n_beams: 10,
            beam_angles: BeamAngles::Reference,
            z_max: 5.0,
            p_occ: 0.65,
            int_res: 0.5,
        }
    }
}

impl IigMi {
    pub fn validate(&self) -> Result<()> {
        if self.n_beams == 0 {
            return Err(config_err("n_beams", "must be ≥ 1"));
        }
        for (field, v) in [("z_max", self.z_max), ("int_res", self.int_res)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(config_err(
                    field,
                    format!("must be finite and > 0, got {v}"),
                ));
            }
        }
        if !(0.0..=1.0).contains(&self.p_occ) {
            return Err(config_err(
                "p_occ",
                format!("must be in [0, 1], got {}", self.p_occ),
            ));
        }
        Ok(())
    }

    /// The reference mixture density called as g(cell range, integration point): the argument
    /// swap of planner-spec 4.3 is kept. A range at z_max (the last step of a max-range beam,
    /// snapped within 1e-12 relative) has no "hit" or "rand" term.
    fn mixture(&self, range: f64, z: f64) -> f64 {
        let short = if range > z {
            LAMBDA_SHORT * (-LAMBDA_SHORT * range).exp() / (1.0 - (-LAMBDA_SHORT * z).exp())
        } else {
            0.0
        };
        let spike = if (range - z).abs() < MAX_SPIKE_HALF_WIDTH {
            1.0
        } else {
            0.0
        };
        let at_max = range >= self.z_max * (1.0 - 1e-12);
        let rand = if at_max { 0.0 } else { P_RAND };
        let hit = if range > 0.0 && !at_max {
            let u = (range - z) / SIGMA_HIT;
            (-0.5 * u * u).exp() / (SQRT_2PI * SIGMA_HIT)
        } else {
            0.0
        };
        (Z_SHORT * short + Z_HIT * hit + Z_RAND * rand + Z_MAX_WEIGHT * spike).max(P_RAND)
    }

    /// p(z) of the reference over steps 1…s (0-based `s`), with the march-time occupancies.
    fn reading_density(&self, steps: &[MarchStep], s: usize, z: f64) -> f64 {
        let (mut survive, mut first_hit) = (1.0, 0.0);
        for step in &steps[..=s] {
            first_hit += self.mixture(step.range, z) * step.prob * survive;
            survive *= 1.0 - step.prob;
        }
        P_RAND * survive + first_hit
    }

    /// Returns ('mi' total before clamping, 'miub' total, overlay of updated nodes).
    fn run(&self, map: &OccupancyLattice, pose: [f64; 3]) -> Result<(f64, f64, ProbabilityUpdate)> {
        self.validate()?;
        let origin = lattice_origin(map, &pose)?;
        let h_sat = bernoulli_entropy(P_SAT);
        let (mut total, mut upper) = (0.0, 0.0);
        let mut overlay: Vec<(usize, f64)> = Vec::new();
        let mut points: Vec<(usize, f64)> = Vec::new();
        let beams: Vec<_> = (self.beam_angles.angles(self.n_beams, pose[2]).into_iter())
            .map(|a| march_beam(map, origin, a, self.z_max, self.p_occ))
            .collect();
        let current = |overlay: &[(usize, f64)], id: usize| {
            overlay
                .iter()
                .find(|e| e.0 == id)
                .map_or(map.get(id), |e| e.1)
        };
        for beam in &beams {
            let steps = &beam.steps;
            if steps.len() < 2 {
                continue;
            }
            let prior: f64 = steps.iter().map(|s| bernoulli_entropy(s.prob)).sum();
            total += prior;
            upper += prior;
            let length = match beam.hit {
                Some(_) => steps[steps.len() - 1].range,
                None => self.z_max,
            };
            // p(z) only reads the march-time occupancies: compute it once per point.
            points.clear();
            for k in 1.. {
                let z = k as f64 * self.int_res;
                if z > length + 1e-9 {
                    break;
                }
                let mut s = 0;
                for (i, step) in steps.iter().enumerate() {
                    if (z - step.range).abs() < (z - steps[s].range).abs() {
                        s = i;
                    }
                }
                let id = steps[s].id;
                let slot = match overlay.iter().position(|e| e.0 == id) {
                    Some(slot) => slot,
                    None => {
                        overlay.push((id, map.get(id)));
                        overlay.len() - 1
                    }
                };
                points.push((slot, self.reading_density(steps, s, z)));
            }
            for step in steps {
                let h = bernoulli_entropy(current(&overlay, step.id));
                if h < h_sat {
                    total -= h;
                    upper -= h;
                    continue;
                }
                let mut posterior_entropy = 0.0;
                for &(slot, pz) in &points {
                    let o = &mut overlay[slot].1;
                    *o = if *o < PROB_FREE {
                        P_FLOOR.max(B_FREE * *o)
                    } else {
                        P_CEIL.min(B_OCC * *o)
                    };
                    posterior_entropy += pz * bernoulli_entropy(*o);
                }
                total -= self.int_res * posterior_entropy;
            }
        }
        overlay.retain(|&(id, p)| p != map.get(id));
        overlay.sort_unstable_by_key(|e| e.0);
        Ok((total, upper, overlay))
    }
}

impl InformationFunction for IigMi {
    type Map = OccupancyLattice;
    type Belief = ();
    type Update = ProbabilityUpdate;

    fn name(&self) -> &'static str {
        if self.upper_bound {
            "iig_miub"
        } else {
            "iig_mi"
        }
    }

    fn units(&self) -> InfoUnits {
        InfoUnits::Nats
    }

    fn evaluate(
        &self,
        map: &OccupancyLattice,
        _parent: &(),
        candidate: &Candidate,
        _seed: u64,
    ) -> Result<Evaluation<(), Self::Update>> {
        let (mi, upper, update) = self.run(map, candidate.pose)?;
        let gain = if self.upper_bound { upper } else { mi };
        Ok(Evaluation {
            gain: gain.max(0.0),
            belief: (),
            update,
        })
    }

    fn commit(&self, map: &mut OccupancyLattice, update: &Self::Update) -> Result<()> {
        commit_probabilities(map, update)
    }
}
