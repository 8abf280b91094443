//! Timing of the information functions outside `crlam bench`, for profiling
//! (`cargo run --release -p crlam-bench --example info_timing -- crmi|mixture|ucrmi|likelihood|window|traverse|fsmi|tfsmi|julian`).
use crlam_bench::info::{crmi_us_per_pose, info_figure};
use crlam_core::info::crmi::CrmiConfig;
use crlam_core::sensor::{SensorModel, SensorModelKind};

/// µs per UCRMI-style batch: 100 root particles, one 10-beam virtual scan, one thread.
fn shared_likelihood_us(n_batches: usize, window_only: bool) -> f64 {
    use crlam_bench::info::{room_poses, synthetic_cave_lattice};
    use crlam_core::info::crmi::virtual_scan;
    use crlam_core::info::prior::crm_from_lattice;
    use crlam_core::info::shared_likelihood::SharedMapLikelihood;
    use crlam_core::info::ucrmi::{Ucrmi, UcrmiConfig};
    let map = crm_from_lattice(&synthetic_cave_lattice().unwrap(), 10).unwrap();
    let cfg = UcrmiConfig::new(5.0, 0.2);
    let f = Ucrmi::new(cfg).unwrap();
    let angles: Vec<f64> = (0..10)
        .map(|i| i as f64 * std::f64::consts::TAU / 10.0)
        .collect();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let work: Vec<_> = room_poses(n_batches)
        .into_iter()
        .enumerate()
        .map(|(i, p)| {
            let root = f.root_belief(p, i as u64).unwrap();
            let scan = virtual_scan(&map, p, &angles, 5.0, cfg.crmi.hit_threshold);
            (root.particles, scan.ranges)
        })
        .collect();
    pool.install(|| {
        let t = std::time::Instant::now();
        let mut sink = 0.0;
        for (particles, ranges) in &work {
            let s = SharedMapLikelihood::new(&map, &cfg.weight_model, particles, 1e9).unwrap();
            if window_only {
                sink += s.window_cells() as f64;
                continue;
            }
            sink += s
                .scan_log_likelihoods(particles, &angles, ranges)
                .unwrap()
                .iter()
                .sum::<f64>();
        }
        if window_only {
            eprintln!("mean window cells {:.0}", sink / work.len() as f64);
        }
        std::hint::black_box(sink);
        t.elapsed().as_secs_f64() * 1e6 / work.len() as f64
    })
}

fn main() {
    let which = std::env::args().nth(1).unwrap_or_else(|| "crmi".into());
    let c = CrmiConfig::new(5.0, 0.2);
    match which.as_str() {
        "crmi" => println!(
            "crmi ijrr {:.1} us/pose",
            crmi_us_per_pose(c, 3000).unwrap()
        ),
        "mixture" => {
            let mut m = c;
            m.model = SensorModel::with_defaults(SensorModelKind::Mixture, 5.0, 0.2);
            println!(
                "crmi mixture {:.1} us/pose",
                crmi_us_per_pose(m, 500).unwrap()
            );
        }
        "ucrmi" => {
            // Best of 7 short runs: the VM's timing noise is one-sided.
            let best = (0..7)
                .map(|_| info_figure("ucrmi_us_per_pose", 150).unwrap().unwrap().0)
                .fold(f64::INFINITY, f64::min);
            println!("ucrmi {best:.1} us/pose (one thread, best of 7)")
        }
        "lnrate" => {
            use crlam_core::numeric::fastmath::ln_clamped_slice;
            let xs: Vec<f64> = (0..20_000)
                .map(|i| 0.01 + (i as f64 * 0.618).fract() * 10.0)
                .collect();
            let mut out = vec![0.0; xs.len()];
            let t = std::time::Instant::now();
            for _ in 0..1000 {
                ln_clamped_slice(&xs, &mut out);
                std::hint::black_box(&mut out);
            }
            let ns = t.elapsed().as_secs_f64() * 1e9 / 2e7;
            println!("{ns:.3} ns per log (ln_clamped_slice, contiguous)")
        }
        "traverse" => {
            use crlam_core::grid::{CellRect, GridGeometry};
            let g = GridGeometry::new([0.0, 0.0], 0.2).unwrap();
            let clip = CellRect {
                ix0: 0,
                iy0: 0,
                nx: 111,
                ny: 111,
            };
            let t = std::time::Instant::now();
            let (mut cells, mut acc) = (0usize, 0.0f64);
            for k in 0..100_000 {
                let a = k as f64 * 0.618;
                let o = [5.0 + (k % 97) as f64 * 0.11, 5.0 + (k % 89) as f64 * 0.13];
                crlam_core::raycast::traverse_with(&g, o, a, 5.0, Some(&clip), |c| {
                    cells += 1;
                    acc += c.t_out;
                    true
                });
            }
            let ns = t.elapsed().as_secs_f64() * 1e9;
            std::hint::black_box(acc);
            println!(
                "traverse {:.2} ns/cell, {:.1} cells/ray",
                ns / cells as f64,
                cells as f64 / 1e5
            )
        }
        "window" => {
            let best = (0..7)
                .map(|_| shared_likelihood_us(100, true))
                .fold(f64::INFINITY, f64::min);
            println!("window only {best:.1} us per batch (best of 7)")
        }
        "likelihood" => {
            let best = (0..7)
                .map(|_| shared_likelihood_us(100, false))
                .fold(f64::INFINITY, f64::min);
            println!("particle likelihoods {best:.1} us per 100 particles x 10 beams (best of 7)")
        }
        "fsmi" | "tfsmi" | "julian" => {
            use crlam_bench::info::bench_lattice;
            use crlam_core::info::fsmi::{Fsmi, FsmiVariant, DEFAULT_TRUNCATION_SIGMAS};
            let variant = match which.as_str() {
                "fsmi" => FsmiVariant::Full,
                "tfsmi" => FsmiVariant::Truncated {
                    width_sigmas: DEFAULT_TRUNCATION_SIGMAS,
                },
                _ => FsmiVariant::Julian {
                    points_per_cell: 16,
                },
            };
            let map = bench_lattice(7).unwrap();
            let f = Fsmi::new(variant);
            let poses: Vec<[f64; 3]> = (0..200)
                .map(|i| {
                    let (a, b) = ((i as f64 * 0.618).fract(), (i as f64 * 0.377).fract());
                    [1.0 + a * 18.0, 1.0 + b * 18.0, 0.0]
                })
                .collect();
            let reps = if which == "julian" { 3 } else { 100 };
            let t = std::time::Instant::now();
            let mut sink = 0.0;
            for _ in 0..reps {
                for &p in &poses {
                    sink += f.scan_mi(&map, p).unwrap();
                }
            }
            std::hint::black_box(sink);
            let us = t.elapsed().as_secs_f64() * 1e6 / (reps * poses.len()) as f64;
            println!("{which} {us:.2} us/pose (sum {sink:.6})")
        }
        other => eprintln!(
            "unknown workload {other:?}: crmi, mixture, ucrmi, likelihood, window, traverse, fsmi, tfsmi or julian"
        ),
    }
}
