//! Exact ray casting against a ground-truth occupancy raster, for the simulator.

use crate::error::{CrlamError, Result};
use crate::grid::{check_pose, CellRect, GridGeometry};
use crate::raycast::first_hit;
use rayon::prelude::*;

/// A boolean world raster indexed `[iy][ix]` (iy = 0 at the minimum y).
#[derive(Clone, Debug)]
pub struct WorldRaster<'a> {
    pub geometry: GridGeometry,
    pub nx: usize,
    pub ny: usize,
    pub occupied: &'a [u8],
}

impl<'a> WorldRaster<'a> {
    pub fn new(geometry: GridGeometry, nx: usize, ny: usize, occupied: &'a [u8]) -> Result<Self> {
        if nx == 0 || ny == 0 || occupied.len() != nx * ny {
            return Err(CrlamError::Shape(format!(
                "world raster of {ny} x {nx} cells needs {} values, got {}",
                nx * ny,
                occupied.len()
            )));
        }
        Ok(Self {
            geometry,
            nx,
            ny,
            occupied,
        })
    }

    /// Exact distance along each beam to the entry of the first occupied cell, or +inf when
    /// none lies within `max_range`; 0 if the sensor sits in an occupied cell. Cells outside the
    /// raster are free. `out` is row-major `[pose][beam]`.
    pub fn cast(
        &self,
        poses: &[[f64; 3]],
        angles: &[f64],
        max_range: f64,
        out: &mut [f64],
    ) -> Result<()> {
        if out.len() != poses.len() * angles.len() {
            return Err(CrlamError::Shape("output buffer has the wrong size".into()));
        }
        if !(max_range.is_finite() && max_range > 0.0) {
            return Err(crate::error::config_err(
                "max_range",
                "must be finite and > 0",
            ));
        }
        for p in poses {
            check_pose(*p)?;
        }
        let rect = CellRect {
            ix0: 0,
            iy0: 0,
            nx: self.nx as i64,
            ny: self.ny as i64,
        };
        let nx = self.nx;
        let m = angles.len();
        if m == 0 {
            return Ok(());
        }
        // Each pose fills its own row: the result does not depend on the thread count.
        out.par_chunks_mut(m)
            .zip(poses.par_iter())
            .for_each(|(row, p)| {
                for (j, &a) in angles.iter().enumerate() {
                    let hit = first_hit(
                        &self.geometry,
                        [p[0], p[1]],
                        p[2] + a,
                        max_range,
                        Some(&rect),
                        |ix, iy| self.occupied[iy as usize * nx + ix as usize] != 0,
                    );
                    row[j] = hit.unwrap_or(f64::INFINITY);
                }
            });
        Ok(())
    }
}
