//! Micro-benchmarks behind `crlam bench`: fixed workloads timed in-process, single thread.

use std::time::Instant;

use crate::crm::{CrmConfig, CrmMap, CrmScratch, ScanOptions};
use crate::error::Result;
use crate::grid::GridGeometry;
use crate::raycast::traverse_with;
use crate::sensor::{SensorModel, SensorModelKind};

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
}

/// The paper's LIDAR: 1079 beams over 270°.
pub fn paper_angles() -> Vec<f64> {
    let fov = 270f64.to_radians();
    (0..1079)
        .map(|i| -fov / 2.0 + fov * i as f64 / 1078.0)
        .collect()
}

/// Ranges of the CRM workload: every third beam a no-return, the rest hits near z_max, so rays
/// span about 40 cells of 0.2 m (z_max = 8 m).
fn workload_ranges(n: usize, step: usize) -> Vec<f64> {
    (0..n)
        .map(|i| {
            if (i + step).is_multiple_of(3) {
                f64::INFINITY
            } else {
                7.3 + 0.4 * (((i * 7 + step) % 11) as f64 / 10.0)
            }
        })
        .collect()
}

/// CRM beam updates per second: `ijrr`, K = 10, batch mode, 0.2 m grid, 8 m rays, one thread.
pub fn crm_beam_updates(n_scans: usize) -> Result<BenchFigure> {
    let g = GridGeometry::new([0.0, 0.0], 0.2)?;
    let mut map = CrmMap::new(&CrmConfig::new(g))?;
    let model = SensorModel::with_defaults(SensorModelKind::Ijrr, 8.0, 0.2);
    let angles = paper_angles();
    let opts = ScanOptions::default();
    let mut sc = CrmScratch::default();
    let scans: Vec<Vec<f64>> = (0..n_scans)
        .map(|s| workload_ranges(angles.len(), s))
        .collect();
    let mut cells = 0u64;
    for (s, r) in scans.iter().enumerate().take(3) {
        let p = [0.05 * s as f64, 0.0, 0.0];
        map.update_scan(p, &angles, r, &model, &opts, &mut sc)?;
    }
    let t = Instant::now();
    for (s, r) in scans.iter().enumerate() {
        let p = [
            0.05 * (s % 40) as f64,
            0.03 * (s % 17) as f64,
            0.01 * s as f64,
        ];
        let st = map.update_scan(p, &angles, r, &model, &opts, &mut sc)?;
        cells += st.n_cell_updates as u64;
    }
    let secs = t.elapsed().as_secs_f64();
    let ops = (n_scans * angles.len()) as u64;
    Ok(BenchFigure {
        name: "crm_beam_updates_per_s",
        per_second: ops as f64 / secs,
        operations: ops,
        seconds: secs,
        unit: "beam update (ijrr, K=10, batch, 0.2 m cells, 8 m rays)",
        cells_per_ray: cells as f64 / ops as f64,
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
    })
}
