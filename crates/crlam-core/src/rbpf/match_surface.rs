//! What the scan matcher reads of a particle's grid: for each cell only whether it is occupied
//! (log-odds > 0) or free. "Free" follows the matcher's [`FreeTest`]: log-odds < 0 (observed
//! free), or anything not occupied, unknown cells included (GMapping's test).
//!
//! A match evaluation reads two cells per beam at least, and a particle's hill climbing and
//! proposal lattice evaluate some hundred poses, so the reads dominate the matcher. Through the
//! tiles, a read is a tile-slot computation and a pointer chase; a [`MatchSurface`] copies the
//! classes of the rectangle the scan covers into one byte per cell once per particle and scan,
//! and reads outside that rectangle (a climb that wandered off) go to the tiles. Both paths give
//! the same class, so the matcher's results do not depend on whether, or where, a patch exists.

use super::scanmatch::{FreeTest, PreparedScan};
use crate::grid::{GridGeometry, TiledGrid};
use crate::ogm::{hit_mean_of, LogOddsGrid};
use crate::pose::Pose;

/// Class bit of an occupied cell (log-odds > 0).
pub(crate) const OCCUPIED: u8 = 1;
/// Class bit of a free cell: log-odds < 0 under [`FreeTest::Observed`], where a cell at exactly 0
/// (unknown) or NaN is neither class; anything not occupied under [`FreeTest::NotOccupied`].
pub(crate) const FREE: u8 = 2;

/// Margin (m) around the scan's endpoints at the starting pose that the patch also covers: the
/// hill climbing's moves and the proposal lattice stay within it in all but rare cases.
const PATCH_MARGIN: f64 = 1.0;

/// A patch is built only when it has at most this many cells per matched beam: a scan of few,
/// long beams on a fine grid (180 beams over 30 m at 5 cm) reads far fewer cells than it spans.
const PATCH_CELLS_PER_BEAM: usize = 16;

#[inline]
fn class_of(v: f32, free_test: FreeTest) -> u8 {
    let occupied = v > 0.0;
    let free = match free_test {
        FreeTest::Observed => v < 0.0,
        FreeTest::NotOccupied => !occupied,
    };
    u8::from(occupied) | (u8::from(free) << 1)
}

/// A particle's grid as the scan matcher reads it, with an optional dense patch of cell classes.
#[derive(Clone, Debug)]
pub struct MatchSurface<'a> {
    grid: &'a TiledGrid<f32>,
    ix0: i64,
    iy0: i64,
    nx: usize,
    ny: usize,
    classes: Vec<u8>,
    free_test: FreeTest,
}

impl<'a> MatchSurface<'a> {
    /// The grid alone: every read goes to the tiles.
    pub fn tiles(map: &'a LogOddsGrid, free_test: FreeTest) -> Self {
        Self {
            grid: map.grid(),
            ix0: 0,
            iy0: 0,
            nx: 0,
            ny: 0,
            classes: Vec::new(),
            free_test,
        }
    }

    /// The grid with a patch over the cells `scan` reaches from `pose` (endpoints and free
    /// points, plus a margin), when that patch is small enough to pay for itself.
    pub fn around(
        map: &'a LogOddsGrid,
        scan: &PreparedScan,
        pose: Pose,
        kernel_size: usize,
        free_test: FreeTest,
    ) -> Self {
        Self::around_within(
            map,
            scan,
            pose,
            kernel_size,
            free_test,
            PATCH_CELLS_PER_BEAM,
        )
    }

    /// [`Self::around`] with the patch built when it has at most `cells_per_beam` cells per
    /// beam of `scan` (the default is 16).
    pub fn around_within(
        map: &'a LogOddsGrid,
        scan: &PreparedScan,
        pose: Pose,
        kernel_size: usize,
        free_test: FreeTest,
        cells_per_beam: usize,
    ) -> Self {
        let mut surface = Self::tiles(map, free_test);
        if scan.is_empty() || !pose.iter().all(|v| v.is_finite()) {
            return surface;
        }
        let g: GridGeometry = *map.grid().geometry();
        let (s, c) = pose[2].sin_cos();
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for e in scan.endpoints() {
            let w = [pose[0] + c * e[0] - s * e[1], pose[1] + s * e[0] + c * e[1]];
            for k in 0..2 {
                lo[k] = lo[k].min(w[k]);
                hi[k] = hi[k].max(w[k]);
            }
        }
        // The free points lie √2 Δ before the endpoints, the window k cells around either.
        let pad = PATCH_MARGIN + (2 + kernel_size) as f64 * g.resolution;
        let inv = 1.0 / g.resolution;
        let cell = |v: f64, o: f64| ((v - o) * inv).floor();
        let (fx0, fy0) = (
            cell(lo[0] - pad, g.origin[0]),
            cell(lo[1] - pad, g.origin[1]),
        );
        let (fx1, fy1) = (
            cell(hi[0] + pad, g.origin[0]),
            cell(hi[1] + pad, g.origin[1]),
        );
        let (nx, ny) = (fx1 - fx0 + 1.0, fy1 - fy0 + 1.0);
        let budget = cells_per_beam as f64 * scan.len() as f64;
        // Also refuses non-finite extents and anything beyond the i64 range (a budget of cells
        // is far below it).
        if !(nx >= 1.0 && ny >= 1.0 && nx * ny <= budget) {
            return surface;
        }
        let (ix0, iy0, nx, ny) = (fx0 as i64, fy0 as i64, nx as usize, ny as usize);
        let grid = map.grid();
        let stride = grid.stride();
        let mut classes = Vec::with_capacity(nx * ny);
        for iy in iy0..iy0 + ny as i64 {
            let mut ix = ix0;
            let end = ix0 + nx as i64;
            while ix < end {
                let (vals, cells, stored) = grid.row_run(ix, iy, (end - ix) as usize);
                if stored {
                    classes.extend(vals.iter().step_by(stride).map(|&v| class_of(v, free_test)));
                } else {
                    classes.extend(std::iter::repeat_n(class_of(vals[0], free_test), cells));
                }
                ix += cells as i64;
            }
        }
        debug_assert_eq!(classes.len(), nx * ny);
        surface.ix0 = ix0;
        surface.iy0 = iy0;
        surface.nx = nx;
        surface.ny = ny;
        surface.classes = classes;
        surface
    }

    pub fn geometry(&self) -> &GridGeometry {
        self.grid.geometry()
    }

    /// Whether a patch was built (for tests and diagnostics).
    pub fn has_patch(&self) -> bool {
        !self.classes.is_empty()
    }

    /// Whether the grid keeps the mean of the hits of each cell ([`LogOddsParams::hit_means`]).
    ///
    /// [`LogOddsParams::hit_means`]: crate::ogm::LogOddsParams::hit_means
    #[inline]
    pub fn has_hit_means(&self) -> bool {
        self.grid.stride() >= 4
    }

    /// For an occupied cell (ix, iy), the offset (m) of the mean of its hits from its centre
    /// (zero without hits); `None` if the cell is not occupied. One read of the tiles gives both
    /// (grids with hit means get no patch benefit here: the patch holds classes only).
    #[inline]
    pub(crate) fn occupied_hit_mean(&self, ix: i64, iy: i64) -> Option<[f64; 2]> {
        let v = self.grid.get(ix, iy);
        (class_of(v[0], self.free_test) & OCCUPIED != 0).then(|| hit_mean_of(v))
    }

    /// The class bits of cell (ix, iy): [`OCCUPIED`], [`FREE`] or neither.
    #[inline]
    pub(crate) fn class(&self, ix: i64, iy: i64) -> u8 {
        let (dx, dy) = (ix.wrapping_sub(self.ix0), iy.wrapping_sub(self.iy0));
        if (dx as u64) < self.nx as u64 && (dy as u64) < self.ny as u64 {
            return self.classes[dy as usize * self.nx + dx as usize];
        }
        class_of(self.grid.get(ix, iy)[0], self.free_test)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ogm::LogOddsParams;

    #[test]
    fn patch_and_tiles_read_the_same_classes() {
        let g = GridGeometry::new([0.0, 0.0], 0.2).unwrap();
        let mut map = LogOddsGrid::new(g, LogOddsParams::new(8.0), 16, None).unwrap();
        let angles: Vec<f64> = (0..90).map(|i| -1.5 + i as f64 * 0.033).collect();
        let ranges: Vec<f64> = (0..90).map(|i| 2.0 + (i % 7) as f64 * 0.3).collect();
        map.update_scan([1.0, -2.0, 0.3], &angles, &ranges).unwrap();
        let scan = PreparedScan::new(&angles, &ranges, [0.0; 3], 7.5, 1).unwrap();
        for test in [FreeTest::Observed, FreeTest::NotOccupied] {
            let patched = MatchSurface::around_within(&map, &scan, [1.0, -2.0, 0.3], 1, test, 1000);
            assert!(patched.has_patch());
            let plain = MatchSurface::tiles(&map, test);
            let mut seen = [0usize; 4];
            for iy in -40..30 {
                for ix in -30..50 {
                    let c = patched.class(ix, iy);
                    assert_eq!(c, plain.class(ix, iy), "cell ({ix}, {iy})");
                    seen[c as usize] += 1;
                    // Only the class of unknown cells depends on the test.
                    let unknown = map.log_odds(ix, iy) == 0.0;
                    let expected = match (test, unknown) {
                        (_, false) if map.log_odds(ix, iy) > 0.0 => OCCUPIED,
                        (_, false) => FREE,
                        (FreeTest::Observed, true) => 0,
                        (FreeTest::NotOccupied, true) => FREE,
                    };
                    assert_eq!(c, expected, "cell ({ix}, {iy}) under {test:?}");
                }
            }
            // The scan left occupied, free and unknown cells, and no cell is both.
            assert!(seen[1] > 0 && seen[2] > 0 && seen[3] == 0);
            match test {
                FreeTest::Observed => assert!(seen[0] > 0),
                FreeTest::NotOccupied => assert_eq!(seen[0], 0),
            }
        }
    }
}
