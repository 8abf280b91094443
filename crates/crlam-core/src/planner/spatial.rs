//! A uniform bucket grid over 2-D points with exact nearest-neighbour and radius queries
//! (planner-spec 3.11 \[CLEAN\]: an incremental structure instead of rebuilding a kd-tree after
//! every insertion). Used for the tree nodes and for the obstacle points.
//!
//! Every answer is exact (distances are compared directly, the grid only prunes), and ties are
//! broken by the lower point index, so results never depend on the bucket size.

use crate::error::{config_err, CrlamError, Result};

/// Points in a fixed axis-aligned box, bucketed by square cells. Insertion is O(1).
#[derive(Clone, Debug)]
pub struct PointGrid {
    lo: [f64; 2],
    hi: [f64; 2],
    cell: f64,
    nx: usize,
    ny: usize,
    /// Point indices per bucket (index `a + b·nx`), in insertion order.
    buckets: Vec<Vec<u32>>,
    points: Vec<[f64; 2]>,
}

/// Relative slack on the ring lower bound, so that rounding in a computed distance can never
/// stop a nearest search one ring too early.
const BOUND_SLACK: f64 = 1e-9;

impl PointGrid {
    /// An empty grid over the box `[lo, hi]` (m) with square buckets of side `cell` (m). At most
    /// 2²⁴ buckets.
    pub fn new(lo: [f64; 2], hi: [f64; 2], cell: f64) -> Result<Self> {
        for v in [lo[0], lo[1], hi[0], hi[1]] {
            if !v.is_finite() {
                return Err(CrlamError::NonFinite {
                    field: "grid_box",
                    value: v,
                });
            }
        }
        if !(cell.is_finite() && cell > 0.0) {
            return Err(config_err("cell", format!("must be > 0, got {cell}")));
        }
        if hi[0] < lo[0] || hi[1] < lo[1] {
            return Err(config_err("grid_box", "hi must be ≥ lo"));
        }
        // floor + 1 buckets so that lo + n·cell > hi: every point of the box has a bucket.
        let count = |span: f64| (span / cell).floor() + 1.0;
        let (fx, fy) = (count(hi[0] - lo[0]), count(hi[1] - lo[1]));
        if fx * fy > (1u64 << 24) as f64 {
            return Err(config_err(
                "cell",
                format!("{fx} x {fy} buckets is too many; use a larger cell"),
            ));
        }
        let (nx, ny) = (fx as usize, fy as usize);
        Ok(Self {
            lo,
            hi,
            cell,
            nx,
            ny,
            buckets: vec![Vec::new(); nx * ny],
            points: Vec::new(),
        })
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether there is no point (candidate).
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The points (m), in insertion order.
    pub fn points(&self) -> &[[f64; 2]] {
        &self.points
    }

    /// Bucket coordinate of `v` along an axis, clamped to `[0, n − 1]`.
    #[inline]
    fn bucket_1d(&self, v: f64, axis: usize) -> usize {
        let n = if axis == 0 { self.nx } else { self.ny };
        let k = ((v - self.lo[axis]) / self.cell).floor();
        if k <= 0.0 {
            0
        } else {
            (k as usize).min(n - 1)
        }
    }

    /// Adds a point (it must lie in the box) and returns its index.
    pub fn insert(&mut self, p: [f64; 2]) -> Result<usize> {
        let inside = (0..2).all(|k| p[k] >= self.lo[k] && p[k] <= self.hi[k]);
        if !inside {
            return Err(CrlamError::OutOfBounds(format!(
                "point ({}, {}) outside the index box [{:?}, {:?}]",
                p[0], p[1], self.lo, self.hi
            )));
        }
        if self.points.len() >= u32::MAX as usize {
            return Err(config_err("points", "too many points"));
        }
        let id = self.points.len();
        let b = self.bucket_1d(p[0], 0) + self.bucket_1d(p[1], 1) * self.nx;
        self.buckets[b].push(id as u32);
        self.points.push(p);
        Ok(id)
    }

    #[inline]
    fn dist2(&self, q: [f64; 2], id: usize) -> f64 {
        let p = self.points[id];
        let (dx, dy) = (p[0] - q[0], p[1] - q[1]);
        dx * dx + dy * dy
    }

    /// The nearest point to `q` among those with `accept(index)`, ties to the lower index, with
    /// its squared distance (m²). `None` when no point is accepted.
    pub fn nearest(&self, q: [f64; 2], accept: impl Fn(usize) -> bool) -> Option<(usize, f64)> {
        let (ca, cb) = (
            self.bucket_1d(q[0], 0) as i64,
            self.bucket_1d(q[1], 1) as i64,
        );
        let mut best: Option<(usize, f64)> = None;
        let max_ring = self.nx.max(self.ny) as i64;
        for r in 0..=max_ring {
            let mut visit = |a: i64, b: i64| {
                if a < 0 || b < 0 || a >= self.nx as i64 || b >= self.ny as i64 {
                    return;
                }
                for &id in &self.buckets[a as usize + b as usize * self.nx] {
                    let id = id as usize;
                    if !accept(id) {
                        continue;
                    }
                    let d2 = self.dist2(q, id);
                    let better = match best {
                        None => true,
                        Some((bi, bd)) => d2 < bd || (d2 == bd && id < bi),
                    };
                    if better {
                        best = Some((id, d2));
                    }
                }
            };
            if r == 0 {
                visit(ca, cb);
            } else {
                for a in (ca - r)..=(ca + r) {
                    visit(a, cb - r);
                    visit(a, cb + r);
                }
                for b in (cb - r + 1)..=(cb + r - 1) {
                    visit(ca - r, b);
                    visit(ca + r, b);
                }
            }
            // Buckets of ring ≥ r + 1 lie at least r cells away from q (also when q is outside
            // the box and was clamped), so a strictly closer point ends the search.
            let bound = r as f64 * self.cell;
            if let Some((_, bd)) = best {
                if bd < bound * bound * (1.0 - BOUND_SLACK) {
                    break;
                }
            }
        }
        best
    }

    /// The bucket ranges that overlap the square of half-side `r` around `q`, if any.
    fn overlap(&self, q: [f64; 2], r: f64) -> Option<([usize; 2], [usize; 2])> {
        let outside = (0..2).any(|k| q[k] + r < self.lo[k] || q[k] - r > self.hi[k]);
        if outside || self.points.is_empty() {
            return None;
        }
        Some((
            [self.bucket_1d(q[0] - r, 0), self.bucket_1d(q[0] + r, 0)],
            [self.bucket_1d(q[1] - r, 1), self.bucket_1d(q[1] + r, 1)],
        ))
    }

    /// All points within distance `r` (m) of `q` (distance ≤ r), sorted by distance then index,
    /// as (index, squared distance (m²)). Clears `out` first.
    pub fn within(&self, q: [f64; 2], r: f64, out: &mut Vec<(usize, f64)>) {
        out.clear();
        let Some((xs, ys)) = self.overlap(q, r) else {
            return;
        };
        let r2 = r * r;
        for b in ys[0]..=ys[1] {
            for a in xs[0]..=xs[1] {
                for &id in &self.buckets[a + b * self.nx] {
                    let d2 = self.dist2(q, id as usize);
                    if d2 <= r2 {
                        out.push((id as usize, d2));
                    }
                }
            }
        }
        out.sort_unstable_by(|x, y| x.1.total_cmp(&y.1).then(x.0.cmp(&y.0)));
    }

    /// Whether any point lies within distance `r` (m) of `q` (distance ≤ r).
    pub fn any_within(&self, q: [f64; 2], r: f64) -> bool {
        let Some((xs, ys)) = self.overlap(q, r) else {
            return false;
        };
        let r2 = r * r;
        (ys[0]..=ys[1]).any(|b| {
            (xs[0]..=xs[1]).any(|a| {
                self.buckets[a + b * self.nx]
                    .iter()
                    .any(|&id| self.dist2(q, id as usize) <= r2)
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    #[test]
    fn queries_match_brute_force() {
        let mut rng = Rng::new(5);
        for cell in [0.3, 1.0, 7.0] {
            let mut g = PointGrid::new([-1.0, -1.0], [21.0, 21.0], cell).unwrap();
            for k in 0..400 {
                // Points on a coarse lattice give many exact distance ties.
                let p = if k % 2 == 0 {
                    [
                        (22.0 * rng.uniform()).floor() - 1.0,
                        (rng.uniform() * 22.0).floor() - 1.0,
                    ]
                } else {
                    [-1.0 + 22.0 * rng.uniform(), -1.0 + 22.0 * rng.uniform()]
                };
                g.insert(p).unwrap();
            }
            let mut out = Vec::new();
            for _ in 0..300 {
                let q = [-5.0 + 30.0 * rng.uniform(), -5.0 + 30.0 * rng.uniform()];
                let q = if rng.uniform() < 0.3 {
                    [q[0].round(), q[1].round()]
                } else {
                    q
                };
                let d2 = |i: usize| {
                    let p = g.points()[i];
                    (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)
                };
                let kept = |i: usize| i % 3 != 1;
                let brute = (0..g.len())
                    .filter(|&i| kept(i))
                    .min_by(|&a, &b| d2(a).total_cmp(&d2(b)).then(a.cmp(&b)))
                    .unwrap();
                assert_eq!(g.nearest(q, kept).unwrap().0, brute);
                let r = 3.0 * rng.uniform();
                g.within(q, r, &mut out);
                let mut want: Vec<_> = (0..g.len()).filter(|&i| d2(i) <= r * r).collect();
                want.sort_by(|&a, &b| d2(a).total_cmp(&d2(b)).then(a.cmp(&b)));
                assert_eq!(out.iter().map(|x| x.0).collect::<Vec<_>>(), want);
                assert_eq!(g.any_within(q, r), !want.is_empty());
            }
        }
    }

    #[test]
    fn refuses_points_outside_and_empty_grid_answers_none() {
        let mut g = PointGrid::new([0.0, 0.0], [1.0, 1.0], 0.5).unwrap();
        assert!(g.nearest([0.5, 0.5], |_| true).is_none());
        assert!(!g.any_within([0.5, 0.5], 10.0));
        assert!(g.insert([1.5, 0.5]).is_err());
        assert!(g.insert([f64::NAN, 0.5]).is_err());
        assert_eq!(g.insert([1.0, 1.0]).unwrap(), 0);
        assert_eq!(g.nearest([-100.0, 50.0], |_| true).unwrap().0, 0);
        assert!(PointGrid::new([0.0, 0.0], [1.0, 1.0], 0.0).is_err());
        assert!(PointGrid::new([0.0, 0.0], [1e9, 1e9], 1e-3).is_err());
    }
}
