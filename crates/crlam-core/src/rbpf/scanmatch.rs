//! GMapping-style scan matching against a particle's own log-odds grid, and the improved
//! proposal built on it (Grisetti, Stachniss, Burgard 2007, section IV).
//!
//! A beam "matches" when, within a (2k+1)² window of cells around its endpoint, there is an
//! occupied cell (log-odds > 0) whose companion cell, shifted by the same window offset from the
//! endpoint's "free point" (the point √2·Δ back along the beam), is free. What "free" means is
//! [`FreeTest`]: with [`FreeTest::Observed`] (the default) the companion must have been seen
//! free (log-odds < 0), which also rejects the far side of a thin wall seen only from the other
//! side; with [`FreeTest::NotOccupied`] (GMapping's `fcell < fullnessThreshold`, where an unknown
//! cell reads −1) it only must not be occupied. The distance d is taken from the endpoint to the
//! centre of the closest such cell, or, when the grid keeps them
//! ([`crate::ogm::LogOddsParams::hit_means`]), to the mean of the hits of the cell, as GMapping
//! does (cell centres cap the precision at about Δ/2).
//!
//! Per matched beam (GMapping's forms; both "sigmas" enter as variances, in m²):
//! - score      `exp(−d² / score_sigma)`,
//! - log-lik    `−d² / likelihood_sigma`; an unmatched beam adds `null_likelihood / likelihood_sigma`
//!   (as if it were off by d² = −null_likelihood m²).
//!
//! The score drives the hill-climbing search ([`ScanMatcher::optimize`]); the log-likelihood
//! drives the proposal and the weights ([`ScanMatcher::improved_proposal`]).

use super::match_surface::{MatchSurface, FREE, OCCUPIED};
pub use super::prepared_scan::PreparedScan;
pub use super::scanmatch_params::{FreeTest, MatcherParams, ProposalParams};
use crate::error::Result;
use crate::grid::{check_pose, GridGeometry};
use crate::pose::{wrap, Pose};
use crate::rng::Rng;

/// Distance from the endpoint to the "free point", in cells: √2 guarantees that the free point
/// lies in a different cell than the endpoint whatever the beam direction (GMapping's
/// freeCellRatio).
const FREE_CELL_RATIO: f64 = std::f64::consts::SQRT_2;
/// Hard cap on accepted hill-climbing moves, so a pathological score surface cannot loop long.
const MAX_MOVES: usize = 1000;

/// Index of the cell containing `p`, like [`GridGeometry::cell_of`] but multiplying by the
/// precomputed inverse resolution and flooring inline (the division and the libm `floor` call
/// showed in the matcher's profile). It may differ from `cell_of` only for points within an ulp
/// of a cell boundary, which is immaterial to matching. Exact floor for |v| < 2⁶³, which valid
/// poses and bounded ranges guarantee.
#[inline]
fn cell_of(g: &GridGeometry, inv_res: f64, p: [f64; 2]) -> (i64, i64) {
    let floor = |v: f64| {
        let i = v as i64;
        i - i64::from((i as f64) > v)
    };
    (
        floor((p[0] - g.origin[0]) * inv_res),
        floor((p[1] - g.origin[1]) * inv_res),
    )
}

/// Score and log-likelihood of a scan at one pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScanFit {
    /// Σ over matched beams of exp(−d²/score_sigma).
    pub score: f64,
    /// Σ over beams of the per-beam log-likelihood (always finite).
    pub log_likelihood: f64,
    /// Beams that found a matching cell.
    pub matched: usize,
}

/// Result of the improved proposal for one particle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProposalDraw {
    /// The sampled pose.
    pub pose: Pose,
    /// log η ≈ log ∫ p(z | m, x) p(x | x', u) dx, by the lattice sum Σ_k L_k p_k ΔV.
    pub log_normalizer: f64,
    /// Mean and covariance of the fitted Gaussian (world x, y, heading).
    pub mean: Pose,
    pub covariance: [[f64; 3]; 3],
}

/// Scan matcher over [`LogOddsGrid`](crate::ogm::LogOddsGrid)s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScanMatcher {
    pub params: MatcherParams,
}

impl ScanMatcher {
    pub fn new(params: MatcherParams) -> Result<Self> {
        params.validate()?;
        Ok(Self { params })
    }

    /// Squared distance from endpoint `e` to the closest occupied cell in the window whose
    /// companion cell around the free point `f` is free; `None` if no cell qualifies.
    #[inline]
    fn best_match(
        &self,
        surface: &MatchSurface,
        g: &GridGeometry,
        e: [f64; 2],
        f: [f64; 2],
    ) -> Option<f64> {
        let inv_res = 1.0 / g.resolution;
        let (ix, iy) = cell_of(g, inv_res, e);
        let (fx, fy) = cell_of(g, inv_res, f);
        // The reads are the dominant cost of the matcher (see [`MatchSurface`]).
        let qualifies = |dx: i64, dy: i64| {
            surface.class(ix + dx, iy + dy) & OCCUPIED != 0
                && surface.class(fx + dx, fy + dy) & FREE != 0
        };
        let c0 = g.cell_center(ix, iy);
        let (ox, oy) = (e[0] - c0[0], e[1] - c0[1]);
        let res = g.resolution;
        let k = self.params.kernel_size as i64;
        // Visit offsets nearest-side first on each axis (0, s, −s, 2s, −2s, ... with s the side
        // of the cell centre the endpoint lies on): a close candidate found early lets the
        // distance test skip the map reads of farther cells.
        let (sx, sy) = (
            if ox >= 0.0 { 1 } else { -1 },
            if oy >= 0.0 { 1 } else { -1 },
        );
        let nth = |s: i64, j: i64| {
            if j % 2 == 1 {
                s * (j + 1) / 2
            } else {
                -s * j / 2
            }
        };
        if surface.has_hit_means() {
            // GMapping: the distance to the mean of the hits of each qualifying cell, the
            // smallest over the window (a neighbour's mean may lie closer than the own cell's).
            // Every mean lies in its cell, so the distance to the cell's square bounds it from
            // below and cells that cannot beat the best so far are not read.
            let half = 0.5 * res;
            let gap = |o: f64, d: i64| ((o - d as f64 * res).abs() - half).max(0.0);
            let mut best = f64::INFINITY;
            for jy in 0..=2 * k {
                let dy = nth(sy, jy);
                for jx in 0..=2 * k {
                    let dx = nth(sx, jx);
                    if gap(ox, dx).powi(2) + gap(oy, dy).powi(2) >= best {
                        continue;
                    }
                    let Some(m) = surface.occupied_hit_mean(ix + dx, iy + dy) else {
                        continue;
                    };
                    if surface.class(fx + dx, fy + dy) & FREE == 0 {
                        continue;
                    }
                    let d2 = (ox - dx as f64 * res - m[0]).powi(2)
                        + (oy - dy as f64 * res - m[1]).powi(2);
                    best = best.min(d2);
                }
            }
            return best.is_finite().then_some(best);
        }
        let dist2 =
            |dx: i64, dy: i64| (ox - dx as f64 * res).powi(2) + (oy - dy as f64 * res).powi(2);
        // The endpoint's own cell centre is the closest of the window (|offset| ≤ Δ/2 on each
        // axis, every other centre is ≥ Δ/2 away on some axis), so when that cell qualifies the
        // rest of the window cannot do better. This is the common case near the match.
        if qualifies(0, 0) {
            return Some(dist2(0, 0));
        }
        let mut best = f64::INFINITY;
        for jy in 0..=2 * k {
            let dy = nth(sy, jy);
            for jx in 0..=2 * k {
                let dx = nth(sx, jx);
                if (dx, dy) == (0, 0) {
                    continue;
                }
                // Distance first: it needs no map read.
                let d2 = dist2(dx, dy);
                if d2 < best && qualifies(dx, dy) {
                    best = d2;
                }
            }
        }
        best.is_finite().then_some(best)
    }

    /// The surface the matcher reads for `scan` near `pose` on `map`: with a dense patch of
    /// cell classes when that pays (the results are the same either way).
    pub fn surface<'a>(
        &self,
        map: &'a crate::ogm::LogOddsGrid,
        scan: &PreparedScan,
        pose: Pose,
    ) -> MatchSurface<'a> {
        MatchSurface::around(
            map,
            scan,
            pose,
            self.params.kernel_size,
            self.params.free_test,
        )
    }

    /// Score and log-likelihood of `scan` with the robot at `pose` on `surface`.
    pub fn evaluate(
        &self,
        surface: &MatchSurface,
        scan: &PreparedScan,
        pose: Pose,
    ) -> Result<ScanFit> {
        self.fit::<true, true>(surface, scan, pose)
    }

    /// [`Self::evaluate`] computing only the score (`SCORE`) and/or the log-likelihood (`LIKE`);
    /// the other is left at 0. The hill climbing needs only scores and the proposal lattice only
    /// likelihoods, and the score's exponentials were a third of the filter's time. Each part is
    /// accumulated in the same order as by `evaluate`, so it is the same to the bit.
    fn fit<const SCORE: bool, const LIKE: bool>(
        &self,
        surface: &MatchSurface,
        scan: &PreparedScan,
        pose: Pose,
    ) -> Result<ScanFit> {
        self.fit_beams::<SCORE, LIKE>(surface, &scan.beams, pose)
    }

    /// GMapping's endpoint log-likelihood of the beams of `scan` beyond its near range (z_max)
    /// with the robot at `pose`: 0 when it has none. RBPF-CLAM's weight scores these readings
    /// with it, the CRM likelihood scoring those below z_max (see [`super::clam_match`]).
    pub fn far_log_likelihood(
        &self,
        surface: &MatchSurface,
        scan: &PreparedScan,
        pose: Pose,
    ) -> Result<f64> {
        let far = &scan.beams[scan.n_near()..];
        if far.is_empty() {
            return Ok(0.0);
        }
        Ok(self
            .fit_beams::<false, true>(surface, far, pose)?
            .log_likelihood)
    }

    /// [`Self::fit`] over `beams`.
    fn fit_beams<const SCORE: bool, const LIKE: bool>(
        &self,
        surface: &MatchSurface,
        beams: &[super::prepared_scan::PreparedBeam],
        pose: Pose,
    ) -> Result<ScanFit> {
        // A valid pose (|x|, |y| ≤ 1e7) and a bounded usable range keep all cell indices far
        // from integer overflow.
        check_pose(pose)?;
        let g = *surface.geometry();
        let back = FREE_CELL_RATIO * g.resolution;
        let (s, c) = pose[2].sin_cos();
        let null = self.params.null_likelihood / self.params.likelihood_sigma;
        let mut fit = ScanFit {
            score: 0.0,
            log_likelihood: 0.0,
            matched: 0,
        };
        for b in beams {
            let e = [
                pose[0] + c * b.end[0] - s * b.end[1],
                pose[1] + s * b.end[0] + c * b.end[1],
            ];
            let f = [
                e[0] - back * (c * b.dir[0] - s * b.dir[1]),
                e[1] - back * (s * b.dir[0] + c * b.dir[1]),
            ];
            match self.best_match(surface, &g, e, f) {
                Some(d2) => {
                    if SCORE {
                        fit.score += (-d2 / self.params.score_sigma).exp();
                    }
                    if LIKE {
                        fit.log_likelihood -= d2 / self.params.likelihood_sigma;
                    }
                    fit.matched += 1;
                }
                None => {
                    if LIKE {
                        fit.log_likelihood += null;
                    }
                }
            }
        }
        Ok(fit)
    }

    /// The endpoint score of `scan` with the robot at `pose` (the log-likelihood not computed).
    pub fn score(&self, surface: &MatchSurface, scan: &PreparedScan, pose: Pose) -> Result<f64> {
        Ok(self.fit::<true, false>(surface, scan, pose)?.score)
    }

    /// Hill climbing from `start` (GMapping's `optimize`): try ±lstep in world x and y and
    /// ±astep in heading, move to the best neighbour while the score strictly improves, else
    /// halve both steps; stop after `iterations` halvings. Returns the best pose and its score.
    pub fn optimize(
        &self,
        surface: &MatchSurface,
        scan: &PreparedScan,
        start: Pose,
    ) -> Result<(Pose, f64)> {
        self.climb(start, |p| self.score(surface, scan, p))
    }

    /// [`Self::optimize`]'s climb on the endpoint log-likelihood plus `log_prior` (the function
    /// [`Self::fit_proposal`] evaluates on its lattice). Returns the best pose and its value.
    pub fn optimize_posterior<F: Fn(Pose) -> f64>(
        &self,
        surface: &MatchSurface,
        scan: &PreparedScan,
        start: Pose,
        log_prior: F,
    ) -> Result<(Pose, f64)> {
        self.climb(start, |p| {
            Ok(self.fit::<false, true>(surface, scan, p)?.log_likelihood + log_prior(p))
        })
    }

    /// GMapping's hill climb of `objective` from `start` (see [`Self::optimize`]).
    fn climb<F: Fn(Pose) -> Result<f64>>(&self, start: Pose, objective: F) -> Result<(Pose, f64)> {
        let mut best = start;
        let mut best_value = objective(start)?;
        let (mut l, mut a) = (self.params.lstep, self.params.astep);
        let mut halvings = 0;
        let mut moves = 0;
        // Index of the move that led to `best`; its reverse (index ^ 1) leads back to the
        // previous pose, whose value is known to be lower, so it is not evaluated again.
        let mut last_move: Option<usize> = None;
        while halvings <= self.params.iterations && moves < MAX_MOVES {
            let steps = [
                [l, 0.0, 0.0],
                [-l, 0.0, 0.0],
                [0.0, l, 0.0],
                [0.0, -l, 0.0],
                [0.0, 0.0, a],
                [0.0, 0.0, -a],
            ];
            let mut cand: Option<(usize, Pose, f64)> = None;
            for (i, d) in steps.iter().enumerate() {
                if last_move == Some(i ^ 1) {
                    continue;
                }
                let p = [best[0] + d[0], best[1] + d[1], wrap(best[2] + d[2])];
                let v = objective(p)?;
                if v > cand.map_or(best_value, |c| c.2) {
                    cand = Some((i, p, v));
                }
            }
            match cand {
                Some((i, p, v)) => {
                    best = p;
                    best_value = v;
                    last_move = Some(i);
                    moves += 1;
                }
                None => {
                    l *= 0.5;
                    a *= 0.5;
                    halvings += 1;
                    last_move = None;
                }
            }
        }
        Ok((best, best_value))
    }

    /// The improved proposal around the matched pose `center`: evaluate
    /// log L_k + log_prior(x_k) on the lattice, fit a Gaussian to the normalised values (mean and
    /// covariance of the lattice offsets, headings as offsets from `center` so the cut at ±π
    /// does not matter), draw the new pose from it, and return log η = LSE_k(...) + log ΔV.
    pub fn improved_proposal<F: Fn(Pose) -> f64>(
        &self,
        surface: &MatchSurface,
        scan: &PreparedScan,
        center: Pose,
        log_prior: F,
        params: &ProposalParams,
        rng: &mut Rng,
    ) -> Result<ProposalDraw> {
        Ok(self
            .fit_proposal(surface, scan, center, log_prior, params)?
            .draw(rng))
    }

    /// The lattice and the fitted Gaussian of [`Self::improved_proposal`], before its draw: a
    /// pure function of the map, the scan and `center`, so particles that share all three (the
    /// children of one parent right after a resampling) share it and draw from it each with
    /// their own random stream.
    pub fn fit_proposal<F: Fn(Pose) -> f64>(
        &self,
        surface: &MatchSurface,
        scan: &PreparedScan,
        center: Pose,
        log_prior: F,
        params: &ProposalParams,
    ) -> Result<ProposalFit> {
        let h = params.half_steps as i64;
        let step = params.range.map(|r| r / h as f64);
        let side = (2 * h + 1) as usize;
        let mut values = Vec::with_capacity(side * side * side);
        for ix in -h..=h {
            for iy in -h..=h {
                for it in -h..=h {
                    let o = [
                        ix as f64 * step[0],
                        iy as f64 * step[1],
                        it as f64 * step[2],
                    ];
                    let x = [center[0] + o[0], center[1] + o[1], wrap(center[2] + o[2])];
                    let lw =
                        self.fit::<false, true>(surface, scan, x)?.log_likelihood + log_prior(x);
                    values.push((o, lw));
                }
            }
        }
        let (mean_off, cov, lse) = fit_gaussian(&values, params.regularization);
        let chol = cholesky3(&cov).ok_or_else(|| crate::error::CrlamError::NonFinite {
            field: "proposal covariance",
            value: cov[0][0],
        })?;
        let log_volume = (step[0] * step[1] * step[2]).ln();
        Ok(ProposalFit {
            center,
            mean_off,
            covariance: cov,
            chol,
            log_normalizer: lse + log_volume,
        })
    }
}

/// The Gaussian the improved proposal fitted around a match ([`ScanMatcher::fit_proposal`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProposalFit {
    center: Pose,
    /// Mean offset from `center` (world x, y, heading).
    mean_off: [f64; 3],
    covariance: [[f64; 3]; 3],
    /// Lower Cholesky factor of `covariance`.
    chol: [[f64; 3]; 3],
    log_normalizer: f64,
}

impl ProposalFit {
    /// log η of the lattice (see [`ProposalDraw::log_normalizer`]).
    pub fn log_normalizer(&self) -> f64 {
        self.log_normalizer
    }

    /// A pose drawn from the fitted Gaussian (three standard normals from `rng`).
    pub fn draw(&self, rng: &mut Rng) -> ProposalDraw {
        let n = [rng.normal(), rng.normal(), rng.normal()];
        let (c, l) = (self.center, &self.chol);
        let mut pose = [0.0; 3];
        for r in 0..3 {
            let noise: f64 = (0..=r).map(|k| l[r][k] * n[k]).sum();
            pose[r] = c[r] + self.mean_off[r] + noise;
        }
        pose[2] = wrap(pose[2]);
        ProposalDraw {
            pose,
            log_normalizer: self.log_normalizer,
            mean: [
                c[0] + self.mean_off[0],
                c[1] + self.mean_off[1],
                wrap(c[2] + self.mean_off[2]),
            ],
            covariance: self.covariance,
        }
    }
}

/// Weighted mean and covariance of lattice offsets with log-weights, plus their logsumexp.
/// Weights are exp(lw − max), so the largest is 1 and the sum is ≥ 1 (no division by zero);
/// a non-finite log-weight counts as zero weight.
fn fit_gaussian(values: &[([f64; 3], f64)], reg: [f64; 3]) -> ([f64; 3], [[f64; 3]; 3], f64) {
    let m = values
        .iter()
        .map(|v| v.1)
        .filter(|v| v.is_finite())
        .fold(f64::NEG_INFINITY, f64::max);
    let weight = |lw: f64| {
        if lw.is_finite() && m.is_finite() {
            (lw - m).exp()
        } else {
            0.0
        }
    };
    let mut sw = 0.0;
    let mut mean = [0.0; 3];
    for (o, lw) in values {
        let w = weight(*lw);
        sw += w;
        for i in 0..3 {
            mean[i] += w * o[i];
        }
    }
    if sw <= 0.0 {
        // Every value −∞ (cannot happen with a finite prior): fall back to the centre.
        let cov = [
            [reg[0] * reg[0], 0.0, 0.0],
            [0.0, reg[1] * reg[1], 0.0],
            [0.0, 0.0, reg[2] * reg[2]],
        ];
        return ([0.0; 3], cov, f64::NEG_INFINITY);
    }
    mean = mean.map(|v| v / sw);
    let mut cov = [[0.0; 3]; 3];
    for (o, lw) in values {
        let w = weight(*lw) / sw;
        let d = [o[0] - mean[0], o[1] - mean[1], o[2] - mean[2]];
        for r in 0..3 {
            for c in 0..3 {
                cov[r][c] += w * d[r] * d[c];
            }
        }
    }
    for i in 0..3 {
        cov[i][i] += reg[i] * reg[i];
    }
    (mean, cov, m + sw.ln())
}

/// Lower Cholesky factor of a symmetric 3×3 matrix; `None` unless positive definite.
pub fn cholesky3(a: &[[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let mut l = [[0.0; 3]; 3];
    for r in 0..3 {
        for c in 0..=r {
            let s: f64 = (0..c).map(|k| l[r][k] * l[c][k]).sum();
            if r == c {
                let d = a[r][r] - s;
                if !(d.is_finite() && d > 0.0) {
                    return None;
                }
                l[r][c] = d.sqrt();
            } else {
                l[r][c] = (a[r][c] - s) / l[c][c];
            }
        }
    }
    Some(l)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_reconstructs_and_refuses_indefinite() {
        let a = [[4.0, 2.0, 0.4], [2.0, 5.0, 1.0], [0.4, 1.0, 3.0]];
        let l = cholesky3(&a).unwrap();
        for r in 0..3 {
            for c in 0..3 {
                let v: f64 = (0..3).map(|k| l[r][k] * l[c][k]).sum();
                assert!((v - a[r][c]).abs() < 1e-12);
            }
        }
        assert!(cholesky3(&[[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).is_none());
    }

    #[test]
    fn gaussian_fit_of_a_symmetric_lattice_is_centred() {
        let mut v = Vec::new();
        for i in -1..=1 {
            let o = [i as f64 * 0.1, 0.0, 0.0];
            v.push((o, -(i as f64).powi(2)));
        }
        let (m, cov, lse) = fit_gaussian(&v, [1e-3; 3]);
        assert!(m.iter().all(|x| x.abs() < 1e-12));
        let w = (-1f64).exp();
        let var = 2.0 * w * 0.01 / (1.0 + 2.0 * w);
        assert!((cov[0][0] - var - 1e-6).abs() < 1e-12);
        assert!((lse - (1.0 + 2.0 * w).ln()).abs() < 1e-12);
    }

    #[test]
    fn prepared_scan_filters_and_strides() {
        let a = [0.0, 0.1, 0.2, 0.3, 0.4];
        let z = [1.0, f64::INFINITY, 2.0, 0.0, 9.0];
        let s = PreparedScan::new(&a, &z, [0.0; 3], 5.0, 1).unwrap();
        assert_eq!(s.len(), 2);
        let s = PreparedScan::new(&a, &z, [0.0; 3], 5.0, 2).unwrap();
        assert_eq!(s.len(), 2); // beams 0 and 2; 4 is beyond the usable range
        assert!(PreparedScan::new(&a, &z[..3], [0.0; 3], 5.0, 1).is_err());
        assert!(PreparedScan::new(&a, &z, [0.0; 3], f64::NAN, 1).is_err());
    }

    #[test]
    fn the_far_log_likelihood_is_that_of_the_far_beams_alone() {
        use crate::ogm::{LogOddsGrid, LogOddsParams};
        use crate::rbpf::clam_config::MatchRange;
        // A map written from the origin up to 12 m; a scan from 1 m further on whose readings
        // reach 2-11 m, with the map's z_max at 6 m.
        let g = GridGeometry::new([0.0, 0.0], 0.1).unwrap();
        let mut map = LogOddsGrid::new(g, LogOddsParams::new(12.0), 16, None).unwrap();
        let angles: Vec<f64> = (0..60).map(|i| -1.2 + i as f64 * 0.04).collect();
        let ranges: Vec<f64> = (0..60).map(|i| 3.0 + (i % 9) as f64).collect();
        map.update_scan([0.0, 0.0, 0.0], &angles, &ranges).unwrap();
        let seen: Vec<f64> = ranges.iter().map(|z| z - 0.5).collect();
        let m = ScanMatcher::new(MatcherParams::default()).unwrap();
        let surface = MatchSurface::tiles(&map, FreeTest::NotOccupied);
        let pose = [0.5, 0.0, 0.0];
        let full = MatchRange::Full.selection(6.0, 20.0);
        let scan = PreparedScan::select(&angles, &seen, [0.0; 3], full, 1).unwrap();
        assert!(scan.n_near() > 0 && scan.n_near() < scan.len());
        // The far readings alone, as a scan of their own.
        let far_z: Vec<f64> = seen
            .iter()
            .map(|&z| if z >= 6.0 { z } else { f64::INFINITY })
            .collect();
        let far = PreparedScan::new(&angles, &far_z, [0.0; 3], 100.0, 1).unwrap();
        assert_eq!(far.len(), scan.len() - scan.n_near());
        let want = m.evaluate(&surface, &far, pose).unwrap();
        assert!(want.matched > 0, "the far endpoints must hit mapped cells");
        let got = m.far_log_likelihood(&surface, &scan, pose).unwrap();
        assert_eq!(got, want.log_likelihood);
        // The paper's range has no far beams.
        let near = PreparedScan::select(
            &angles,
            &seen,
            [0.0; 3],
            MatchRange::ZMax.selection(6.0, 20.0),
            1,
        )
        .unwrap();
        assert_eq!(m.far_log_likelihood(&surface, &near, pose).unwrap(), 0.0);
    }
}
