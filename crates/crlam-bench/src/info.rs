//! Benchmark workloads of the information functions (`crlam bench`): 10 beams over 360°, 5 m
//! range, 0.2 m grid, one thread, on a synthetic 20 m × 20 m cave-like world.

use std::time::Instant;

use crlam_core::error::{CrlamError, Result};
use crlam_core::grid::GridGeometry;
use crlam_core::info::crmi::{Crmi, CrmiConfig, CrmiScratch};
use crlam_core::info::fsmi::{Fsmi, FsmiVariant, DEFAULT_TRUNCATION_SIGMAS};
use crlam_core::info::gp::{GpVarianceMap, Gpvr, GpvrOptions, Ugpvr};
use crlam_core::info::iig_mi::IigMi;
use crlam_core::info::lattice::{traverse_lattice, BeamAngles, OccupancyLattice};
use crlam_core::info::prior::crm_from_lattice;
use crlam_core::info::ucrmi::{Ucrmi, UcrmiConfig};
use crlam_core::info::{Candidate, InformationFunction};
use crlam_core::rng::Rng;
use crlam_core::sensor::{SensorModel, SensorModelKind};

/// Microseconds per candidate pose of CRMI with the given configuration.
pub fn crmi_us_per_pose(cfg: CrmiConfig, n_poses: usize) -> Result<f64> {
    let lat = synthetic_cave_lattice()?;
    let map = crm_from_lattice(&lat, 10)?;
    let crmi = Crmi::new(cfg)?;
    let poses = room_poses(n_poses);
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
        crlam_core::grid::GridGeometry::new([-1.1, -1.1], 0.2)?,
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

/// A Cave-like lattice for checks and benchmarks: the planner's 111 × 111 nodes at 0.2 m
/// (−1 … 21 m), prior 0.3, walls 0.85 on the border x, y ∈ {0, 20} and on x, y ∈ {5, 10, 15}
/// with 1.2 m doors at 2.5, 7.5, 12.5 and 17.5 m: sixteen 5 m rooms, so most beams hit.
pub fn synthetic_cave_lattice() -> Result<OccupancyLattice> {
    let (n, res) = (111usize, 0.2);
    let on = |v: f64, c: f64| (v - c).abs() < 0.05;
    let door = |v: f64| [2.5, 7.5, 12.5, 17.5].iter().any(|&d| (v - d).abs() < 0.65);
    let inside = |v: f64| (-0.05..=20.05).contains(&v);
    let wall_at = |v: f64, along: f64| {
        inside(along)
            && (on(v, 0.0)
                || on(v, 20.0)
                || ([5.0, 10.0, 15.0].iter().any(|&c| on(v, c)) && !door(along)))
    };
    let prob = (0..n * n)
        .map(|id| {
            let (x, y) = (-1.0 + res * (id % n) as f64, -1.0 + res * (id / n) as f64);
            if wall_at(x, y) || wall_at(y, x) {
                0.85
            } else {
                0.3
            }
        })
        .collect();
    OccupancyLattice::new(GridGeometry::new([-1.1, -1.1], res)?, n, n, prob)
}

/// Timing of one information function on [`synthetic_cave_lattice`] (one thread, the fastest
/// of three passes over the poses).
#[derive(Clone, Debug, PartialEq)]
pub struct GpBench {
    /// Wall-clock per `evaluate` (µs).
    pub us_per_pose: f64,
    /// Number of poses timed.
    pub poses: usize,
    /// Mean hits per scan.
    pub mean_hits: f64,
    /// Mean test points (hits + free points) per scan.
    pub mean_test_points: f64,
    /// Mean gain (nats) on the prior map.
    pub mean_gain: f64,
}

/// Deterministic poses inside the rooms of [`synthetic_cave_lattice`].
pub fn room_poses(n: usize) -> Vec<[f64; 3]> {
    let offsets = [
        [0.0, 0.0],
        [0.7, -0.4],
        [-0.6, 0.5],
        [0.3, 0.9],
        [-1.1, -0.8],
    ];
    (0..n)
        .map(|i| {
            let room = i % 16;
            let o = offsets[(i / 16) % offsets.len()];
            let x = 2.5 + 5.0 * (room % 4) as f64 + o[0];
            let y = 2.5 + 5.0 * (room / 4) as f64 + o[1];
            [x, y, 0.37 * i as f64]
        })
        .collect()
}

fn bench_with<F: InformationFunction<Map = GpVarianceMap>>(
    f: &F,
    gp: &GpvrOptions,
    belief: &F::Belief,
    n_poses: usize,
) -> Result<GpBench> {
    let map = GpVarianceMap::new(synthetic_cave_lattice()?);
    let poses = room_poses(n_poses.max(1));
    let cand = |p: &[f64; 3]| Candidate {
        pose: *p,
        parent: [p[0] - 1.0, p[1]],
    };
    for p in poses.iter().take(3) {
        f.evaluate(&map, belief, &cand(p), 0)?;
    }
    // The fastest of three passes: the least disturbed by other load on the machine.
    let (mut secs, mut gain) = (f64::INFINITY, 0.0);
    for _ in 0..3 {
        let t = Instant::now();
        gain = 0.0;
        for p in &poses {
            gain += f.evaluate(&map, belief, &cand(p), 0)?.gain;
        }
        secs = secs.min(t.elapsed().as_secs_f64());
    }
    let (mut hits, mut pts) = (0usize, 0usize);
    for p in &poses {
        let s = Gpvr::new(*gp)?.scan_points(&map, *p)?;
        hits += s.n_hits;
        pts += s.test.len();
    }
    let np = poses.len() as f64;
    Ok(GpBench {
        us_per_pose: 1e6 * secs / np,
        poses: poses.len(),
        mean_hits: hits as f64 / np,
        mean_test_points: pts as f64 / np,
        mean_gain: gain / np,
    })
}

/// µs per GPVR evaluation on the Cave-like lattice (10 beams, 5 m, 0.2 m nodes; one thread).
pub fn bench_us_per_pose_gpvr(f: &Gpvr, n_poses: usize) -> Result<GpBench> {
    bench_with(f, f.options(), &(), n_poses)
}

/// µs per UGPVR evaluation (including the 1 m edge propagation) from a depth-3 covariance.
pub fn bench_us_per_pose_ugpvr(f: &Ugpvr, n_poses: usize) -> Result<GpBench> {
    let mut s = crlam_core::info::posecov::root_covariance();
    for k in 0..3 {
        let c = Candidate {
            pose: [k as f64 + 1.0, 0.5 * k as f64, 0.0],
            parent: [k as f64, 0.0],
        };
        s = f.propagate(&s, &c);
    }
    bench_with(f, &f.options().gp, &s, n_poses)
}

/// Microseconds per candidate of UCRMI (100 particles, α = 0.5): each candidate extends a node
/// 1 m away whose root particle set is drawn once.
pub fn ucrmi_us_per_pose(n_poses: usize) -> Result<f64> {
    let lat = synthetic_cave_lattice()?;
    let map = crm_from_lattice(&lat, 10)?;
    let f = Ucrmi::new(UcrmiConfig::new(5.0, 0.2))?;
    let poses = room_poses(n_poses.max(1));
    let roots: Vec<_> = poses
        .iter()
        .enumerate()
        .map(|(i, p)| f.root_belief([p[0] - 1.0, p[1], 0.0], i as u64))
        .collect::<Result<_>>()?;
    let t = Instant::now();
    let mut sink = 0.0;
    for (i, p) in poses.iter().enumerate() {
        let c = Candidate {
            pose: *p,
            parent: [p[0] - 1.0, p[1]],
        };
        sink += f.evaluate(&map, &roots[i], &c, i as u64)?.gain;
    }
    std::hint::black_box(sink);
    Ok(t.elapsed().as_secs_f64() * 1e6 / poses.len() as f64)
}

/// A benchmark result: µs per candidate pose and named details.
pub type InfoFigure = (f64, Vec<(&'static str, f64)>);

/// One named figure of the information benchmarks: µs per candidate pose and details, measured
/// inside a one-thread rayon pool (the functions' inner parallel loops, such as UCRMI's particle
/// likelihoods, run on that one thread too). `None` for an unknown name.
pub fn info_figure(name: &str, size: usize) -> Result<Option<InfoFigure>> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| crlam_core::error::config_err("threads", e.to_string()))?;
    pool.install(|| info_figure_on_this_pool(name, size))
}

fn info_figure_on_this_pool(name: &str, size: usize) -> Result<Option<InfoFigure>> {
    let n = size.max(1);
    Ok(Some(match name {
        "crmi_us_per_pose" => (crmi_us_per_pose(CrmiConfig::new(5.0, 0.2), n)?, vec![]),
        "crmi_mixture_us_per_pose" => {
            let mut c = CrmiConfig::new(5.0, 0.2);
            c.model = SensorModel::with_defaults(SensorModelKind::Mixture, 5.0, 0.2);
            (crmi_us_per_pose(c, n)?, vec![])
        }
        "ucrmi_us_per_pose" => (ucrmi_us_per_pose(n)?, vec![]),
        "fsmi_us_per_pose" | "ogmi_julian_us_per_pose" | "iig_mi_us_per_pose" => {
            let b = bench_fsmi_vs_julian(n, 1)?;
            let details = vec![
                ("full_us", b.full_us),
                ("truncated_us", b.truncated_us),
                ("noise_free_us", b.noise_free_us),
                ("julian_us", b.julian_us),
                ("julian_points_per_cell", b.julian_points_per_cell as f64),
                ("julian_max_rel_err", b.julian_max_rel_err),
                ("truncated_max_rel_err", b.truncated_max_rel_err),
                ("speedup_full_over_julian", b.julian_us / b.full_us),
                (
                    "speedup_truncated_over_julian",
                    b.julian_us / b.truncated_us,
                ),
                (
                    "speedup_noise_free_over_julian",
                    b.julian_us / b.noise_free_us,
                ),
                ("cells_per_beam", b.cells_per_beam),
            ];
            let v = match name {
                "fsmi_us_per_pose" => b.full_us,
                "ogmi_julian_us_per_pose" => b.julian_us,
                _ => b.iig_mi_us,
            };
            (v, details)
        }
        "gpvr_us_per_pose" => {
            let r = bench_us_per_pose_gpvr(&Gpvr::reference(), n)?;
            let c = bench_us_per_pose_gpvr(&Gpvr::clean(), n)?;
            (
                r.us_per_pose,
                vec![
                    ("clean_us", c.us_per_pose),
                    ("mean_test_points", r.mean_test_points),
                ],
            )
        }
        "ugpvr_us_per_pose" => {
            let r = bench_us_per_pose_ugpvr(&Ugpvr::reference(), n)?;
            let c = bench_us_per_pose_ugpvr(&Ugpvr::clean(), (n / 5).max(1))?;
            (
                r.us_per_pose,
                vec![
                    ("clean_us", c.us_per_pose),
                    ("mean_test_points", r.mean_test_points),
                ],
            )
        }
        _ => return Ok(None),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn synthetic_cave_has_walls_and_free_space() {
        let l = synthetic_cave_lattice().unwrap();
        let occ = l.probabilities().iter().filter(|&&p| p > 0.5).count();
        assert!(occ > 400 && occ < l.len() / 2, "{occ}");
    }
}
