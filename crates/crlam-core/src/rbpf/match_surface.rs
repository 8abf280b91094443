//! What the scan matcher reads of a particle's grid: for each cell only whether it is occupied
//! (log-odds > 0) or free. "Free" follows the matcher's [`FreeTest`]: log-odds < 0 (observed
//! free), or anything not occupied, unknown cells included (GMapping's test).
//!
//! A confidence-rich map is read the same way through its expected occupancy m̂: a cell is
//! occupied when m̂ exceeds a threshold (the prior's mean 0.5 by default: more evidence of a
//! wall than of free space) and observed free below it, i.e. m̂ − threshold plays the log-odds.
//! The means come from the map's block means, which copies of one map share, so the particles
//! of one parent compute each block once.
//!
//! A match evaluation reads two cells per beam at least, and a particle's hill climbing and
//! proposal lattice evaluate some hundred poses, so the reads dominate the matcher. Through the
//! tiles, a read is a tile-slot computation and a pointer chase; a [`MatchSurface`] copies the
//! classes of the rectangle the scan covers into one byte per cell once per particle and scan,
//! and reads outside that rectangle (a climb that wandered off) go to the tiles. Both paths give
//! the same class, so the matcher's results do not depend on whether, or where, a patch exists.

use std::cell::Cell;
use std::sync::Arc;

use super::prepared_scan::PreparedScan;
use super::scanmatch_params::FreeTest;
use crate::crm::mean_cache::MeanTable;
use crate::crm::CrmMap;
use crate::grid::{CellRect, GridGeometry, TiledGrid};
use crate::ogm::{hit_mean_of, LogOddsGrid};
use crate::pose::Pose;
use crate::rbpf::hit_means::HitMeans;

/// Class bit of an occupied cell (log-odds > 0).
pub(crate) const OCCUPIED: u8 = 1;
/// Patch entry of a confidence-rich map's cell whose class has not been computed yet (neither
/// class bit pattern uses it).
const UNREAD: u8 = 0x80;

/// Class bit of a free cell: log-odds < 0 under [`FreeTest::Observed`], where a cell at exactly 0
/// (unknown) or NaN is neither class; anything not occupied under [`FreeTest::NotOccupied`].
pub(crate) const FREE: u8 = 2;

/// Margin (m) around the scan's endpoints at the starting pose that the patch also covers: the
/// hill climbing's moves and the proposal lattice stay within it in all but rare cases.
const PATCH_MARGIN: f64 = 1.0;

/// A patch is built only when it has at most this many cells per matched beam: a scan of few,
/// long beams on a fine grid (180 beams over 30 m at 5 cm) reads far fewer cells than it spans.
const PATCH_CELLS_PER_BEAM: usize = 16;

/// The same budget for a confidence-rich map, whose tile read costs a block-mean lookup (a
/// block's means are computed once per map version, and every particle's map is a new version
/// after each scan): a dense patch of classes pays for itself at a larger size there (Intel,
/// 4,000 scans, robust preset: 18.6 s with 16 cells per beam, 14.8 s with 256 or 1,024; the
/// same trajectory).
const CRM_PATCH_CELLS_PER_BEAM: usize = 256;

#[inline]
fn class_of(v: f32, free_test: FreeTest) -> u8 {
    let occupied = v > 0.0;
    let free = match free_test {
        FreeTest::Observed => v < 0.0,
        FreeTest::NotOccupied => !occupied,
    };
    u8::from(occupied) | (u8::from(free) << 1)
}

/// The cells a surface reads where it has no patch.
#[derive(Clone, Copy, Debug)]
enum Cells<'a> {
    /// Log-odds grids (first value of each cell; hit-mean grids keep more after it).
    LogOdds(&'a TiledGrid<f32>),
    /// A confidence-rich map, classified by `m̂ − occupied_above`, with the means of its hits
    /// when the particle keeps them.
    Crm {
        map: &'a CrmMap,
        occupied_above: f64,
        hits: Option<&'a HitMeans>,
    },
}

impl Cells<'_> {
    /// The value whose sign gives the class: log-odds, or m̂ minus the threshold.
    #[inline]
    fn value(&self, ix: i64, iy: i64) -> f32 {
        match *self {
            Cells::LogOdds(grid) => grid.get(ix, iy)[0],
            Cells::Crm {
                map,
                occupied_above,
                ..
            } => {
                let mean = match map.tile_means() {
                    Some(tm) => match map.mean_block(tm, ix, iy) {
                        (_, Some(block)) => block[tm.offset(ix, iy)],
                        (_, None) => tm.outside(),
                    },
                    None => map.mean_at(ix, iy),
                };
                (mean - occupied_above) as f32
            }
        }
    }

    fn geometry(&self) -> &GridGeometry {
        match self {
            Cells::LogOdds(grid) => grid.geometry(),
            Cells::Crm { map, .. } => map.geometry(),
        }
    }
}

/// A particle's grid as the scan matcher reads it, with an optional dense patch of cell classes.
#[derive(Clone, Debug)]
pub struct MatchSurface<'a> {
    cells: Cells<'a>,
    ix0: i64,
    iy0: i64,
    nx: usize,
    ny: usize,
    /// Row-major classes of the patch. For a confidence-rich map they start [`UNREAD`] and are
    /// computed on the first read: the climb and the lattice read a band of a few cells around
    /// each endpoint, a small part of the rectangle the scan spans, and a cell's mean costs a sum
    /// over its levels (Intel, robust preset: the dense patch's means were 14 % of the run).
    classes: Vec<Cell<u8>>,
    free_test: FreeTest,
    /// A confidence-rich map's cached window means (the same values as `mean_at`), read for the
    /// patch's classes where they cover the cell: a table read instead of a sum over levels.
    means: Option<Arc<MeanTable>>,
}

impl<'a> MatchSurface<'a> {
    /// The grid alone: every read goes to the tiles.
    pub fn tiles(map: &'a LogOddsGrid, free_test: FreeTest) -> Self {
        Self::over(Cells::LogOdds(map.grid()), free_test)
    }

    fn over(cells: Cells<'a>, free_test: FreeTest) -> Self {
        Self {
            cells,
            ix0: 0,
            iy0: 0,
            nx: 0,
            ny: 0,
            classes: Vec::new(),
            free_test,
            means: None,
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
        let Some(rect) = patch_rect(
            map.grid().geometry(),
            scan,
            pose,
            kernel_size,
            cells_per_beam,
        ) else {
            return surface;
        };
        let grid = map.grid();
        let stride = grid.stride();
        let (nx, ny) = (rect.nx as usize, rect.ny as usize);
        let mut classes: Vec<u8> = Vec::with_capacity(nx * ny);
        for iy in rect.iy0..rect.iy0 + rect.ny {
            let mut ix = rect.ix0;
            let end = rect.ix0 + rect.nx;
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
        surface.set_patch(rect, classes.into_iter().map(Cell::new).collect());
        surface
    }

    /// A confidence-rich map as the matcher reads it: cells with expected occupancy above
    /// `occupied_above` are occupied, those below it observed free (see the module
    /// documentation), with a patch over the cells `scan` reaches from `pose` when it is small.
    /// With `hits`, the matcher measures distances to the means of the hits of occupied cells
    /// (as on a log-odds grid with hit means) instead of their centres.
    pub fn around_crm(
        map: &'a CrmMap,
        hits: Option<&'a HitMeans>,
        scan: &PreparedScan,
        pose: Pose,
        kernel_size: usize,
        free_test: FreeTest,
        occupied_above: f64,
    ) -> Self {
        Self::around_crm_within(
            map,
            hits,
            scan,
            pose,
            kernel_size,
            free_test,
            occupied_above,
            CRM_PATCH_CELLS_PER_BEAM,
        )
    }

    /// [`Self::around_crm`] with the patch built when it has at most `cells_per_beam` cells per
    /// beam of `scan`.
    #[allow(clippy::too_many_arguments)]
    pub fn around_crm_within(
        map: &'a CrmMap,
        hits: Option<&'a HitMeans>,
        scan: &PreparedScan,
        pose: Pose,
        kernel_size: usize,
        free_test: FreeTest,
        occupied_above: f64,
        cells_per_beam: usize,
    ) -> Self {
        let cells = Cells::Crm {
            map,
            occupied_above,
            hits,
        };
        let mut surface = Self::over(cells, free_test);
        let Some(rect) = patch_rect(map.geometry(), scan, pose, kernel_size, cells_per_beam) else {
            return surface;
        };
        // Classes are filled in on first read (see `classes`), from the same mean as a dense
        // `means_into` would give, so the matcher's results do not change.
        surface.set_patch(rect, vec![Cell::new(UNREAD); rect.n_cells()]);
        surface.means = map.window_means();
        surface
    }

    fn set_patch(&mut self, rect: CellRect, classes: Vec<Cell<u8>>) {
        debug_assert_eq!(classes.len(), rect.n_cells());
        self.ix0 = rect.ix0;
        self.iy0 = rect.iy0;
        self.nx = rect.nx as usize;
        self.ny = rect.ny as usize;
        self.classes = classes;
    }

    pub fn geometry(&self) -> &GridGeometry {
        self.cells.geometry()
    }

    /// Whether a patch was built (for tests and diagnostics).
    pub fn has_patch(&self) -> bool {
        !self.classes.is_empty()
    }

    /// Whether the grid keeps the mean of the hits of each cell ([`LogOddsParams::hit_means`],
    /// or a confidence-rich map read with its [`HitMeans`]).
    ///
    /// [`LogOddsParams::hit_means`]: crate::ogm::LogOddsParams::hit_means
    #[inline]
    pub fn has_hit_means(&self) -> bool {
        match self.cells {
            Cells::LogOdds(grid) => grid.stride() >= 4,
            Cells::Crm { hits, .. } => hits.is_some(),
        }
    }

    /// For an occupied cell (ix, iy), the offset (m) of the mean of its hits from its centre
    /// (zero without hits); `None` if the cell is not occupied. One read of the tiles gives both
    /// (grids with hit means get no patch benefit here: the patch holds classes only).
    #[inline]
    pub(crate) fn occupied_hit_mean(&self, ix: i64, iy: i64) -> Option<[f64; 2]> {
        match self.cells {
            Cells::LogOdds(grid) => {
                let v = grid.get(ix, iy);
                (class_of(v[0], self.free_test) & OCCUPIED != 0).then(|| hit_mean_of(v))
            }
            Cells::Crm { hits, .. } => (self.class(ix, iy) & OCCUPIED != 0)
                .then(|| hits.map_or([0.0; 2], |h| h.offset(ix, iy))),
        }
    }

    /// The class bits of cell (ix, iy): [`OCCUPIED`], [`FREE`] or neither.
    #[inline]
    pub(crate) fn class(&self, ix: i64, iy: i64) -> u8 {
        let (dx, dy) = (ix.wrapping_sub(self.ix0), iy.wrapping_sub(self.iy0));
        if (dx as u64) < self.nx as u64 && (dy as u64) < self.ny as u64 {
            let slot = &self.classes[dy as usize * self.nx + dx as usize];
            let class = slot.get();
            if class != UNREAD {
                return class;
            }
            return self.first_read(slot, ix, iy);
        }
        class_of(self.cells.value(ix, iy), self.free_test)
    }

    /// The class of patch cell (ix, iy) on its first read, stored in its `slot` (kept out of
    /// line: the matcher's loops read classes already known far more often).
    #[cold]
    #[inline(never)]
    fn first_read(&self, slot: &Cell<u8>, ix: i64, iy: i64) -> u8 {
        let class = match self.cells {
            Cells::Crm {
                map,
                occupied_above,
                ..
            } => {
                let mean = match &self.means {
                    Some(t) if t.rect.contains(ix, iy) => t.get(ix, iy),
                    _ => map.mean_at(ix, iy),
                };
                class_of((mean - occupied_above) as f32, self.free_test)
            }
            Cells::LogOdds(_) => class_of(self.cells.value(ix, iy), self.free_test),
        };
        slot.set(class);
        class
    }
}

/// The rectangle of cells that the beams of `scan` below its near range (z_max) reach from
/// `pose` (endpoints and free points, the window around either, plus a margin), if it has at
/// most `cells_per_beam` cells per such beam. The farther beams (a full-range matcher's) read
/// the tiles: their endpoints spread over an area that grows with the square of their length,
/// so a patch sized by them would cost memory and filling for cells never read.
fn patch_rect(
    g: &GridGeometry,
    scan: &PreparedScan,
    pose: Pose,
    kernel_size: usize,
    cells_per_beam: usize,
) -> Option<CellRect> {
    if scan.n_near() == 0 || !pose.iter().all(|v| v.is_finite()) {
        return None;
    }
    let (s, c) = pose[2].sin_cos();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for e in scan.near_endpoints() {
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
    let budget = cells_per_beam as f64 * scan.n_near() as f64;
    // Also refuses non-finite extents and anything beyond the i64 range (a budget of cells is
    // far below it).
    (nx >= 1.0 && ny >= 1.0 && nx * ny <= budget).then_some(CellRect {
        ix0: fx0 as i64,
        iy0: fy0 as i64,
        nx: nx as i64,
        ny: ny as i64,
    })
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

    #[test]
    fn a_crm_reads_as_occupied_above_the_threshold_on_patch_and_tiles_alike() {
        use crate::crm::{CrmConfig, CrmScratch, ScanOptions};
        use crate::sensor::{SensorModel, SensorModelKind};
        let g = GridGeometry::new([0.0, 0.0], 0.2).unwrap();
        let mut map = CrmMap::new(&CrmConfig::new(g)).unwrap();
        let angles: Vec<f64> = (0..90).map(|i| -1.5 + i as f64 * 0.033).collect();
        let ranges: Vec<f64> = (0..90).map(|i| 2.0 + (i % 7) as f64 * 0.3).collect();
        let model = SensorModel::with_defaults(SensorModelKind::Ijrr, 8.0, 0.2);
        let mut sc = CrmScratch::default();
        map.update_scan(
            [1.0, -2.0, 0.3],
            &angles,
            &ranges,
            &model,
            &ScanOptions::default(),
            &mut sc,
        )
        .unwrap();
        let scan = PreparedScan::new(&angles, &ranges, [0.0; 3], 7.5, 1).unwrap();
        let pose = [1.0, -2.0, 0.3];
        for test in [FreeTest::Observed, FreeTest::NotOccupied] {
            for threshold in [0.5, 0.6] {
                let patched = MatchSurface::around_crm_within(
                    &map, None, &scan, pose, 1, test, threshold, 1000,
                );
                assert!(patched.has_patch() && !patched.has_hit_means());
                // No budget, no patch: every read goes to the block means.
                let tiles =
                    MatchSurface::around_crm_within(&map, None, &scan, pose, 1, test, threshold, 0);
                assert!(!tiles.has_patch());
                let mut seen = [0usize; 4];
                for iy in -40..30 {
                    for ix in -30..50 {
                        let c = patched.class(ix, iy);
                        assert_eq!(c, tiles.class(ix, iy), "cell ({ix}, {iy})");
                        let m = map.mean_at(ix, iy);
                        let v = (m - threshold) as f32;
                        let expected = if v > 0.0 {
                            OCCUPIED
                        } else if v < 0.0 || test == FreeTest::NotOccupied {
                            FREE
                        } else {
                            0
                        };
                        assert_eq!(c, expected, "cell ({ix}, {iy}), mean {m}");
                        seen[c as usize] += 1;
                    }
                }
                assert!(seen[1] > 0 && seen[2] > 0 && seen[3] == 0, "{seen:?}");
                // Unknown cells hold the prior (mean 0.5): neither class under the observed test.
                if test == FreeTest::Observed && threshold == 0.5 {
                    assert!(seen[0] > 0);
                }
            }
        }
    }

    #[test]
    fn a_crm_with_hit_means_scores_sub_cell_shifts_and_one_without_does_not() {
        use crate::crm::{CrmConfig, CrmScratch, ScanOptions};
        use crate::rbpf::hit_means::HitMeans;
        use crate::rbpf::scanmatch::{MatcherParams, ScanMatcher};
        use crate::sensor::{SensorModel, SensorModelKind};
        // A wall across x = 2.03 m seen head-on: its cells (0.1 m, centre 2.05) hold hits 2 cm
        // before their centres.
        let g = GridGeometry::new([0.0, 0.0], 0.1).unwrap();
        let mut map = CrmMap::new(&CrmConfig::new(g)).unwrap();
        let mut hits = HitMeans::new(g, 32).unwrap();
        let angles: Vec<f64> = (0..61).map(|i| -0.6 + i as f64 * 0.02).collect();
        let ranges: Vec<f64> = angles.iter().map(|a| 2.03 / a.cos()).collect();
        let model = SensorModel::with_defaults(SensorModelKind::Ijrr, 8.0, 0.1);
        let mut sc = CrmScratch::default();
        for _ in 0..3 {
            map.update_scan(
                [0.0; 3],
                &angles,
                &ranges,
                &model,
                &ScanOptions::default(),
                &mut sc,
            )
            .unwrap();
            hits.record_scan([0.0; 3], &angles, &ranges, 0.0, 8.0, 1)
                .unwrap();
        }
        let scan = PreparedScan::new(&angles, &ranges, [0.0; 3], 7.5, 1).unwrap();
        let with = MatchSurface::around_crm(
            &map,
            Some(&hits),
            &scan,
            [0.0; 3],
            1,
            FreeTest::Observed,
            0.5,
        );
        let without =
            MatchSurface::around_crm(&map, None, &scan, [0.0; 3], 1, FreeTest::Observed, 0.5);
        assert!(with.has_hit_means() && !without.has_hit_means());
        let (ix, iy) = g.cell_of(2.03, 0.0);
        let m = with
            .occupied_hit_mean(ix, iy)
            .expect("the wall's cell is occupied");
        assert!((m[0] + 0.02).abs() < 1e-4, "{m:?}");
        assert_eq!(without.occupied_hit_mean(ix, iy), Some([0.0, 0.0]));
        // A free cell has no mean to offer.
        assert_eq!(with.occupied_hit_mean(g.cell_of(1.0, 0.0).0, 0), None);
        let matcher = ScanMatcher {
            params: MatcherParams::default(),
        };
        let score =
            |s: &MatchSurface, dx: f64| matcher.evaluate(s, &scan, [dx, 0.0, 0.0]).unwrap().score;
        // The best shift along x: with the means the wall where it was seen (no shift), without
        // them its endpoints on the cells' centres 2 cm farther.
        let best = |s: &MatchSurface| {
            (-40..=40)
                .map(|i| i as f64 * 0.001)
                .max_by(|a, b| score(s, *a).total_cmp(&score(s, *b)))
                .unwrap()
        };
        assert!(best(&with).abs() < 1.5e-3, "{}", best(&with));
        assert!((best(&without) - 0.02).abs() < 1.5e-3, "{}", best(&without));
    }
}
