//! Property tests of what input can do to the core (issue 31): grid extents and dense copies are
//! bounded by the map-cell limit and never panic, whatever the rectangle or pose; traversal and
//! scan updates with extreme coordinates, resolutions and ranges give cells or errors, never a
//! panic, an overflow or an unbounded walk.

use crlam_core::crm::{CrmConfig, CrmMap, CrmScratch, ScanOptions};
use crlam_core::grid::{CellRect, GridGeometry, TiledGrid, MAX_COORD};
use crlam_core::limits::max_map_cells;
use crlam_core::raycast::traverse;
use crlam_core::sensor::{SensorModel, SensorModelKind};
use proptest::prelude::*;

/// Any i64, with the extremes and the values around the index limit over-represented.
fn index() -> impl Strategy<Value = i64> {
    prop_oneof![
        any::<i64>(),
        Just(i64::MAX),
        Just(i64::MIN),
        Just(0),
        Just((1i64 << 46) + 1),
        Just(-(1i64 << 46)),
        -100_000i64..100_000,
    ]
}

/// Any f64, with NaN, the infinities, huge, tiny and ordinary values over-represented.
fn coordinate() -> impl Strategy<Value = f64> {
    prop_oneof![
        any::<f64>(),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(f64::MAX),
        Just(-1e300),
        Just(MAX_COORD),
        Just(-MAX_COORD * 1.0001),
        -1e8f64..1e8,
        -50.0f64..50.0,
    ]
}

fn geometry() -> GridGeometry {
    GridGeometry::new([0.0, 0.0], 0.2).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    #[test]
    fn a_growing_grid_covers_no_more_cells_than_the_limit(
        ix0 in index(), iy0 in index(), nx in index(), ny in index(),
    ) {
        let mut g = TiledGrid::new(geometry(), 32, &[0.0f32; 2], None).unwrap();
        let r = CellRect { ix0, iy0, nx, ny };
        if g.reserve(r).is_ok() {
            prop_assert!(g.bounds().cells_f64() <= 1.6 * max_map_cells() as f64 + 1e7);
        }
        // Dense copies of any rectangle: refused above the limit, exact below it.
        match g.export(r) {
            Ok(v) => prop_assert_eq!(v.len(), r.n_cells() * 2),
            Err(e) => prop_assert!(!e.to_string().is_empty()),
        }
        let _ = g.get(ix0, iy0);
        let _ = g.get_mut(ix0, iy0);
    }

    #[test]
    fn fixed_extents_are_validated(ix0 in index(), iy0 in index(), nx in index(), ny in index()) {
        let r = CellRect { ix0, iy0, nx, ny };
        if let Ok(g) = TiledGrid::new(geometry(), 16, &[1u8], Some(r)) {
            prop_assert!(r.cells_f64() <= max_map_cells() as f64);
            prop_assert_eq!(g.bounds(), r);
        }
    }

    #[test]
    fn geometry_and_cell_lookup_never_overflow(
        ox in coordinate(), oy in coordinate(), res in coordinate(), x in coordinate(), y in coordinate(),
    ) {
        if let Ok(g) = GridGeometry::new([ox, oy], res) {
            prop_assert!(res.is_finite() && res > 0.0);
            match g.checked_cell_of(x, y) {
                Ok((ix, iy)) => {
                    prop_assert!(ix.unsigned_abs() < 1u64 << 46 && iy.unsigned_abs() < 1u64 << 46);
                    let c = g.cell_center(ix, iy);
                    prop_assert!(c[0].is_finite() && c[1].is_finite());
                }
                Err(_) => prop_assert!(!(x.is_finite() && y.is_finite()) || (x - ox).abs() > MAX_COORD || (y - oy).abs() > MAX_COORD),
            }
            let _ = g.cell_of(x, y);
        }
    }

    #[test]
    fn traversal_from_extreme_coordinates_is_bounded(
        x in coordinate(), y in coordinate(), angle in coordinate(), len_cells in prop_oneof![0.0f64..5000.0, Just(0.0), Just(1e-300)],
        res in prop_oneof![1e-3f64..5.0, Just(1e-6), Just(1e7)],
    ) {
        // Lengths of up to 5,000 cells: the callers bound a ray's cells by the map-cell limit.
        let len = len_cells * res;
        let g = GridGeometry::new([0.0, 0.0], res).unwrap();
        let mut cells = Vec::new();
        traverse(&g, [x, y], angle, len, None, &mut cells);
        // Never more cells than the ray can cross (both axes' boundaries, plus the start).
        prop_assert!(cells.len() as f64 <= 2.0 * len / res + 4.0, "{} cells", cells.len());
        for w in cells.windows(2) {
            prop_assert!(w[0].ix.abs_diff(w[1].ix) <= 1 && w[0].iy.abs_diff(w[1].iy) <= 1);
        }
    }

    #[test]
    fn scan_updates_at_extreme_poses_give_errors_not_panics(
        x in coordinate(), y in coordinate(), theta in coordinate(),
        range in prop_oneof![coordinate(), 0.0f64..10.0], res in prop_oneof![Just(0.2f64), Just(1e-6), Just(0.05)],
        z_max in prop_oneof![Just(8.0f64), Just(1e6), Just(1e-9)],
    ) {
        let g = GridGeometry::new([0.0, 0.0], res).unwrap();
        let Ok(mut map) = CrmMap::new(&CrmConfig::new(g)) else { return Ok(()); };
        let model = SensorModel::with_defaults(SensorModelKind::Ijrr, z_max, res);
        if model.validate().is_err() {
            return Ok(());
        }
        let angles = [-1.0, 0.0, 0.5];
        let ranges = [range, range * 0.5, f64::INFINITY];
        let mut scratch = CrmScratch::default();
        let _ = map.update_scan([x, y, theta], &angles, &ranges, &model, &ScanOptions::default(), &mut scratch);
        prop_assert!(map.grid().bounds().cells_f64() <= 1.6 * max_map_cells() as f64 + 1e7);
        let _ = map.scan_log_likelihood([x, y, theta], &angles, &ranges, &model, &ScanOptions::default(), &mut scratch);
    }
}
