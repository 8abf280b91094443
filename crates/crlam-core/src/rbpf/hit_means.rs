//! Where in its cell a particle's map saw each wall: the mean of the scan endpoints (hits) that
//! fell in a cell, kept beside a confidence-rich map for the endpoint matcher.
//!
//! GMapping's matcher scores a beam by the distance from its endpoint to the mean of the hits of
//! the nearest occupied cell, not to the cell's centre: walls sit where they were seen, to a
//! fraction of a cell, and a pose shift smaller than a cell changes the score. A CRM holds a pmf
//! of occupancy per cell and no positions, so without these means the matcher's score is flat
//! within a cell and quantized to the grid.
//!
//! Invariant: a cell's entry is `[n, Σ dx, Σ dy]` over the `n` endpoints recorded in it, with
//! (dx, dy) the endpoint's offset (m) from the cell's centre, so the mean offset lies within the
//! cell. A scan records exactly the readings that the CRM update treats as hits (finite, within
//! `[z_min, z_max)`, every `stride`-th beam), so a cell has hits here iff the map was told of a
//! wall in it. The grid shares tiles copy-on-write like the map's, so resampled copies of one
//! particle share them until either is written.

use crate::error::Result;
use crate::grid::{GridGeometry, TiledGrid};
use crate::pose::Pose;

/// Per-cell hit counts and summed endpoint offsets of one particle's map.
#[derive(Clone, Debug)]
pub struct HitMeans {
    grid: TiledGrid<f32>,
}

impl HitMeans {
    /// No hits yet, over the map's `geometry` in tiles of `tile_size` cells.
    pub fn new(geometry: GridGeometry, tile_size: usize) -> Result<Self> {
        Ok(Self {
            grid: TiledGrid::new(geometry, tile_size, &[0.0; 3], None)?,
        })
    }

    /// Records the endpoints of a scan taken with the laser at `sensor`: each `stride`-th reading
    /// that is finite and in `[z_min, z_max)` (the readings the map update marks as hits).
    pub fn record_scan(
        &mut self,
        sensor: Pose,
        angles: &[f64],
        ranges: &[f64],
        z_min: f64,
        z_max: f64,
        stride: usize,
    ) -> Result<()> {
        self.grid.prepare_scan(sensor, z_max)?;
        let g = *self.grid.geometry();
        for (&a, &z) in angles.iter().zip(ranges).step_by(stride.max(1)) {
            if !(z.is_finite() && z > 0.0 && z >= z_min && z < z_max) {
                continue;
            }
            let (s, c) = (sensor[2] + a).sin_cos();
            let e = [sensor[0] + z * c, sensor[1] + z * s];
            let (ix, iy) = g.cell_of(e[0], e[1]);
            let centre = g.cell_center(ix, iy);
            let v = self.grid.get_mut(ix, iy)?;
            v[0] += 1.0;
            v[1] += (e[0] - centre[0]) as f32;
            v[2] += (e[1] - centre[1]) as f32;
        }
        Ok(())
    }

    /// The offset (m) of the mean of the hits in cell (ix, iy) from its centre; zero without hits.
    #[inline]
    pub fn offset(&self, ix: i64, iy: i64) -> [f64; 2] {
        let v = self.grid.get(ix, iy);
        if v[0] <= 0.0 {
            return [0.0; 2];
        }
        [(v[1] / v[0]) as f64, (v[2] / v[0]) as f64]
    }

    /// The number of hits recorded in cell (ix, iy).
    pub fn hits(&self, ix: i64, iy: i64) -> f64 {
        self.grid.get(ix, iy)[0] as f64
    }

    /// The underlying grid (for memory accounting).
    pub fn grid(&self) -> &TiledGrid<f32> {
        &self.grid
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn means() -> HitMeans {
        HitMeans::new(GridGeometry::new([0.0, 0.0], 0.1).unwrap(), 8).unwrap()
    }

    #[test]
    fn the_mean_is_the_mean_offset_of_the_recorded_endpoints() {
        let mut m = means();
        // Endpoints at x = 1.02 and 1.04, y = 0 (cell (10, 0), centre (1.05, 0.05)).
        m.record_scan([0.0, 0.0, 0.0], &[0.0], &[1.02], 0.0, 8.0, 1)
            .unwrap();
        m.record_scan([0.02, 0.0, 0.0], &[0.0], &[1.02], 0.0, 8.0, 1)
            .unwrap();
        assert_eq!(m.hits(10, 0), 2.0);
        let o = m.offset(10, 0);
        assert!((o[0] - -0.02).abs() < 1e-6, "{o:?}");
        assert!((o[1] - -0.05).abs() < 1e-6, "{o:?}");
        assert_eq!(m.offset(9, 0), [0.0, 0.0]);
    }

    #[test]
    fn only_the_readings_the_map_counts_as_hits_are_recorded() {
        let mut m = means();
        let angles = [0.0, 0.5, 1.0, 1.5, 2.0];
        let ranges = [8.0, f64::INFINITY, f64::NAN, 0.05, 2.0];
        m.record_scan([0.0, 0.0, 0.0], &angles, &ranges, 0.1, 8.0, 1)
            .unwrap();
        let g = *m.grid().geometry();
        let (ix, iy) = g.cell_of(2.0 * 2f64.cos(), 2.0 * 2f64.sin());
        assert_eq!(m.hits(ix, iy), 1.0);
        let total: f64 = (-90..90)
            .flat_map(|ix| (-90..90).map(move |iy| (ix, iy)))
            .map(|(ix, iy)| m.hits(ix, iy))
            .sum();
        assert_eq!(total, 1.0);
    }

    #[test]
    fn a_stride_skips_beams_and_copies_share_until_written() {
        let mut m = means();
        m.record_scan([0.0, 0.0, 0.0], &[0.0, 0.0], &[1.0, 1.0], 0.0, 8.0, 2)
            .unwrap();
        assert_eq!(m.hits(10, 0), 1.0);
        let copy = m.clone();
        m.record_scan([0.0, 0.0, 0.0], &[0.0], &[1.0], 0.0, 8.0, 1)
            .unwrap();
        assert_eq!(copy.hits(10, 0), 1.0);
        assert_eq!(m.hits(10, 0), 2.0);
    }

    #[test]
    fn every_mean_lies_within_its_cell() {
        let mut m = means();
        let angles: Vec<f64> = (0..360).map(|i| (i as f64).to_radians()).collect();
        let ranges: Vec<f64> = (0..360).map(|i| 0.5 + 0.013 * i as f64).collect();
        m.record_scan([0.3, -0.2, 0.4], &angles, &ranges, 0.0, 8.0, 1)
            .unwrap();
        for ix in -90..90 {
            for iy in -90..90 {
                let o = m.offset(ix, iy);
                assert!(o[0].abs() <= 0.05 + 1e-6 && o[1].abs() <= 0.05 + 1e-6);
            }
        }
    }
}
