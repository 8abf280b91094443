//! RBPF-CLAM's likelihood-mode proposal (the CRM analogue of GMapping's improved proposal):
//! hill-climb the predictive scan likelihood × motion density, evaluate it on a lattice around
//! the mode, fit a Gaussian and draw from it (or keep the mode); the weight increment is the log
//! of the lattice normaliser.

use crate::crm::{CrmMap, CrmScratch};
use crate::error::Result;
use crate::pose::{compose, wrap, Pose};
use crate::rbpf::clam_config::{scan_opts, ClamConfig, ClamProposal};
use crate::rbpf::clam_particle::ClamParticle;
use crate::rbpf::common::{ProposalPose, ScanInput};
use crate::rng::Rng;

/// A particle's proposed move.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Proposed {
    /// The new pose (drawn, or the mode with [`ProposalPose::Match`]).
    pub pose: Pose,
    /// The mean of the distribution `pose` was drawn from: the fitted Gaussian's mean, or `pose`
    /// itself where nothing is fitted (odometry fallback, `Match`).
    pub mean: Pose,
    /// The log-weight increment (tempered).
    pub dlogw: f64,
}

/// How the proposal evaluates a scan's Σ log η at the poses it tries, all within a few decimetres
/// of the odometry guess. Where the scan's window is small (8 m at 0.05 m or coarser), by the
/// batch scan's weight-only path ([`CrmMap::weigh_scan`]) on a copy of the particle's map: the
/// copy shares the map's tiles and its window mean table, which the first pose fills and later
/// poses (and the particle's relatives) read, and it weighs sixteen beams at a time in lanes.
/// Elsewhere (long ranges on fine grids, where a table per copy costs more than it saves), by
/// the forward walk ([`CrmMap::scan_log_likelihood`]). The two agree to rounding. The copy may
/// grow its storage to cover a pose's scan; the particle's own map is never written here.
struct ScanLikelihood<'a> {
    cfg: &'a ClamConfig,
    scan: &'a ScanInput<'a>,
    map: &'a CrmMap,
    batch: Option<CrmMap>,
}

impl<'a> ScanLikelihood<'a> {
    fn new(cfg: &'a ClamConfig, scan: &'a ScanInput<'a>, map: &'a CrmMap) -> Self {
        let z_max = cfg.weight_model.z_max.max(cfg.mapping_model.z_max);
        let small = map.weighs_in_a_small_window(z_max, &scan_opts(cfg, cfg.map_stride));
        Self {
            cfg,
            scan,
            map,
            batch: small.then(|| map.clone()),
        }
    }

    /// Σ log η of every `stride`-th beam of the scan taken at robot pose `pose`.
    fn eval(&mut self, pose: Pose, stride: usize, sc: &mut CrmScratch) -> Result<f64> {
        let (cfg, scan) = (self.cfg, self.scan);
        let sensor = compose(pose, scan.laser_offset);
        let (ll, _) = match &mut self.batch {
            Some(copy) => copy.weigh_scan(
                sensor,
                scan.angles,
                scan.ranges,
                &cfg.weight_model,
                stride,
                &cfg.mapping_model,
                &scan_opts(cfg, cfg.map_stride),
                sc,
            )?,
            None => self.map.scan_log_likelihood(
                sensor,
                scan.angles,
                scan.ranges,
                &cfg.weight_model,
                &scan_opts(cfg, stride),
                sc,
            )?,
        };
        Ok(ll)
    }
}

/// Proposes the particle's new pose and the log-weight increment.
pub(crate) fn propose(
    cfg: &ClamConfig,
    p: &ClamParticle,
    u: Pose,
    n_steps: usize,
    scan: &ScanInput,
    rng: &mut Rng,
    sc: &mut CrmScratch,
) -> Result<Proposed> {
    let mut like = ScanLikelihood::new(cfg, scan, &p.map);
    match cfg.proposal {
        // The scan-match proposal needs the prepared scan: the filter calls it directly
        // (`clam_match`); here it stands for the paper's proposal.
        ClamProposal::Odometry | ClamProposal::ScanMatch(_) => {
            let pose = cfg.motion.sample(p.pose, u, n_steps, rng);
            let dlogw = like.eval(pose, cfg.weight_stride, sc)? / cfg.tempering;
            Ok(Proposed {
                pose,
                mean: compose(p.pose, u),
                dlogw,
            })
        }
        ClamProposal::LikelihoodMode {
            step,
            iterations,
            match_stride,
            lattice: fine,
            pose: pose_rule,
            motion_outlier,
        } => {
            // With `Match` nothing is drawn after the climb, so the climb must start from a
            // motion-model sample (as in GMapping): from the odometry guess, the children of one
            // parent (same pose, same map) would stay identical copies for ever.
            let guess = match pose_rule {
                ProposalPose::Sample => compose(p.pose, u),
                ProposalPose::Match => cfg.motion.sample(p.pose, u, n_steps, rng),
            };
            // The target is the proposal's own density, likelihood × motion prior: the prior keeps
            // the climb from sliding along corridors of a poorly converged map.
            let prior = |x: Pose| {
                robust_log_density(
                    cfg.motion.log_density(p.pose, x, u, n_steps),
                    motion_outlier,
                )
            };
            let mode = hill_climb(guess, step, iterations, |x| {
                Ok(like.eval(x, match_stride, sc)? + prior(x))
            })?;
            // Lattice around the mode: likelihood × motion density.
            let mut pts = Vec::with_capacity(27);
            let mut lw = Vec::with_capacity(27);
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dt in -1..=1 {
                        let x = [
                            mode[0] + dx as f64 * fine[0],
                            mode[1] + dy as f64 * fine[1],
                            wrap(mode[2] + dt as f64 * fine[2]),
                        ];
                        let l = like.eval(x, cfg.weight_stride, sc)? + prior(x);
                        pts.push(x);
                        lw.push(l);
                    }
                }
            }
            let m = lw.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            if !m.is_finite() {
                // No lattice point is plausible under the motion model: fall back to odometry.
                let pose = cfg.motion.sample(p.pose, u, n_steps, rng);
                let dlogw = like.eval(pose, cfg.weight_stride, sc)? / cfg.tempering;
                return Ok(Proposed {
                    pose,
                    mean: pose,
                    dlogw,
                });
            }
            let w: Vec<f64> = lw.iter().map(|l| (l - m).exp()).collect();
            let s: f64 = w.iter().sum();
            let dlogw = (m + s.ln()) / cfg.tempering;
            Ok(match pose_rule {
                ProposalPose::Sample => {
                    let fit = FittedGaussian::fit(&pts, &w, s, fine);
                    Proposed {
                        pose: fit.draw(rng),
                        mean: fit.mean,
                        dlogw,
                    }
                }
                ProposalPose::Match => Proposed {
                    pose: mode,
                    mean: mode,
                    dlogw,
                },
            })
        }
    }
}

/// log((1 − ε)·e^{log_p} + ε·u₀) with u₀ = 1 per m²·rad; exactly `log_p` for ε = 0.
fn robust_log_density(log_p: f64, eps: f64) -> f64 {
    if eps == 0.0 {
        return log_p;
    }
    let (a, b) = ((1.0 - eps).ln() + log_p, eps.ln());
    let hi = a.max(b);
    hi + ((a - hi).exp() + (b - hi).exp()).ln()
}

/// Coordinate hill climbing with step halving (GMapping's `optimize`, on any objective).
fn hill_climb<F: FnMut(Pose) -> Result<f64>>(
    start: Pose,
    step: [f64; 3],
    iterations: usize,
    mut f: F,
) -> Result<Pose> {
    let mut best = start;
    let mut best_v = f(start)?;
    let mut st = step;
    for _ in 0..=iterations {
        let mut improved = true;
        let mut guard = 0;
        while improved && guard < 20 {
            improved = false;
            guard += 1;
            for k in 0..6 {
                let mut x = best;
                let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
                x[k / 2] += sign * st[k / 2];
                x[2] = wrap(x[2]);
                let v = f(x)?;
                if v > best_v {
                    best_v = v;
                    best = x;
                    improved = true;
                }
            }
        }
        st = [st[0] / 2.0, st[1] / 2.0, st[2] / 2.0];
    }
    Ok(best)
}

/// The Gaussian fitted to weighted lattice points (circular in θ), with the covariance floored at
/// a tenth of the lattice spacing so it stays positive definite.
struct FittedGaussian {
    mean: Pose,
    /// Lower Cholesky factor of the covariance.
    chol: [[f64; 3]; 3],
}

impl FittedGaussian {
    fn fit(pts: &[Pose], w: &[f64], s: f64, fine: [f64; 3]) -> Self {
        let (mut mx, mut my, mut ss, mut cc) = (0.0, 0.0, 0.0, 0.0);
        for (p, &wi) in pts.iter().zip(w) {
            mx += wi * p[0];
            my += wi * p[1];
            ss += wi * p[2].sin();
            cc += wi * p[2].cos();
        }
        let mean = [mx / s, my / s, ss.atan2(cc)];
        let mut cov = [[0.0f64; 3]; 3];
        for (p, &wi) in pts.iter().zip(w) {
            let d = [p[0] - mean[0], p[1] - mean[1], wrap(p[2] - mean[2])];
            for a in 0..3 {
                for b in 0..3 {
                    cov[a][b] += wi * d[a] * d[b] / s;
                }
            }
        }
        for a in 0..3 {
            cov[a][a] += (0.1 * fine[a]).powi(2);
        }
        Self {
            mean,
            chol: cholesky3(cov),
        }
    }

    fn draw(&self, rng: &mut Rng) -> Pose {
        let (m, l) = (self.mean, self.chol);
        let z = [rng.normal(), rng.normal(), rng.normal()];
        [
            m[0] + l[0][0] * z[0],
            m[1] + l[1][0] * z[0] + l[1][1] * z[1],
            wrap(m[2] + l[2][0] * z[0] + l[2][1] * z[1] + l[2][2] * z[2]),
        ]
    }
}

/// Lower Cholesky factor of a symmetric positive (semi-)definite 3×3 matrix (non-positive
/// pivots clamp to 0, so a degenerate direction gets no noise rather than NaN).
fn cholesky3(a: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut l = [[0.0f64; 3]; 3];
    for i in 0..3 {
        for j in 0..=i {
            let s: f64 = (0..j).map(|k| l[i][k] * l[j][k]).sum();
            if i == j {
                l[i][j] = (a[i][i] - s).max(0.0).sqrt();
            } else {
                l[i][j] = if l[j][j] > 0.0 {
                    (a[i][j] - s) / l[j][j]
                } else {
                    0.0
                };
            }
        }
    }
    l
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    #[test]
    fn cholesky_reconstructs() {
        let a = [[4.0, 2.0, 0.4], [2.0, 3.0, 0.1], [0.4, 0.1, 1.0]];
        let l = cholesky3(a);
        for i in 0..3 {
            for j in 0..3 {
                let v: f64 = (0..3).map(|k| l[i][k] * l[j][k]).sum();
                assert!((v - a[i][j]).abs() < 1e-12);
            }
        }
    }

    /// A lattice much wider than the peak sees only its centre: the draws are the mode plus the
    /// covariance floor (a tenth of the spacing per axis), so the spacing sets their spread.
    #[test]
    fn a_lattice_wider_than_the_peak_draws_the_mode_plus_the_floor() {
        let mode = [1.0, -2.0, 0.3];
        for fine in [[0.05, 0.05, 0.025], [0.1, 0.1, 0.05]] {
            let (mut pts, mut w) = (Vec::new(), Vec::new());
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dt in -1..=1 {
                        let off = [dx as f64, dy as f64, dt as f64];
                        pts.push([
                            mode[0] + off[0] * fine[0],
                            mode[1] + off[1] * fine[1],
                            mode[2] + off[2] * fine[2],
                        ]);
                        // Neighbours 200 nats down: exp underflows to 0 for all but the centre.
                        w.push((-200.0 * (off[0].abs() + off[1].abs() + off[2].abs())).exp());
                    }
                }
            }
            let s: f64 = w.iter().sum();
            let mut rng = Rng::new(7);
            let fit = FittedGaussian::fit(&pts, &w, s, fine);
            assert_eq!(fit.mean, mode);
            let n = 20_000;
            let mut sq = [0.0f64; 3];
            for _ in 0..n {
                let x = fit.draw(&mut rng);
                for a in 0..3 {
                    sq[a] += (x[a] - mode[a]).powi(2);
                }
            }
            for a in 0..3 {
                let sd = (sq[a] / n as f64).sqrt();
                assert!((sd / (0.1 * fine[a]) - 1.0).abs() < 0.03, "axis {a}: {sd}");
            }
        }
    }

    #[test]
    fn robust_density_is_the_motion_density_near_the_guess_and_log_eps_far_away() {
        assert_eq!(robust_log_density(-3.7, 0.0), -3.7);
        let eps: f64 = 1e-3;
        // Near the guess: log(1 − ε) + log p to within the floor's share.
        let near = robust_log_density(2.0, eps);
        assert!((near - ((1.0 - eps).ln() + 2.0)).abs() < eps * (-2.0f64).exp() * 1.01);
        // Far away (p → 0): the floor ε·u₀.
        assert!((robust_log_density(-500.0, eps) - eps.ln()).abs() < 1e-12);
        assert_eq!(robust_log_density(f64::NEG_INFINITY, eps), eps.ln());
        // A proper mixture: it never falls below either weighted component.
        for lp in [-50.0, -7.0, -6.9, 0.0, 3.0] {
            let v = robust_log_density(lp, eps);
            assert!(v >= eps.ln() && v >= (1.0 - eps).ln() + lp);
        }
    }

    /// A map of a 4 m × 3 m room (0.1 m cells) seen from near its centre by 361 beams over 360°,
    /// and the scan taken at the centre.
    pub(crate) fn room_scan(z_max: f64) -> (ClamConfig, CrmMap, Vec<f64>, Vec<f64>) {
        use crate::crm::CrmConfig;
        use crate::grid::GridGeometry;
        let cfg = ClamConfig::paper(
            CrmConfig::new(GridGeometry::new([0.0, 0.0], 0.1).unwrap()),
            z_max,
        );
        let angles: Vec<f64> = (0..361)
            .map(|i| -std::f64::consts::PI + i as f64 * std::f64::consts::TAU / 361.0)
            .collect();
        // Distances to the walls x = ±2, y = ±1.5 from the origin.
        let ranges: Vec<f64> = angles
            .iter()
            .map(|a| {
                let (s, c) = a.sin_cos();
                let tx = if c.abs() > 1e-12 {
                    2.0 / c.abs()
                } else {
                    f64::INFINITY
                };
                let ty = if s.abs() > 1e-12 {
                    1.5 / s.abs()
                } else {
                    f64::INFINITY
                };
                tx.min(ty)
            })
            .collect();
        let mut map = CrmMap::new(&cfg.crm).unwrap();
        let mut sc = CrmScratch::default();
        for k in 0..3 {
            let pose = [0.02 * k as f64, -0.01 * k as f64, 0.01 * k as f64];
            map.update_scan(
                pose,
                &angles,
                &ranges,
                &cfg.mapping_model,
                &scan_opts(&cfg, 1),
                &mut sc,
            )
            .unwrap();
        }
        (cfg, map, angles, ranges)
    }

    #[test]
    fn batch_and_forward_likelihoods_agree_and_the_window_picks_the_path() {
        let (cfg, map, angles, ranges) = room_scan(8.0);
        let scan = ScanInput {
            odom: [0.0; 3],
            angles: &angles,
            ranges: &ranges,
            laser_offset: [0.0; 3],
        };
        let mut sc = CrmScratch::default();
        // 8 m at 0.1 m: a small window, so the batch path on a copy of the map.
        let mut like = ScanLikelihood::new(&cfg, &scan, &map);
        assert!(like.batch.is_some());
        let mut forward = ScanLikelihood {
            batch: None,
            ..ScanLikelihood::new(&cfg, &scan, &map)
        };
        let mut distinct = Vec::new();
        for pose in [[0.0, 0.0, 0.0], [0.07, -0.04, 0.02], [-0.3, 0.2, -0.1]] {
            for stride in [1, 3] {
                let (a, b) = (
                    like.eval(pose, stride, &mut sc).unwrap(),
                    forward.eval(pose, stride, &mut sc).unwrap(),
                );
                assert!(
                    a.is_finite() && (a - b).abs() <= 1e-10 * b.abs(),
                    "{pose:?} {stride}: {a} vs {b}"
                );
                distinct.push(a);
            }
        }
        assert!(
            distinct.windows(2).any(|w| (w[0] - w[1]).abs() > 1.0),
            "{distinct:?}"
        );
        // 80 m at 0.1 m: a window of 2.6 M cells, so the forward walk.
        let (cfg80, map80, ..) = room_scan(80.0);
        assert!(ScanLikelihood::new(&cfg80, &scan, &map80).batch.is_none());
    }

    #[test]
    fn hill_climb_finds_a_quadratic_peak() {
        let target = [0.23, -0.11, 0.07];
        let best = hill_climb([0.0; 3], [0.1, 0.1, 0.05], 6, |x| {
            Ok(-((x[0] - target[0]).powi(2)
                + (x[1] - target[1]).powi(2)
                + (x[2] - target[2]).powi(2)))
        })
        .unwrap();
        for i in 0..3 {
            assert!((best[i] - target[i]).abs() < 5e-3, "{best:?}");
        }
    }
}
