//! Property tests of the exact grid traversal.

use crlam_core::grid::{CellRect, GridGeometry};
use crlam_core::raycast::{traverse, RayCell};
use proptest::prelude::*;

fn walk(
    res: f64,
    o: [f64; 2],
    angle: f64,
    len: f64,
    clip: Option<&CellRect>,
) -> (Vec<RayCell>, f64) {
    let g = GridGeometry::new([-0.37, 0.21], res).unwrap();
    let mut v = Vec::new();
    let end = traverse(&g, o, angle, len, clip, &mut v);
    (v, end)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn chords_sum_to_length_and_cells_are_contiguous(
        res in 0.05f64..1.0, x in -20.0f64..20.0, y in -20.0f64..20.0,
        angle in -7.0f64..7.0, len in 0.0f64..30.0,
    ) {
        let (cells, end) = walk(res, [x, y], angle, len, None);
        prop_assert!((end - len).abs() < 1e-9);
        let total: f64 = cells.iter().map(|c| c.t_out - c.t_in).sum();
        prop_assert!((total - len).abs() < 1e-7 + 1e-9 * cells.len() as f64, "total {} len {}", total, len);
        for w in cells.windows(2) {
            prop_assert!((w[0].ix - w[1].ix).abs() <= 1 && (w[0].iy - w[1].iy).abs() <= 1);
            prop_assert!((w[0].ix, w[0].iy) != (w[1].ix, w[1].iy));
            prop_assert!((w[0].t_out - w[1].t_in).abs() < 1e-9);
        }
        // Every reported point lies in its cell.
        let g = GridGeometry::new([-0.37, 0.21], res).unwrap();
        for c in &cells {
            let t = c.mid();
            let p = [x + t * angle.cos(), y + t * angle.sin()];
            prop_assert_eq!(g.cell_of(p[0], p[1]), (c.ix, c.iy));
            prop_assert!(c.t_out - c.t_in >= 1e-9);
        }
    }

    #[test]
    fn symmetric_under_transpose(
        x in -5.0f64..5.0, y in -5.0f64..5.0, angle in -3.2f64..3.2, len in 0.0f64..10.0,
    ) {
        let g = GridGeometry::new([0.0, 0.0], 0.25).unwrap();
        let (mut a, mut b) = (Vec::new(), Vec::new());
        traverse(&g, [x, y], angle, len, None, &mut a);
        traverse(&g, [y, x], std::f64::consts::FRAC_PI_2 - angle, len, None, &mut b);
        prop_assert_eq!(a.len(), b.len());
        for (p, q) in a.iter().zip(&b) {
            prop_assert_eq!((p.ix, p.iy), (q.iy, q.ix));
            prop_assert!((p.t_in - q.t_in).abs() < 1e-9 && (p.t_out - q.t_out).abs() < 1e-9);
        }
    }

    #[test]
    fn clipped_walks_stay_inside(
        x in -5.0f64..15.0, y in -5.0f64..15.0, angle in -3.2f64..3.2, len in 0.0f64..30.0,
    ) {
        let r = CellRect { ix0: 0, iy0: 0, nx: 20, ny: 20 };
        let g = GridGeometry::new([0.0, 0.0], 0.5).unwrap();
        let mut v = Vec::new();
        traverse(&g, [x, y], angle, len, Some(&r), &mut v);
        for c in &v {
            prop_assert!(r.contains(c.ix, c.iy));
            prop_assert!(c.t_in >= -1e-12 && c.t_out <= len + 1e-9);
        }
    }
}
