//! Baseline log-odds occupancy grid (standard inverse sensor model with clamping), on the same
//! tiled storage and traversal as the CRM.

use crate::error::{config_err, CrlamError, Result};
use crate::grid::{CellRect, GridGeometry, TileStats, TiledGrid};
use crate::raycast::traverse_with;

/// Parameters of the inverse sensor model. Log-odds are in base `base` (2 in the authors' code).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogOddsParams {
    /// Increment for the cell holding the reading's endpoint.
    pub l_occ: f64,
    /// Increment (negative) for cells the beam passed.
    pub l_free: f64,
    /// Clamp bounds.
    pub l_min: f64,
    pub l_max: f64,
    /// Logarithm base of the values (probability = base^l / (1 + base^l)).
    pub base: f64,
    /// Readings at or beyond this (m) are no-returns.
    pub z_max: f64,
    /// Clear free space along no-return beams up to z_max.
    pub clear_no_return: bool,
    /// Also keep, per cell, the number of hits and the sum of their offsets from the cell centre
    /// (GMapping's `PointAccumulator`), so that the scan matcher measures a beam's distance to
    /// the mean of the hits rather than to the cell centre. Four values per cell instead of one.
    pub hit_means: bool,
}

impl LogOddsParams {
    /// crm-spec 9 (R1's display map): +1, −0.5, ±100, base 2.
    pub fn new(z_max: f64) -> Self {
        Self {
            l_occ: 1.0,
            l_free: -0.5,
            l_min: -100.0,
            l_max: 100.0,
            base: 2.0,
            z_max,
            clear_no_return: true,
            hit_means: false,
        }
    }

    /// GMapping's counting map (its `PointAccumulator`) as log-odds: a cell is occupied when
    /// its hit rate n / (n + f) (n hits, f pass-throughs) exceeds `fullness_threshold` t
    /// (GMapping's fullnessThreshold, 0.1). With l_occ = 1/t − 1 and l_free = −1 the value is
    /// n·(1 − t)/t − f, positive exactly when n / (n + f) > t; the wide clamps (±10⁶, with unit
    /// steps exact in f32) never bind in practice, so nothing is forgotten, as in GMapping.
    /// Base 2 only shapes [`LogOddsGrid::probability`], which is then a sharp display value
    /// rather than the hit rate.
    pub fn hit_rate(z_max: f64, fullness_threshold: f64) -> Result<Self> {
        if !(fullness_threshold > 0.0 && fullness_threshold < 1.0) {
            return Err(config_err(
                "fullness_threshold",
                format!("must be in (0, 1), got {fullness_threshold}"),
            ));
        }
        let p = Self {
            l_occ: 1.0 / fullness_threshold - 1.0,
            l_free: -1.0,
            l_min: -1e6,
            l_max: 1e6,
            base: 2.0,
            z_max,
            clear_no_return: true,
            hit_means: false,
        };
        p.validate()?;
        Ok(p)
    }

    pub fn validate(&self) -> Result<()> {
        if !(self.l_occ.is_finite() && self.l_occ > 0.0) {
            return Err(config_err("l_occ", "must be finite and > 0"));
        }
        if !(self.l_free.is_finite() && self.l_free < 0.0) {
            return Err(config_err("l_free", "must be finite and < 0"));
        }
        if !(self.l_min < 0.0
            && self.l_max > 0.0
            && self.l_min.is_finite()
            && self.l_max.is_finite())
        {
            return Err(config_err("clamp", "need finite l_min < 0 < l_max"));
        }
        if !(self.base.is_finite() && self.base > 1.0) {
            return Err(config_err("base", "must be > 1"));
        }
        if !(self.z_max.is_finite() && self.z_max > 0.0) {
            return Err(config_err("z_max", "must be finite and > 0"));
        }
        Ok(())
    }
}

/// The offset (m) of the mean of the hits from the cell centre, from a cell's stored values
/// (`[log-odds]`, or `[log-odds, hits, Σ dx, Σ dy]` with [`LogOddsParams::hit_means`]); zero
/// without hits or means.
#[inline]
pub(crate) fn hit_mean_of(cell: &[f32]) -> [f64; 2] {
    if cell.len() < 4 || cell[1] <= 0.0 {
        return [0.0; 2];
    }
    [(cell[2] / cell[1]) as f64, (cell[3] / cell[1]) as f64]
}

/// A log-odds occupancy grid; cloning shares tiles copy-on-write.
#[derive(Clone, Debug)]
pub struct LogOddsGrid {
    grid: TiledGrid<f32>,
    params: LogOddsParams,
}

impl LogOddsGrid {
    pub fn new(
        geometry: GridGeometry,
        params: LogOddsParams,
        tile_size: usize,
        extent: Option<CellRect>,
    ) -> Result<Self> {
        params.validate()?;
        let fill: &[f32] = if params.hit_means { &[0.0; 4] } else { &[0.0] };
        Ok(Self {
            grid: TiledGrid::new(geometry, tile_size, fill, extent)?,
            params,
        })
    }

    pub fn params(&self) -> &LogOddsParams {
        &self.params
    }

    pub fn grid(&self) -> &TiledGrid<f32> {
        &self.grid
    }

    pub fn tile_stats(&self) -> TileStats {
        self.grid.tile_stats()
    }

    /// Log-odds of a cell.
    pub fn log_odds(&self, ix: i64, iy: i64) -> f64 {
        self.grid.get(ix, iy)[0] as f64
    }

    /// Offset (m) of the mean of the hits in a cell from its centre; zero without hits or when
    /// the grid keeps no hit means.
    #[inline]
    pub fn hit_mean_offset(&self, ix: i64, iy: i64) -> [f64; 2] {
        hit_mean_of(self.grid.get(ix, iy))
    }

    /// Occupancy probability of a cell.
    pub fn probability(&self, ix: i64, iy: i64) -> f64 {
        let l = self.log_odds(ix, iy);
        1.0 / (1.0 + self.params.base.powf(-l))
    }

    fn add(&mut self, ix: i64, iy: i64, delta: f64) -> Result<()> {
        let (lo, hi) = (self.params.l_min as f32, self.params.l_max as f32);
        let v = self.grid.get_mut(ix, iy)?;
        v[0] = (v[0] + delta as f32).clamp(lo, hi);
        Ok(())
    }

    /// Integrates one scan from sensor pose (x, y, θ). Returns (beams used, beams dropped).
    pub fn update_scan(
        &mut self,
        pose: [f64; 3],
        angles: &[f64],
        ranges: &[f64],
    ) -> Result<(usize, usize)> {
        if angles.len() != ranges.len() {
            return Err(CrlamError::Shape(format!(
                "{} angles but {} ranges",
                angles.len(),
                ranges.len()
            )));
        }
        self.grid.prepare_scan(pose, self.params.z_max)?;
        let g = *self.grid.geometry();
        let ext = self.grid.fixed_extent();
        let (mut used, mut dropped) = (0, 0);
        let mut cells = Vec::new();
        for (&a, &z) in angles.iter().zip(ranges) {
            let no_return = !(z.is_finite() && z < self.params.z_max);
            if !no_return && z <= 0.0 {
                dropped += 1;
                continue;
            }
            if no_return && !self.params.clear_no_return {
                dropped += 1;
                continue;
            }
            let length = if no_return { self.params.z_max } else { z };
            cells.clear();
            let end = traverse_with(
                &g,
                [pose[0], pose[1]],
                pose[2] + a,
                length,
                ext.as_ref(),
                |c| {
                    cells.push((c.ix, c.iy));
                    true
                },
            );
            let hit_inside = !no_return && end + 1e-9 >= z;
            let n = cells.len();
            if hit_inside && self.params.hit_means {
                if let Some(&(ix, iy)) = cells.last() {
                    let c = g.cell_center(ix, iy);
                    let (s, co) = (pose[2] + a).sin_cos();
                    let offset = [pose[0] + z * co - c[0], pose[1] + z * s - c[1]];
                    let v = self.grid.get_mut(ix, iy)?;
                    v[1] += 1.0;
                    v[2] += offset[0] as f32;
                    v[3] += offset[1] as f32;
                }
            }
            for (i, &(ix, iy)) in cells.iter().enumerate() {
                let occ = hit_inside && i + 1 == n;
                self.add(
                    ix,
                    iy,
                    if occ {
                        self.params.l_occ
                    } else {
                        self.params.l_free
                    },
                )?;
            }
            used += 1;
        }
        Ok((used, dropped))
    }

    /// Log-odds over `rect`, row-major `[iy][ix]` (the hit means, if kept, are not exported).
    pub fn export(&self, rect: CellRect) -> Result<Vec<f32>> {
        let stride = self.grid.stride();
        let all = self.grid.export(rect)?;
        if stride == 1 {
            return Ok(all);
        }
        Ok(all.chunks_exact(stride).map(|c| c[0]).collect())
    }

    /// Replaces the log-odds over `rect` (hit means, if kept, are left as they are).
    pub fn import(&mut self, rect: CellRect, values: &[f32]) -> Result<()> {
        let stride = self.grid.stride();
        if stride == 1 {
            return self.grid.import(rect, values);
        }
        if values.len() != rect.n_cells() {
            return Err(CrlamError::Shape(format!(
                "expected {} values for {} cells, got {}",
                rect.n_cells(),
                rect.n_cells(),
                values.len()
            )));
        }
        self.grid.reserve(rect)?;
        let mut k = 0;
        for iy in rect.iy0..rect.iy0 + rect.ny {
            for ix in rect.ix0..rect.ix0 + rect.nx {
                self.grid.get_mut(ix, iy)?[0] = values[k];
                k += 1;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_beam_clears_free_cells_and_marks_the_hit() {
        let g = GridGeometry::new([0.0, 0.0], 0.1).unwrap();
        let mut m = LogOddsGrid::new(g, LogOddsParams::new(8.0), 32, None).unwrap();
        m.update_scan([0.05, 0.05, 0.0], &[0.0], &[1.0]).unwrap();
        assert!(m.log_odds(0, 0) < 0.0);
        assert!(m.log_odds(9, 0) < 0.0);
        assert!(m.probability(10, 0) > 0.5);
        assert_eq!(m.log_odds(11, 0), 0.0);
    }

    #[test]
    fn hit_rate_cells_are_occupied_above_the_fullness_threshold() {
        let g = GridGeometry::new([0.0, 0.0], 0.1).unwrap();
        let p = LogOddsParams::hit_rate(8.0, 0.1).unwrap();
        assert_eq!((p.l_occ, p.l_free), (9.0, -1.0));
        // Cell 5 along +x: hit by `hits` short beams, passed by `passes` long ones. It is
        // occupied exactly when hits / (hits + passes) > 0.1.
        for (hits, passes) in [(1, 8), (1, 9), (1, 10), (2, 17), (2, 18), (3, 40)] {
            let mut m = LogOddsGrid::new(g, p, 32, None).unwrap();
            for _ in 0..hits {
                m.update_scan([0.05, 0.05, 0.0], &[0.0], &[0.55]).unwrap();
            }
            for _ in 0..passes {
                m.update_scan([0.05, 0.05, 0.0], &[0.0], &[2.0]).unwrap();
            }
            let rate = hits as f64 / (hits + passes) as f64;
            assert_eq!(
                m.log_odds(5, 0) > 0.0,
                rate > 0.1,
                "{hits} hits, {passes} passes"
            );
        }
        assert!(LogOddsParams::hit_rate(8.0, 0.0).is_err());
        assert!(LogOddsParams::hit_rate(8.0, 1.0).is_err());
    }

    #[test]
    fn hit_means_are_the_mean_offset_of_the_endpoints() {
        let g = GridGeometry::new([0.0, 0.0], 0.1).unwrap();
        let mut p = LogOddsParams::hit_rate(8.0, 0.1).unwrap();
        p.hit_means = true;
        let mut m = LogOddsGrid::new(g, p, 32, None).unwrap();
        // Two hits in cell (5, 0) (centre 0.55, 0.05): at x = 0.52 and x = 0.58 + 0.01 up.
        m.update_scan([0.0, 0.05, 0.0], &[0.0], &[0.52]).unwrap();
        m.update_scan([0.0, 0.06, 0.0], &[0.0], &[0.58]).unwrap();
        let o = m.hit_mean_offset(5, 0);
        assert!(
            (o[0] - 0.0).abs() < 1e-6 && (o[1] - 0.005).abs() < 1e-6,
            "{o:?}"
        );
        assert_eq!(m.hit_mean_offset(4, 0), [0.0, 0.0]);
        // Export and import see the log-odds alone; import leaves the means.
        let r = CellRect {
            ix0: 3,
            iy0: 0,
            nx: 3,
            ny: 1,
        };
        let lo = m.export(r).unwrap();
        assert_eq!(lo, vec![-2.0, -2.0, 18.0]);
        m.import(r, &[1.0, 2.0, 3.0]).unwrap();
        assert_eq!(m.export(r).unwrap(), vec![1.0, 2.0, 3.0]);
        assert_eq!(m.hit_mean_offset(5, 0), o);
        assert!(m.import(r, &[1.0]).is_err());
        // Without the option a grid keeps one value per cell and reports no offsets.
        let plain = LogOddsGrid::new(g, LogOddsParams::new(8.0), 32, None).unwrap();
        assert_eq!(plain.grid().stride(), 1);
        assert_eq!(m.grid().stride(), 4);
    }

    #[test]
    fn clamps() {
        let g = GridGeometry::new([0.0, 0.0], 0.1).unwrap();
        let mut p = LogOddsParams::new(8.0);
        p.l_max = 2.5;
        let mut m = LogOddsGrid::new(g, p, 32, None).unwrap();
        for _ in 0..10 {
            m.update_scan([0.05, 0.05, 0.0], &[0.0], &[1.0]).unwrap();
        }
        assert_eq!(m.log_odds(10, 0), 2.5);
    }
}
