//! Benchmark workloads of the information functions (`crlam bench`): 10 beams over 360°, 5 m
//! range, 0.2 m grid, one thread, on a synthetic 20 m × 20 m cave-like world.

use std::time::Instant;

use crate::error::{CrlamError, Result};
use crate::grid::GridGeometry;
use crate::info::crmi::{Crmi, CrmiConfig, CrmiScratch};
use crate::info::fsmi::{Fsmi, FsmiVariant, DEFAULT_TRUNCATION_SIGMAS};
use crate::info::iig_mi::IigMi;
use crate::info::lattice::{traverse_lattice, BeamAngles, OccupancyLattice};
use crate::info::prior::crm_from_lattice;
use crate::info::{Candidate, InformationFunction};
use crate::rng::Rng;

/// The planner's lattice shape: nodes at −1, −0.8, …, 21 m (111 × 111).
pub const CAVE_NODES: usize = 111;

/// A deterministic cave-like world on the planner's lattice: border walls, a few rectangular
/// blocks and scattered pillars, with the reference prior (0.85 on obstacles, 0.3 elsewhere).
pub fn synthetic_cave() -> Result<OccupancyLattice> {
    let g = GridGeometry::new([-1.1, -1.1], 0.2)?;
    let n = CAVE_NODES;
    let mut p = vec![0.3; n * n];
    let mut rng = Rng::new(2022);
    let blocks: Vec<[f64; 4]> = (0..12)
        .map(|_| {
            let (x, y) = (2.0 + 15.0 * rng.uniform(), 2.0 + 15.0 * rng.uniform());
            [
                x,
                y,
                x + 0.6 + 2.0 * rng.uniform(),
                y + 0.6 + 2.0 * rng.uniform(),
            ]
        })
        .collect();
    for b in 0..n {
        for a in 0..n {
            let (x, y) = (-1.0 + 0.2 * a as f64, -1.0 + 0.2 * b as f64);
            let border = (x.abs() < 0.05 || (x - 20.0).abs() < 0.05)
                && (-0.05..=20.05).contains(&y)
                || (y.abs() < 0.05 || (y - 20.0).abs() < 0.05) && (-0.05..=20.05).contains(&x);
            let block = blocks
                .iter()
                .any(|r| x >= r[0] && x <= r[2] && y >= r[1] && y <= r[3]);
            if border || block {
                p[a + b * n] = 0.85;
            }
        }
    }
    OccupancyLattice::new(g, n, n, p)
}

/// Candidate poses inside the world, away from the border.
pub fn bench_poses(n: usize) -> Vec<[f64; 3]> {
    let mut rng = Rng::new(7);
    (0..n)
        .map(|_| [1.0 + 18.0 * rng.uniform(), 1.0 + 18.0 * rng.uniform(), 0.0])
        .collect()
}

/// Microseconds per candidate pose of CRMI with the given configuration.
pub fn crmi_us_per_pose(cfg: CrmiConfig, n_poses: usize) -> Result<f64> {
    let lat = synthetic_cave()?;
    let map = crm_from_lattice(&lat, 10)?;
    let crmi = Crmi::new(cfg)?;
    let poses = bench_poses(n_poses);
    let mut sc = CrmiScratch::default();
    let mut sink = 0.0;
    // Warm-up pass so that buffers are sized.
    for p in poses.iter().take(10) {
        sink += crmi.gain_with(&map, *p, &mut sc)?;
    }
    let t = Instant::now();
    for p in &poses {
        sink += crmi.gain_with(&map, *p, &mut sc)?;
    }
    let us = t.elapsed().as_secs_f64() * 1e6 / n_poses.max(1) as f64;
    std::hint::black_box(sink);
    Ok(us)
}

/// µs per pose of each OGMI evaluation on one thread (see [`bench_fsmi_vs_julian`]).
#[derive(Clone, Debug, PartialEq)]
pub struct FsmiBench {
    pub n_poses: usize,
    pub cells_per_beam: f64,
    pub full_us: f64,
    pub truncated_us: f64,
    pub noise_free_us: f64,
    /// Smallest tried λ_z whose Julian scan MI is within 1e-3 relative of full FSMI at every pose.
    pub julian_points_per_cell: usize,
    pub julian_us: f64,
    pub julian_max_rel_err: f64,
    pub julian10_us: f64,
    pub julian100_us: f64,
    /// Largest relative difference of truncated (3σ) and full FSMI over the poses.
    pub truncated_max_rel_err: f64,
    /// IIG 'mi' (`evaluate`, map update included).
    pub iig_mi_us: f64,
}

/// The benchmark map: the planner's 111 × 111 lattice at 0.2 m, background 0.3, 20 unknown (0.5)
/// squares and 40 wall segments at 0.85, seeded.
pub fn bench_lattice(seed: u64) -> Result<OccupancyLattice> {
    let n = 111;
    let mut prob = vec![0.3; n * n];
    let mut rng = Rng::new(seed);
    let mut pick = |m: usize| ((rng.uniform() * m as f64) as usize).min(m - 1);
    for _ in 0..20 {
        let (a, b, side) = (pick(n), pick(n), 3 + pick(6));
        for y in b..(b + side).min(n) {
            prob[y * n + a..y * n + (a + side).min(n)].fill(0.5);
        }
    }
    for _ in 0..40 {
        let (a, b, len, vertical) = (pick(n), pick(n), 5 + pick(20), pick(2) == 0);
        for t in 0..len {
            let (x, y) = if vertical { (a, b + t) } else { (a + t, b) };
            if x < n && y < n {
                prob[y * n + x] = 0.85;
            }
        }
    }
    OccupancyLattice::new(
        crate::grid::GridGeometry::new([-1.1, -1.1], 0.2)?,
        n,
        n,
        prob,
    )
}

/// The values at `poses` and the mean µs per pose: passes are repeated until 0.2 s have been
/// timed, the first (warm-up) pass being kept only when it alone is that long.
fn time_per_pose(
    poses: &[[f64; 3]],
    f: impl Fn([f64; 3]) -> Result<f64>,
) -> Result<(f64, Vec<f64>)> {
    let start = Instant::now();
    let values = poses.iter().map(|&p| f(p)).collect::<Result<Vec<_>>>()?;
    let mut elapsed = start.elapsed().as_secs_f64();
    let mut passes = 1;
    if elapsed < 0.2 {
        let start = Instant::now();
        passes = 0;
        while passes == 0 || start.elapsed().as_secs_f64() < 0.2 {
            for &p in poses {
                std::hint::black_box(f(p)?);
            }
            passes += 1;
        }
        elapsed = start.elapsed().as_secs_f64();
    }
    Ok((elapsed * 1e6 / (passes * poses.len()) as f64, values))
}

fn max_rel_err(a: &[f64], reference: &[f64]) -> f64 {
    let rel = |(x, r): (&f64, &f64)| (x - r).abs() / if *r > 0.0 { *r } else { 1.0 };
    a.iter().zip(reference).map(rel).fold(0.0, f64::max)
}

/// Times FSMI full, truncated (3σ) and noise-free, Julian (at the smallest tried λ_z that matches
/// full FSMI to 1e-3 relative at every pose, and at λ_z = 10 and 100) and IIG 'mi', on `n_poses`
/// seeded positions of [`bench_lattice`]: 10 distinct beams over 360°, z_max = 5 m, one thread.
pub fn bench_fsmi_vs_julian(n_poses: usize, seed: u64) -> Result<FsmiBench> {
    let map = bench_lattice(seed)?;
    let mut rng = Rng::new(seed ^ 0x05E5);
    let poses: Vec<[f64; 3]> = (0..n_poses.max(1))
        .map(|_| [20.0 * rng.uniform(), 20.0 * rng.uniform(), 0.0])
        .collect();
    let values = |variant| -> Result<Vec<f64>> {
        let f = Fsmi::new(variant);
        poses.iter().map(|&p| f.scan_mi(&map, p)).collect()
    };
    let timed = |variant| {
        let f = Fsmi::new(variant);
        time_per_pose(&poses, |p| f.scan_mi(&map, p))
    };
    let (full_us, full) = timed(FsmiVariant::Full)?;
    let width_sigmas = DEFAULT_TRUNCATION_SIGMAS;
    let (truncated_us, truncated) = timed(FsmiVariant::Truncated { width_sigmas })?;
    let (noise_free_us, _) = timed(FsmiVariant::NoiseFree)?;
    let mut julian = (0, f64::INFINITY);
    for points_per_cell in [1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 256] {
        julian = (
            points_per_cell,
            max_rel_err(&values(FsmiVariant::Julian { points_per_cell })?, &full),
        );
        if julian.1 <= 1e-3 {
            break;
        }
    }
    let julian_us =
        |points_per_cell| Ok::<_, CrlamError>(timed(FsmiVariant::Julian { points_per_cell })?.0);
    let iig = IigMi::default();
    let (iig_mi_us, _) = time_per_pose(&poses, |p| {
        iig.evaluate(&map, &(), &Candidate::at(p), 0)
            .map(|e| e.gain)
    })?;
    let (mut cells, mut count) = (Vec::new(), 0);
    for p in &poses {
        for a in BeamAngles::Distinct.angles(10, 0.0) {
            traverse_lattice(&map, [p[0], p[1]], a, 5.0, &mut cells);
            count += cells.len();
        }
    }
    Ok(FsmiBench {
        n_poses: poses.len(),
        cells_per_beam: count as f64 / (10 * poses.len()) as f64,
        full_us,
        truncated_us,
        noise_free_us,
        julian_points_per_cell: julian.0,
        julian_us: julian_us(julian.0)?,
        julian_max_rel_err: julian.1,
        julian10_us: julian_us(10)?,
        julian100_us: julian_us(100)?,
        truncated_max_rel_err: max_rel_err(&truncated, &full),
        iig_mi_us,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn synthetic_cave_has_walls_and_free_space() {
        let l = synthetic_cave().unwrap();
        let occ = l.probabilities().iter().filter(|&&p| p > 0.5).count();
        assert!(occ > 400 && occ < l.len() / 2, "{occ}");
    }
}
