//! Tests of the grid geodesic (8-connected Dijkstra, no corner cutting): distances against a
//! Bellman-Ford relaxation to a fixpoint, predecessors against a selection-order Dijkstra that
//! pops the smallest (distance, index) by linear scan, hand-made corner-cutting, unreachable and
//! blocked-start grids, and the refused inputs.

use crlam_core::planner::{geodesic, Geodesic};
use crlam_core::rng::Rng;
use crlam_core::CrlamError;

const SQRT2: f64 = std::f64::consts::SQRT_2;

/// The moves allowed out of cell `u`: (neighbour, step in cells). The same rule as the module,
/// written independently: in the grid, neighbour traversable, both side cells of a diagonal
/// traversable.
fn moves(trav: &[bool], ny: usize, nx: usize, u: usize) -> Vec<(usize, f64)> {
    let (y, x) = ((u / nx) as i64, (u % nx) as i64);
    let ok = |yy: i64, xx: i64| yy >= 0 && xx >= 0 && yy < ny as i64 && xx < nx as i64;
    let t = |yy: i64, xx: i64| trav[yy as usize * nx + xx as usize];
    let mut out = Vec::new();
    for dy in -1i64..=1 {
        for dx in -1i64..=1 {
            let (yy, xx) = (y + dy, x + dx);
            if (dy, dx) == (0, 0) || !ok(yy, xx) || !t(yy, xx) {
                continue;
            }
            if dy != 0 && dx != 0 {
                if !(t(y, xx) && t(yy, x)) {
                    continue;
                }
                out.push((yy as usize * nx + xx as usize, SQRT2));
            } else {
                out.push((yy as usize * nx + xx as usize, 1.0));
            }
        }
    }
    out
}

/// Bellman-Ford: relax every allowed move until nothing changes.
fn bellman_ford(trav: &[bool], ny: usize, nx: usize, s: usize, res: f64) -> Vec<f64> {
    let mut d = vec![f64::INFINITY; ny * nx];
    d[s] = 0.0;
    loop {
        let mut changed = false;
        for u in 0..ny * nx {
            if !d[u].is_finite() {
                continue;
            }
            for (v, c) in moves(trav, ny, nx, u) {
                // A margin keeps rounding differences between equal-length paths from looping.
                if d[u] + c * res < d[v] - 1e-12 {
                    d[v] = d[u] + c * res;
                    changed = true;
                }
            }
        }
        if !changed {
            return d;
        }
    }
}

/// Dijkstra that finalises the unfinalised reached cell with the smallest (distance, index) by
/// linear scan: the pop order of a heap of (d, u) tuples with stale entries skipped.
fn selection_dijkstra(trav: &[bool], ny: usize, nx: usize, s: usize, res: f64) -> Geodesic {
    let n = ny * nx;
    let mut dist = vec![f64::INFINITY; n];
    let mut pred = vec![-1i64; n];
    let mut done = vec![false; n];
    dist[s] = 0.0;
    loop {
        let next = (0..n)
            .filter(|&u| !done[u] && dist[u].is_finite())
            .min_by(|&a, &b| dist[a].total_cmp(&dist[b]).then(a.cmp(&b)));
        let Some(u) = next else { break };
        done[u] = true;
        for (v, c) in moves(trav, ny, nx, u) {
            let nd = dist[u] + c * res;
            if nd < dist[v] {
                dist[v] = nd;
                pred[v] = u as i64;
            }
        }
    }
    Geodesic { ny, nx, dist, pred }
}

fn random_grid(rng: &mut Rng, ny: usize, nx: usize, p_free: f64) -> Vec<bool> {
    (0..ny * nx).map(|_| rng.uniform() < p_free).collect()
}

#[test]
fn random_grids_match_brute_force() {
    let mut rng = Rng::new(7);
    let mut reached_some = 0;
    for trial in 0..300 {
        let ny = 1 + (rng.uniform() * 12.0) as usize;
        let nx = 1 + (rng.uniform() * 12.0) as usize;
        let p_free = 0.4 + 0.6 * rng.uniform();
        let trav = random_grid(&mut rng, ny, nx, p_free);
        let start = (
            (rng.uniform() * ny as f64) as i64,
            (rng.uniform() * nx as f64) as i64,
        );
        let res = [0.2, 0.05, 1.0, 0.3][trial % 4];
        let g = geodesic(&trav, ny, nx, start, res).unwrap();
        let s = start.0 as usize * nx + start.1 as usize;
        let bf = bellman_ford(&trav, ny, nx, s, res);
        for (k, (&d, &b)) in g.dist.iter().zip(&bf).enumerate() {
            assert_eq!(d.is_finite(), b.is_finite(), "trial {trial} cell {k}");
            if b.is_finite() {
                assert!((d - b).abs() < 1e-9, "trial {trial} cell {k}: {d} vs {b}");
            }
        }
        // Same pop order, same float operations: identical distances and predecessors.
        assert_eq!(
            g,
            selection_dijkstra(&trav, ny, nx, s, res),
            "trial {trial}"
        );
        // Every predecessor is an allowed move whose step gives the distance exactly.
        for v in 0..ny * nx {
            let p = g.pred[v];
            if v == s || !g.dist[v].is_finite() {
                assert_eq!(p, -1);
                continue;
            }
            let u = p as usize;
            let step = moves(&trav, ny, nx, u).into_iter().find(|&(w, _)| w == v);
            let (_, c) = step.unwrap_or_else(|| panic!("trial {trial}: {u} -> {v} is not a move"));
            assert_eq!(g.dist[v], g.dist[u] + c * res);
        }
        reached_some += usize::from(g.dist.iter().filter(|d| d.is_finite()).count() > 5);
    }
    // The random grids are not all trivially blocked.
    assert!(reached_some > 100, "{reached_some}");
}

#[test]
fn no_corner_cutting() {
    // 0 = blocked. The diagonal from (0, 0) to (1, 1) passes the corners of two blocked cells.
    let trav = [true, false, false, true];
    let g = geodesic(&trav, 2, 2, (0, 0), 0.2).unwrap();
    assert!(g.dist[3].is_infinite() && g.pred[3] == -1);
    // With one side open the robot goes around: two edge steps, not one diagonal.
    let trav = [true, true, false, true];
    let g = geodesic(&trav, 2, 2, (0, 0), 0.2).unwrap();
    assert_eq!(g.dist[3], 0.2 + 0.2);
    assert_eq!(g.pred[3], 1);
    assert_eq!(g.path(3), vec![(0, 0), (0, 1), (1, 1)]);
    // Both sides open: the diagonal.
    let g = geodesic(&[true; 4], 2, 2, (0, 0), 0.2).unwrap();
    assert_eq!(g.dist[3], SQRT2 * 0.2);
    assert_eq!(g.pred[3], 0);
}

#[test]
fn open_grid_distances() {
    // On an open grid the geodesic is the octile distance: max·res + (√2 − 1)·min·res.
    let (ny, nx, res) = (9, 13, 0.25);
    let g = geodesic(&vec![true; ny * nx], ny, nx, (4, 6), res).unwrap();
    for iy in 0..ny {
        for ix in 0..nx {
            let (a, b) = ((iy as f64 - 4.0).abs(), (ix as f64 - 6.0).abs());
            let octile = (a.max(b) + (SQRT2 - 1.0) * a.min(b)) * res;
            assert!(
                (g.dist[iy * nx + ix] - octile).abs() < 1e-12,
                "({iy}, {ix})"
            );
        }
    }
    assert_eq!(SQRT2, 2f64.sqrt());
}

#[test]
fn unreachable_cells_stay_infinite() {
    // A wall across column 2 splits a 4 x 5 grid.
    let (ny, nx) = (4, 5);
    let trav: Vec<bool> = (0..ny * nx).map(|k| k % nx != 2).collect();
    let g = geodesic(&trav, ny, nx, (0, 0), 0.2).unwrap();
    for k in 0..ny * nx {
        assert_eq!(g.dist[k].is_finite(), k % nx < 2, "cell {k}");
        if k % nx >= 2 {
            assert_eq!(g.pred[k], -1);
            assert!(g.path(k).is_empty());
        }
    }
    assert_eq!(g.path(3 * nx + 1).first(), Some(&(0, 0)));
}

#[test]
fn blocked_start_is_left_but_never_crossed() {
    // The robot's own cell may be blocked (it stands where the map is unsure): it still starts
    // there, and a blocked start is no side cell for diagonal moves.
    let mut trav = vec![true; 9];
    trav[4] = false;
    let g = geodesic(&trav, 3, 3, (1, 1), 0.2).unwrap();
    assert_eq!(g.dist[4], 0.0);
    assert_eq!(g.pred[4], -1);
    assert!(g.dist.iter().all(|d| d.is_finite()));
    assert_eq!(g.dist[0], SQRT2 * 0.2);
    // A lone blocked start with blocked neighbours reaches nothing else.
    let g = geodesic(&[false; 9], 3, 3, (1, 1), 0.2).unwrap();
    assert_eq!(g.dist.iter().filter(|d| d.is_finite()).count(), 1);
}

#[test]
fn refused_inputs() {
    let t = [true; 6];
    assert!(matches!(
        geodesic(&t, 2, 2, (0, 0), 0.2),
        Err(CrlamError::Shape(_))
    ));
    assert!(matches!(
        geodesic(&t, 2, 3, (2, 0), 0.2),
        Err(CrlamError::OutOfBounds(_))
    ));
    assert!(matches!(
        geodesic(&t, 2, 3, (0, 3), 0.2),
        Err(CrlamError::OutOfBounds(_))
    ));
    assert!(matches!(
        geodesic(&t, 2, 3, (-1, 0), 0.2),
        Err(CrlamError::OutOfBounds(_))
    ));
    assert!(matches!(
        geodesic(&[], 0, 0, (0, 0), 0.2),
        Err(CrlamError::OutOfBounds(_))
    ));
    for res in [0.0, -0.2, f64::NAN, f64::INFINITY] {
        assert!(
            matches!(
                geodesic(&t, 2, 3, (0, 0), res),
                Err(CrlamError::Config { .. })
            ),
            "{res}"
        );
    }
}
