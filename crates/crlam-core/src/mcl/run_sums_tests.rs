//! Tests of the far phase by runs against the cell walk.

use super::*;
use crate::grid::{CellRect, GridGeometry};
use crate::raycast::WalkCell;

/// A field of `nx` x `ny` cells of 0.1 m from the means `mean`, stored with a margin of 30.
fn field(mean: Vec<f64>, nx: i64, ny: i64) -> MeanField {
    let g = GridGeometry::new([-1.3, 0.7], 0.1).unwrap();
    let rect = CellRect {
        ix0: -4,
        iy0: 3,
        nx,
        ny,
    };
    MeanField::from_means(g, rect, mean, 0.3, 0.25, 30).unwrap()
}

/// What the walk itself gives: Σ ln(1 − m̂) over the reported cells whose chord ends before
/// `lim`, and the cells after them.
fn walked(f: &MeanField, mut walk: FastWalk, lim: f64) -> (f64, Vec<WalkCell>) {
    let mut sum = 0.0;
    let mut rest = Vec::new();
    for wc in walk.by_ref() {
        if wc.cell.t_out < lim && rest.is_empty() {
            sum += log_clear(f.values()[wc.index as usize]);
        } else {
            rest.push(wc);
        }
    }
    (sum, rest)
}

/// Random fields (free cells, walls, cells of m̂ = 1 and m̂ = 0) and random rays (any
/// direction, axis-aligned and diagonal included, from anywhere in the map, cut anywhere): the
/// runs consume the cells the walk reports before the cut with the walk's Σ ln(1 − m̂) to
/// 1e-9, and leave the walk where its own steps would have (same cells, crossings to 1e-9).
/// Fails if a run takes a cell the walk does not visit, misses one, or resumes the walk wrong.
#[test]
fn runs_take_the_walks_cells() {
    use proptest::prelude::*;
    use proptest::test_runner::{Config, TestRunner};
    let mut runner = TestRunner::new(Config {
        cases: 400,
        failure_persistence: None,
        ..Config::default()
    });
    let angle = prop_oneof![
        -3.2f64..3.2,
        Just(0.0),
        Just(std::f64::consts::FRAC_PI_2),
        Just(std::f64::consts::PI),
        Just(-std::f64::consts::FRAC_PI_2),
        Just(std::f64::consts::FRAC_PI_4),
        Just(-3.0 * std::f64::consts::FRAC_PI_4),
    ];
    let case = (
        proptest::collection::vec(0.0f64..1.0, 50 * 40),
        proptest::collection::vec((0usize..50, 0usize..40, 0.5f64..=1.0), 0..60),
        (-1.0f64..4.5, 0.6f64..5.0),
        proptest::collection::vec((angle, 0.0f64..2.5, 0.0f64..3.2), 1..30),
    );
    runner
        .run(&case, |(noise, walls, origin, rays)| {
            let mut mean: Vec<f64> = noise
                .iter()
                .map(|u| if *u < 0.05 { 0.0 } else { 0.2 * u * u })
                .collect();
            for (ix, iy, m) in walls {
                mean[iy * 50 + ix] = if m > 0.95 { 1.0 } else { m };
            }
            let f = field(mean, 50, 40);
            let runs = RunSums::new(&f).unwrap();
            let origin = [origin.0 - 1.3 - 0.4, origin.1 + 0.7 + 0.3];
            for (a, length, lim) in rays {
                if !f.holds_ray(origin, length) {
                    continue;
                }
                let walk = FastWalk::new(f.geometry(), origin, a, length, f.window());
                // The ray's last cell ends at the ray's end and is left to the walk.
                let (want, rest) = walked(&f, walk.clone(), lim.min(length));
                let mut fast = walk;
                let got = runs.consume_before(&mut fast, lim, f64::NEG_INFINITY);
                let scale = 1.0 + want.abs().min(OPAQUE);
                prop_assert!(
                    (got - want).abs() <= 1e-9 * scale || (got <= -OPAQUE && want <= -OPAQUE),
                    "Σ ln(1 − m̂) {} against the walk's {} (angle {}, length {}, cut {})",
                    got,
                    want,
                    a,
                    length,
                    lim
                );
                let after: Vec<WalkCell> = fast.collect();
                prop_assert_eq!(
                    after.len(),
                    rest.len(),
                    "cells after the runs (angle {}, length {}, cut {}, origin {:?})",
                    a,
                    length,
                    lim,
                    origin
                );
                for (x, y) in after.iter().zip(&rest) {
                    prop_assert_eq!(
                        (x.cell.ix, x.cell.iy, x.index),
                        (y.cell.ix, y.cell.iy, y.index)
                    );
                    prop_assert!((x.cell.t_in - y.cell.t_in).abs() < 1e-9);
                    prop_assert!((x.cell.t_out - y.cell.t_out).abs() < 1e-9);
                }
            }
            Ok(())
        })
        .unwrap();
}

/// The sums themselves against a direct sum, and m̂ = 1 reading as a blocked run.
#[test]
fn sums_of_rows_and_columns() {
    let mean = vec![0.1, 0.2, 1.0, 0.0, 0.5, 0.25];
    let f = field(mean, 3, 2);
    let runs = RunSums::new(&f).unwrap();
    let s = f.store();
    // Store coordinates of map cell (0, 0): the margin is 30.
    let (x0, y0) = (30, 30);
    let row0 = runs.run(true, y0, x0, x0 + 1).unwrap();
    assert!((row0 - (0.9f64.ln() + 0.8f64.ln())).abs() < 1e-12);
    let row1 = runs.run(true, y0 + 1, x0 + 2, x0).unwrap();
    assert!((row1 - (0.5f64.ln() + 0.75f64.ln())).abs() < 1e-12);
    let col2 = runs.run(false, x0 + 2, y0, y0 + 1).unwrap();
    assert!(col2 <= -OPAQUE);
    assert_eq!(col2.exp(), 0.0);
    // Outside cells read the outside value 0.3.
    let out = runs.run(true, 0, 0, 9).unwrap();
    assert!((out - 10.0 * 0.7f64.ln()).abs() < 1e-12);
    assert!(runs.run(true, 0, 0, s.nx).is_none());
    assert!(runs.run(false, s.nx, 0, 1).is_none());
    assert!(runs.run(true, -1, 0, 1).is_none());
}
