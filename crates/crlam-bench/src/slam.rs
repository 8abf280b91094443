//! Micro-benchmarks behind `crlam bench`: fixed workloads timed in-process, single thread.

use std::time::Instant;

use crlam_core::crm::{BatchKernel, CrmConfig, CrmMap, CrmScratch, ScanOptions};
use crlam_core::error::Result;
use crlam_core::grid::GridGeometry;
use crlam_core::raycast::traverse_with;
use crlam_core::sensor::{SensorModel, SensorModelKind};

/// One measured figure.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchFigure {
    pub name: &'static str,
    /// Operations per second.
    pub per_second: f64,
    pub operations: u64,
    pub seconds: f64,
    /// Workload description (what one operation is).
    pub unit: &'static str,
    /// Mean cells per ray in the workload.
    pub cells_per_ray: f64,
    /// CPU time of the timing thread over the timed part (s), where the system reports it
    /// (Linux: `/proc/thread-self/schedstat`), else NaN. On a loaded machine the wall time
    /// `seconds` also counts the time the thread waited for a core; this does not.
    pub cpu_seconds: f64,
}

/// CPU time (s) the calling thread has run, from `/proc/thread-self/schedstat` (Linux); None
/// elsewhere.
pub fn thread_cpu_seconds() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: f64 = text.split_whitespace().next()?.parse().ok()?;
    Some(ns * 1e-9)
}

/// The paper's LIDAR: 1079 beams over 270°.
pub fn paper_angles() -> Vec<f64> {
    let fov = 270f64.to_radians();
    (0..1079)
        .map(|i| -fov / 2.0 + fov * i as f64 / 1078.0)
        .collect()
}

/// Which beams the CRM workload reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CrmWorkload {
    /// Every beam a hit placed so that its traversed ray (z + 6σ + Δ under `ijrr`) spans 40
    /// cells of 0.2 m whatever its bearing: the "40-cell rays".
    FortyCellHits,
    /// The paper's scan as the museum run sees it: two thirds hits at 7.3–7.7 m, one third
    /// no-returns (8 m rays; diagonal rays cross up to 57 cells).
    PaperScan,
}

fn workload_ranges(
    kind: CrmWorkload,
    model: &SensorModel,
    pose: [f64; 3],
    angles: &[f64],
    step: usize,
) -> Vec<f64> {
    angles
        .iter()
        .enumerate()
        .map(|(i, a)| match kind {
            CrmWorkload::FortyCellHits => {
                let phi = pose[2] + a;
                // A ray of length L crosses about L (|cos φ| + |sin φ|) / Δ cells.
                let len = 40.0 * 0.2 / (phi.cos().abs() + phi.sin().abs());
                len - 6.0 * model.sigma_hit - 0.2
            }
            CrmWorkload::PaperScan => {
                if (i + step).is_multiple_of(3) {
                    f64::INFINITY
                } else {
                    7.3 + 0.4 * (((i * 7 + step) % 11) as f64 / 10.0)
                }
            }
        })
        .collect()
}

/// CRM beam updates per second: `ijrr`, K = 10, batch mode, 0.2 m grid, z_max = 8 m, the
/// paper's 1079-beam scan, one thread.
pub fn crm_beam_updates(n_scans: usize, kind: CrmWorkload) -> Result<BenchFigure> {
    let g = GridGeometry::new([0.0, 0.0], 0.2)?;
    let mut map = CrmMap::new(&CrmConfig::new(g))?;
    let model = SensorModel::with_defaults(SensorModelKind::Ijrr, 8.0, 0.2);
    let angles = paper_angles();
    let opts = ScanOptions::default();
    let mut sc = CrmScratch::default();
    let pose = |s: usize| {
        [
            0.05 * (s % 40) as f64,
            0.03 * (s % 17) as f64,
            0.01 * s as f64,
        ]
    };
    let scans: Vec<Vec<f64>> = (0..n_scans)
        .map(|s| workload_ranges(kind, &model, pose(s), &angles, s))
        .collect();
    // Warm-up: the first scans allocate the tiles.
    for (s, r) in scans.iter().enumerate().take(3) {
        map.update_scan(pose(s), &angles, r, &model, &opts, &mut sc)?;
    }
    let mut cells = 0u64;
    let t = Instant::now();
    for (s, r) in scans.iter().enumerate() {
        let st = map.update_scan(pose(s), &angles, r, &model, &opts, &mut sc)?;
        cells += st.n_cell_updates as u64;
    }
    let secs = t.elapsed().as_secs_f64();
    let ops = (n_scans * angles.len()) as u64;
    let (name, unit) = match kind {
        CrmWorkload::FortyCellHits => (
            "crm_beam_updates_per_s",
            "beam update (ijrr, K=10, batch, 0.2 m cells, 40-cell rays)",
        ),
        CrmWorkload::PaperScan => (
            "crm_beam_updates_per_s_paper_scan",
            "beam update (ijrr, K=10, batch, 0.2 m cells, 8 m rays, 1/3 no-returns)",
        ),
    };
    Ok(BenchFigure {
        name,
        per_second: ops as f64 / secs,
        operations: ops,
        seconds: secs,
        unit,
        cells_per_ray: cells as f64 / ops as f64,
        cpu_seconds: f64::NAN,
    })
}

/// Cells traversed per second by the exact traversal alone (8 m rays, 0.2 m grid).
pub fn raycast_cells(n_rays: usize) -> Result<BenchFigure> {
    let g = GridGeometry::new([0.0, 0.0], 0.2)?;
    let angles = paper_angles();
    let mut cells = 0u64;
    let mut checksum = 0.0;
    let t = Instant::now();
    for i in 0..n_rays {
        let a = angles[i % angles.len()] + 1e-3 * (i / angles.len()) as f64;
        let o = [0.013 * (i % 13) as f64, 0.007 * (i % 29) as f64];
        traverse_with(&g, o, a, 8.0, None, |c| {
            cells += 1;
            checksum += c.t_out;
            true
        });
    }
    let secs = t.elapsed().as_secs_f64();
    std::hint::black_box(checksum);
    Ok(BenchFigure {
        name: "raycast_cells_per_s",
        per_second: cells as f64 / secs,
        operations: cells,
        seconds: secs,
        unit: "cell visited (Amanatides-Woo, 8 m rays, 0.2 m cells)",
        cells_per_ray: cells as f64 / n_rays as f64,
        cpu_seconds: f64::NAN,
    })
}

/// A 20 m x 20 m room with pillars and a loop through it: exact scans for the filter benchmarks.
pub(crate) struct FilterWorkload {
    pub(crate) odom: Vec<crlam_core::pose::Pose>,
    pub(crate) angles: Vec<f64>,
    pub(crate) ranges: Vec<Vec<f64>>,
}

pub(crate) fn filter_workload(
    n_scans: usize,
    n_beams: usize,
    fov_deg: f64,
    z_max: f64,
) -> Result<FilterWorkload> {
    use crlam_core::sim::WorldRaster;
    let n = 400; // 0.05 m cells
    let mut occ = vec![0u8; n * n];
    for i in 0..n {
        for t in 0..4 {
            occ[t * n + i] = 1;
            occ[(n - 1 - t) * n + i] = 1;
            occ[i * n + t] = 1;
            occ[i * n + n - 1 - t] = 1;
        }
    }
    for (cx, cy) in [(100, 100), (300, 100), (100, 300), (300, 300), (200, 200)] {
        for y in cy - 15..cy + 15 {
            for x in cx - 15..cx + 15 {
                occ[y * n + x] = 1;
            }
        }
    }
    let world = WorldRaster::new(GridGeometry::new([0.0, 0.0], 0.05)?, n, n, &occ)?;
    let fov = fov_deg.to_radians();
    let angles: Vec<f64> = (0..n_beams)
        .map(|i| -fov / 2.0 + fov * i as f64 / (n_beams - 1) as f64)
        .collect();
    let odom: Vec<crlam_core::pose::Pose> = (0..n_scans)
        .map(|k| {
            let a = k as f64 * 0.01;
            [
                10.0 + 5.0 * a.cos(),
                10.0 + 5.0 * a.sin(),
                a + std::f64::consts::FRAC_PI_2,
            ]
        })
        .collect();
    let mut flat = vec![0.0; n_scans * n_beams];
    world.cast(&odom, &angles, z_max, &mut flat)?;
    let ranges = flat.chunks(n_beams).map(|c| c.to_vec()).collect();
    Ok(FilterWorkload {
        odom,
        angles,
        ranges,
    })
}

/// Seconds to feed scans 1..=n of a workload (after scan 0) to `process`, on one thread.
fn time_filter<F>(w: &FilterWorkload, n_scans: usize, process: F) -> Result<f64>
where
    F: FnMut(&crlam_core::rbpf::ScanInput) -> Result<crlam_core::rbpf::FilterStep> + Send,
{
    Ok(time_filter_cpu(w, n_scans, process)?.0)
}

/// [`time_filter`]'s wall time and the timing thread's CPU time (NaN where not reported).
pub(crate) fn time_filter_cpu<F>(
    w: &FilterWorkload,
    n_scans: usize,
    mut process: F,
) -> Result<(f64, f64)>
where
    F: FnMut(&crlam_core::rbpf::ScanInput) -> Result<crlam_core::rbpf::FilterStep> + Send,
{
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| crlam_core::error::config_err("threads", e.to_string()))?;
    let scan = |k: usize| crlam_core::rbpf::ScanInput {
        odom: w.odom[k],
        angles: &w.angles,
        ranges: &w.ranges[k],
        laser_offset: [0.0; 3],
    };
    pool.install(|| process(&scan(0)))?;
    let cpu0 = pool.install(thread_cpu_seconds);
    let t = Instant::now();
    for k in 1..=n_scans {
        pool.install(|| process(&scan(k)))?;
    }
    let wall = t.elapsed().as_secs_f64();
    let cpu = match (cpu0, pool.install(thread_cpu_seconds)) {
        (Some(a), Some(b)) => b - a,
        _ => f64::NAN,
    };
    Ok((wall, cpu))
}

pub(crate) fn filter_figure(
    name: &'static str,
    unit: &'static str,
    n_scans: usize,
    secs: f64,
) -> BenchFigure {
    BenchFigure {
        name,
        per_second: n_scans as f64 / secs,
        operations: n_scans as u64,
        seconds: secs,
        unit,
        cells_per_ray: f64::NAN,
        cpu_seconds: f64::NAN,
    }
}

/// Seconds RBPF-CLAM takes for `n_scans` of the filter workload (1079 beams over 270°, otherwise
/// over 180°; 8 m, 0.2 m grid, one thread), with the paper's settings changed by `adjust`.
fn time_clam(
    n_scans: usize,
    n_particles: usize,
    n_beams: usize,
    adjust: impl FnOnce(&mut crlam_core::rbpf::ClamConfig),
) -> Result<f64> {
    use crlam_core::rbpf::{ClamConfig, RbpfClam};
    let fov = if n_beams == 1079 { 270.0 } else { 180.0 };
    let w = filter_workload(n_scans + 1, n_beams, fov, 8.0)?;
    let mut cfg = ClamConfig::paper(CrmConfig::new(GridGeometry::new([0.0, 0.0], 0.2)?), 8.0);
    cfg.n_particles = n_particles;
    adjust(&mut cfg);
    let mut f = RbpfClam::new(cfg, w.odom[0])?;
    time_filter(&w, n_scans, |s| f.process(s))
}

/// RBPF-CLAM scans per second on one thread (paper settings: every beam, odometry proposal).
pub fn rbpf_clam_scans(n_scans: usize, n_particles: usize, n_beams: usize) -> Result<BenchFigure> {
    rbpf_clam_scans_with(n_scans, n_particles, n_beams, BatchKernel::Windowed)
}

/// [`rbpf_clam_scans`] with a given batch kernel (the full sweep is the same run's baseline).
pub fn rbpf_clam_scans_with(
    n_scans: usize,
    n_particles: usize,
    n_beams: usize,
    kernel: BatchKernel,
) -> Result<BenchFigure> {
    let secs = time_clam(n_scans, n_particles, n_beams, |cfg| {
        cfg.batch_kernel = kernel
    })?;
    let name = match (n_beams, n_particles, kernel) {
        (1079, 100, BatchKernel::Windowed) => "rbpf_clam_scans_per_s_1079x100",
        (1079, 100, BatchKernel::FullRay) => "rbpf_clam_scans_per_s_1079x100_full_ray",
        (180, 30, _) => "rbpf_clam_scans_per_s_180x30",
        _ => "rbpf_clam_scans_per_s",
    };
    Ok(filter_figure(
        name,
        "processed scan (all particles: weight + map update; 0.2 m grid, 8 m, one thread)",
        n_scans,
        secs,
    ))
}

/// RBPF-CLAM with the likelihood-mode proposal (hill climb on every third beam, 3×3×3 lattice and
/// weights on every beam) on [`rbpf_clam_scans`]'s workload: 0.2 m grid, 8 m, one thread.
pub fn rbpf_clam_likelihood_mode_scans(
    n_scans: usize,
    n_particles: usize,
    n_beams: usize,
) -> Result<BenchFigure> {
    use crlam_core::rbpf::ClamProposal;
    let secs = time_clam(n_scans, n_particles, n_beams, |cfg| {
        cfg.proposal = ClamProposal::likelihood_mode()
    })?;
    let name = match (n_beams, n_particles) {
        (1079, 100) => "rbpf_clam_likelihood_mode_scans_per_s_1079x100",
        _ => "rbpf_clam_likelihood_mode_scans_per_s",
    };
    Ok(filter_figure(
        name,
        "processed scan (all particles: hill climb, lattice, weight, map update; 0.2 m grid, 8 m, one thread)",
        n_scans,
        secs,
    ))
}

/// RBPF-CLAM as the `robust` preset runs it (the scan-match proposal, 0.1 m grid, 8 m, map
/// updates that keep the scan's hits first, Thrun's odometry model, tempering 40) on the 180-beam filter workload, every
/// scan processed, one thread: the figure to set beside `rbpf_ogm_gmapping_scans_per_s_180x30`.
pub fn rbpf_clam_scan_match_scans(n_scans: usize, n_particles: usize) -> Result<BenchFigure> {
    use crlam_core::motion::MotionModel;
    use crlam_core::rbpf::{ClamConfig, ClamProposal, ScanMatchSettings};
    let preset = ClamConfig::paper(CrmConfig::new(GridGeometry::new([0.0, 0.0], 0.1)?), 8.0);
    let secs = time_clam(n_scans, n_particles, 180, |cfg| {
        *cfg = ClamConfig {
            n_particles: cfg.n_particles,
            ..preset
        };
        cfg.motion = MotionModel::Thrun {
            alpha: [0.1, 0.1, 0.002, 0.1],
        };
        cfg.tempering = 40.0;
        cfg.hits_first = true;
        cfg.proposal = ClamProposal::ScanMatch(ScanMatchSettings::default());
    })?;
    let name = match n_particles {
        30 => "rbpf_clam_scan_match_scans_per_s_180x30",
        _ => "rbpf_clam_scan_match_scans_per_s",
    };
    Ok(filter_figure(
        name,
        "processed scan (all particles: endpoint climb and lattice, one CRM weight, map update; 0.1 m grid, 8 m, one thread)",
        n_scans,
        secs,
    ))
}

/// RBPF-OGM (GMapping-style) scans per second on one thread, 180 beams over 180°, 0.05 m grid.
pub fn rbpf_ogm_scans(n_scans: usize, n_particles: usize) -> Result<BenchFigure> {
    use crlam_core::rbpf::{OgmFilterConfig, RbpfOgm};
    let w = filter_workload(n_scans + 1, 180, 180.0, 8.0)?;
    let mut f = RbpfOgm::new(
        OgmFilterConfig {
            n_particles,
            ..OgmFilterConfig::default()
        },
        w.odom[0],
    )?;
    let secs = time_filter(&w, n_scans, |s| f.process(s))?;
    let unit = "processed scan (all particles: scan matching, improved proposal, map update; 0.05 m grid, one thread)";
    Ok(filter_figure(
        "rbpf_ogm_scans_per_s_180x30",
        unit,
        n_scans,
        secs,
    ))
}

/// [`rbpf_ogm_scans`] with GMapping's cells in full (hit rate, not-occupied test, hit means:
/// [`crlam_core::rbpf::OgmFilterConfig::with_gmapping_map`]), its odometry model drawn per scan.
pub fn rbpf_ogm_gmapping_scans(n_scans: usize, n_particles: usize) -> Result<BenchFigure> {
    use crlam_core::motion::MotionModel;
    use crlam_core::rbpf::{MotionDraws, OgmFilterConfig, RbpfOgm};
    let w = filter_workload(n_scans + 1, 180, 180.0, 8.0)?;
    let cfg = OgmFilterConfig {
        n_particles,
        motion: MotionModel::gmapping(),
        motion_draws: MotionDraws::PerScan,
        ..OgmFilterConfig::default()
    }
    .with_gmapping_map(0.1)?;
    let mut f = RbpfOgm::new(cfg, w.odom[0])?;
    let secs = time_filter(&w, n_scans, |s| f.process(s))?;
    let unit = "processed scan (as rbpf_ogm_scans_per_s_180x30, with GMapping's cells: hit rate and hit means)";
    Ok(filter_figure(
        "rbpf_ogm_gmapping_scans_per_s_180x30",
        unit,
        n_scans,
        secs,
    ))
}

/// RBPF-OGM in the Table I setting: 100 particles, 1079 beams over 270°, 8 m, 0.2 m grid, one
/// thread (the same workload as [`rbpf_clam_scans`] with 1079 beams).
pub fn rbpf_ogm_scans_table1(n_scans: usize) -> Result<BenchFigure> {
    use crlam_core::rbpf::{OgmFilterConfig, RbpfOgm};
    let w = filter_workload(n_scans + 1, 1079, 270.0, 8.0)?;
    let defaults = OgmFilterConfig::default();
    let mut f = RbpfOgm::new(
        OgmFilterConfig {
            n_particles: 100,
            geometry: GridGeometry::new(defaults.geometry.origin, 0.2)?,
            ..defaults
        },
        w.odom[0],
    )?;
    let secs = time_filter(&w, n_scans, |s| f.process(s))?;
    let unit = "processed scan (all particles: scan matching, improved proposal, map update; 0.2 m grid, 8 m, one thread)";
    Ok(filter_figure(
        "rbpf_ogm_scans_per_s_1079x100",
        unit,
        n_scans,
        secs,
    ))
}
