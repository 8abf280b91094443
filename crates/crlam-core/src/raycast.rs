//! Exact grid traversal (Amanatides–Woo) with per-cell entry/exit distances.
//!
//! A ray `o + t·u` (unit `u`) is walked cell by cell for `t ∈ [t0, t1]`. Every visited cell is
//! reported with the ray parameters where the ray enters and leaves it, so chords sum to the
//! traversed length and the chord midpoint serves as the cause distance of the CRM model
//! (crm-spec 2.1). Cells touched only at a corner (chord < [`MIN_CHORD`]) are dropped.

use crate::grid::{floor_to_i64, CellRect, GridGeometry, MAX_CELL_INDEX};

mod walk;
pub use walk::{FastWalk, FastWalkParts, GridWalk, WalkCell};

/// Chords shorter than this (m) are corner grazes and are not reported.
pub const MIN_CHORD: f64 = 1e-9;

/// One traversed cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayCell {
    pub ix: i64,
    pub iy: i64,
    /// Ray parameter (m) where the ray enters the cell.
    pub t_in: f64,
    /// Ray parameter (m) where the ray leaves the cell (or stops).
    pub t_out: f64,
}

impl RayCell {
    /// Chord midpoint: the CRM cause distance `d_l`.
    #[inline]
    pub fn mid(&self) -> f64 {
        0.5 * (self.t_in + self.t_out)
    }
}

/// Intersection `[t_enter, t_exit]` of the ray with an axis-aligned box, if non-empty.
pub fn clip_to_box(o: [f64; 2], u: [f64; 2], lo: [f64; 2], hi: [f64; 2]) -> Option<(f64, f64)> {
    let mut t0 = f64::NEG_INFINITY;
    let mut t1 = f64::INFINITY;
    for a in 0..2 {
        if u[a] == 0.0 {
            if o[a] < lo[a] || o[a] >= hi[a] {
                return None;
            }
        } else {
            let inv = 1.0 / u[a];
            let (mut ta, mut tb) = ((lo[a] - o[a]) * inv, (hi[a] - o[a]) * inv);
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

/// World-space box of a cell rectangle.
pub fn rect_box(g: &GridGeometry, r: &CellRect) -> ([f64; 2], [f64; 2]) {
    (
        [
            g.origin[0] + r.ix0 as f64 * g.resolution,
            g.origin[1] + r.iy0 as f64 * g.resolution,
        ],
        [
            g.origin[0] + (r.ix0 + r.nx) as f64 * g.resolution,
            g.origin[1] + (r.iy0 + r.ny) as f64 * g.resolution,
        ],
    )
}

/// Walks the ray from `origin` in direction `angle` (rad) for `t ∈ [0, length]`, restricted to
/// `clip` when given, and calls `visit` for every cell in order. `visit` returns `false` to stop
/// early. Returns the parameter where the walk ended (≤ `length`; smaller if the ray left `clip`).
pub fn traverse_with<F: FnMut(RayCell) -> bool>(
    g: &GridGeometry,
    origin: [f64; 2],
    angle: f64,
    length: f64,
    clip: Option<&CellRect>,
    mut visit: F,
) -> f64 {
    let u = [angle.cos(), angle.sin()];
    let (mut t_start, mut t_end): (f64, f64) = (0.0, length.max(0.0));
    if let Some(r) = clip {
        let (lo, hi) = rect_box(g, r);
        match clip_to_box(origin, u, lo, hi) {
            Some((a, b)) => {
                t_start = t_start.max(a);
                t_end = t_end.min(b);
            }
            None => return 0.0,
        }
        if t_start >= t_end {
            return t_end.max(0.0).min(t_start);
        }
    }
    let res = g.resolution;
    let inv_res = 1.0 / res;
    // Local coordinates relative to the grid origin, in cells.
    let px = (origin[0] - g.origin[0] + t_start * u[0]) * inv_res;
    let py = (origin[1] - g.origin[1] + t_start * u[1]) * inv_res;
    // A ray from a non-finite or absurdly far point, in a non-finite direction or of unbounded
    // length crosses no cell: its indices would overflow and its walk would not end. (Poses
    // are checked before a scan; this guards direct callers.)
    let far = MAX_CELL_INDEX as f64;
    if !(px.abs() < far
        && py.abs() < far
        && u[0].is_finite()
        && u[1].is_finite()
        && (t_end - t_start) * inv_res < far)
    {
        return 0.0;
    }
    let mut ix = floor_to_i64(px);
    let mut iy = floor_to_i64(py);
    // When entering a clip box exactly on its far boundary the floor lands outside; pull back in.
    if let Some(r) = clip {
        ix = ix.clamp(r.ix0, r.ix0 + r.nx - 1);
        iy = iy.clamp(r.iy0, r.iy0 + r.ny - 1);
    }
    let step_x: i64 = if u[0] > 0.0 { 1 } else { -1 };
    let step_y: i64 = if u[1] > 0.0 { 1 } else { -1 };
    let ox = origin[0] - g.origin[0];
    let oy = origin[1] - g.origin[1];
    let inv_ux = if u[0] != 0.0 {
        1.0 / u[0]
    } else {
        f64::INFINITY
    };
    let inv_uy = if u[1] != 0.0 {
        1.0 / u[1]
    } else {
        f64::INFINITY
    };
    // Boundary crossings are recomputed from the cell index each step (no accumulated drift).
    let next_x = |ix: i64| -> f64 {
        if u[0] == 0.0 {
            f64::INFINITY
        } else {
            let b = (ix + i64::from(u[0] > 0.0)) as f64 * res;
            (b - ox) * inv_ux
        }
    };
    let next_y = |iy: i64| -> f64 {
        if u[1] == 0.0 {
            f64::INFINITY
        } else {
            let b = (iy + i64::from(u[1] > 0.0)) as f64 * res;
            (b - oy) * inv_uy
        }
    };
    let mut t_in = t_start;
    let mut tx = next_x(ix);
    let mut ty = next_y(iy);
    // Bounded loop: a ray of length L crosses at most L/res + 2 boundaries per axis.
    let max_steps = (2.0 * (t_end - t_start) * inv_res) as usize + 8;
    for _ in 0..max_steps {
        let t_out = tx.min(ty).min(t_end).max(t_in);
        if t_out - t_in >= MIN_CHORD
            && !visit(RayCell {
                ix,
                iy,
                t_in,
                t_out,
            })
        {
            return t_out;
        }
        if t_out >= t_end {
            return t_end;
        }
        if tx <= ty {
            ix += step_x;
            tx = next_x(ix);
        } else {
            iy += step_y;
            ty = next_y(iy);
        }
        t_in = t_out;
    }
    t_in
}

/// Collects the traversed cells into `out` (cleared first). See [`traverse_with`].
pub fn traverse(
    g: &GridGeometry,
    origin: [f64; 2],
    angle: f64,
    length: f64,
    clip: Option<&CellRect>,
    out: &mut Vec<RayCell>,
) -> f64 {
    out.clear();
    traverse_with(g, origin, angle, length, clip, |c| {
        out.push(c);
        true
    })
}

/// Distance from `origin` along `angle` to the entry of the first cell for which `occupied`
/// returns true, within `max_range`; `None` if there is none. Cells outside `clip` are free.
/// An occupied start cell gives 0.
pub fn first_hit<F: Fn(i64, i64) -> bool>(
    g: &GridGeometry,
    origin: [f64; 2],
    angle: f64,
    max_range: f64,
    clip: Option<&CellRect>,
    occupied: F,
) -> Option<f64> {
    let mut hit = None;
    traverse_with(g, origin, angle, max_range, clip, |c| {
        if occupied(c.ix, c.iy) {
            hit = Some(c.t_in.max(0.0));
            false
        } else {
            true
        }
    });
    hit
}

#[cfg(test)]
mod tests {
    use super::*;

    fn g() -> GridGeometry {
        GridGeometry::new([0.0, 0.0], 1.0).unwrap()
    }

    #[test]
    fn axis_aligned_ray() {
        let mut v = Vec::new();
        let end = traverse(&g(), [0.5, 0.5], 0.0, 3.0, None, &mut v);
        assert_eq!(end, 3.0);
        let ids: Vec<_> = v.iter().map(|c| (c.ix, c.iy)).collect();
        assert_eq!(ids, vec![(0, 0), (1, 0), (2, 0), (3, 0)]);
        assert!((v[0].t_out - 0.5).abs() < 1e-12);
        assert!((v[3].t_out - 3.0).abs() < 1e-12);
    }

    #[test]
    fn diagonal_through_corners_drops_grazed_cells() {
        let mut v = Vec::new();
        traverse(
            &g(),
            [0.5, 0.5],
            std::f64::consts::FRAC_PI_4,
            2.0 * 2f64.sqrt(),
            None,
            &mut v,
        );
        let total: f64 = v.iter().map(|c| c.t_out - c.t_in).sum();
        assert!((total - 2.0 * 2f64.sqrt()).abs() < 1e-9);
        for w in v.windows(2) {
            assert!((w[0].ix - w[1].ix).abs() <= 1 && (w[0].iy - w[1].iy).abs() <= 1);
        }
    }

    #[test]
    fn clip_stops_at_the_box() {
        let r = CellRect {
            ix0: 0,
            iy0: 0,
            nx: 2,
            ny: 2,
        };
        let mut v = Vec::new();
        let end = traverse(&g(), [0.5, 0.5], 0.0, 10.0, Some(&r), &mut v);
        assert!((end - 1.5).abs() < 1e-12);
        assert_eq!(v.len(), 2);
        // From outside the box: entry at t = 1.5.
        let end = traverse(&g(), [-1.0, 0.5], 0.0, 10.0, Some(&r), &mut v);
        assert!((v[0].t_in - 1.0).abs() < 1e-12);
        assert!((end - 3.0).abs() < 1e-12);
    }

    #[test]
    fn first_hit_is_the_entry_distance() {
        let d = first_hit(&g(), [0.25, 0.5], 0.0, 10.0, None, |ix, _| ix == 3).unwrap();
        assert!((d - 2.75).abs() < 1e-12);
        assert_eq!(
            first_hit(&g(), [0.25, 0.5], 0.0, 2.0, None, |ix, _| ix == 3),
            None
        );
        assert_eq!(
            first_hit(&g(), [0.25, 0.5], 0.0, 2.0, None, |ix, _| ix == 0),
            Some(0.0)
        );
    }
}
