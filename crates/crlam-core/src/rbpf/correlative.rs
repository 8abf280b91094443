//! Correlative scan matching over a wide window of poses (Olson 2009, "Real-time correlative
//! scan matching"), searched by branch and bound over max-pooled copies of a likelihood field
//! (Hess, Kohler, Rapp and Andor 2016, Cartographer's fast correlative matcher).
//!
//! GMapping's hill climb ([`super::ScanMatcher::optimize`]) finds the pose only within a few
//! centimetres and degrees of where it starts. When the odometry is off by more between two
//! processed scans (a sharp turn, wheel slip, a laser stamped late), every particle climbs from
//! the same wrong start and the map breaks. This search looks at every pose of a window around
//! the odometry's guess (±`linear_window` in x and y, ±`angular_window` in heading) at a cost of
//! a small share of them:
//!
//! 1. a [`LikelihoodField`] over the part of the map the scan can reach: each cell holds
//!    exp(−d²/2σ²), d the distance between its centre and the nearest occupied cell's centre,
//!    σ one cell, 0 beyond [`FIELD_RADIUS`] cells;
//! 2. coarser copies of it: level h holds at each cell the maximum of level 0 over the
//!    2^h × 2^h cells from that cell up and right, so the scan read on level h at a translation
//!    bounds from above its score at every translation of the block that starts there;
//! 3. for every heading of the window, in steps small enough that the farthest endpoint moves at
//!    most one cell, the translations are searched depth first, best bound first, and a block
//!    whose bound cannot beat the best pose found so far is never opened.
//!
//! The score of a pose is the mean field value under the scan's endpoints minus a penalty for
//! leaving the guess, `penalty · ((|Δt| / linear_window)² + (Δθ / angular_window)²)`: at the
//! window's edge a pose must explain a share `penalty` more of the scan than at the guess, so in a
//! featureless corridor the guess stands. The search returns the best pose on the lattice of
//! whole cells and heading steps; the particles' hill climbs refine it.

use crate::error::{config_err, CrlamError, Result};
use crate::grid::{CellRect, GridGeometry};
use crate::pose::{wrap, Pose};

/// Cells around an occupied cell that its likelihood reaches (the field is 0 farther away).
pub const FIELD_RADIUS: i64 = 2;
/// Most cells on a side of the field (the scan's reach plus the window, in cells); a scan that
/// would need more uses only its endpoints within the reach this allows.
const MAX_FIELD_SIDE: i64 = 2048;
/// Most headings searched (a window so wide, or endpoints so far, that steps of one cell at the
/// farthest endpoint would need more, is searched at the coarser step this allows).
const MAX_HEADINGS: usize = 721;
/// Deepest level of the max-pooled field (blocks of 2^5 = 32 cells on a side).
const MAX_DEPTH: usize = 5;

/// Settings of the correlative search in front of the scan-match proposal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CorrelativeSettings {
    /// Half-width of the translation window (m), in world x and y.
    pub linear_window: f64,
    /// Half-width of the heading window (rad).
    pub angular_window: f64,
    /// Share of a perfect score lost at the window's edge (see the module documentation).
    pub penalty: f64,
    /// The search's match replaces the odometry's guess only when the share of the scan's
    /// endpoints it explains (its unpenalised mean field value) is at least this...
    pub min_score: f64,
    /// ...and its penalised score exceeds the guess's by at least this.
    pub min_gain: f64,
}

impl Default for CorrelativeSettings {
    /// ±0.4 m and ±20° (0.35 rad): what a sharp turn, a slipping wheel or a laser 0.15 s late
    /// do to odometry between two processed scans; a 5 % penalty at the edge; a match must
    /// explain a quarter of the scan and beat the guess by 5 % of it.
    fn default() -> Self {
        Self {
            linear_window: 0.4,
            angular_window: 0.35,
            penalty: 0.05,
            min_score: 0.25,
            min_gain: 0.05,
        }
    }
}

impl CorrelativeSettings {
    pub fn validate(&self) -> Result<()> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !(positive(self.linear_window) && self.linear_window <= 10.0) {
            return Err(config_err(
                "correlative.linear_window",
                format!("must be in (0, 10] m, got {}", self.linear_window),
            ));
        }
        if !(positive(self.angular_window) && self.angular_window <= std::f64::consts::PI) {
            return Err(config_err(
                "correlative.angular_window",
                format!("must be in (0, pi] rad, got {}", self.angular_window),
            ));
        }
        for (name, v) in [
            ("correlative.penalty", self.penalty),
            ("correlative.min_score", self.min_score),
            ("correlative.min_gain", self.min_gain),
        ] {
            if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
                return Err(config_err(name, format!("must be in [0, 1], got {v}")));
            }
        }
        Ok(())
    }
}

/// The likelihood field of a map's occupied cells and its max-pooled levels (see the module
/// documentation).
#[derive(Clone, Debug)]
pub struct LikelihoodField {
    geometry: GridGeometry,
    rect: CellRect,
    /// `levels[h]`, row-major over `rect`: level 0 the field, level h the maximum of level 0
    /// over the 2^h × 2^h block from each cell up and right (cells outside `rect` read 0).
    levels: Vec<Vec<f32>>,
}

impl LikelihoodField {
    /// The field of the cells of `rect` that `occupied` (row-major over `rect`) marks, with
    /// levels up to `depth` (at most `MAX_DEPTH`, 5).
    pub fn new(
        geometry: GridGeometry,
        rect: CellRect,
        occupied: &[bool],
        depth: usize,
    ) -> Result<Self> {
        rect.validate()?;
        if rect.nx > MAX_FIELD_SIDE || rect.ny > MAX_FIELD_SIDE {
            return Err(CrlamError::Shape(format!(
                "a likelihood field of {} x {} cells exceeds {MAX_FIELD_SIDE} on a side",
                rect.nx, rect.ny
            )));
        }
        if occupied.len() != rect.n_cells() {
            return Err(CrlamError::Shape(format!(
                "{} occupancy flags for a field of {} cells",
                occupied.len(),
                rect.n_cells()
            )));
        }
        let (nx, ny) = (rect.nx as usize, rect.ny as usize);
        let r = FIELD_RADIUS;
        // exp(−d²/2) for the squared offsets (in cells) the radius reaches.
        let kernel: Vec<(i64, i64, f32)> = (-r..=r)
            .flat_map(|dy| (-r..=r).map(move |dx| (dx, dy)))
            .filter(|&(dx, dy)| dx * dx + dy * dy <= r * r)
            .map(|(dx, dy)| (dx, dy, (-0.5 * (dx * dx + dy * dy) as f64).exp() as f32))
            .collect();
        let mut field = vec![0.0f32; nx * ny];
        for (i, _) in occupied.iter().enumerate().filter(|(_, &o)| o) {
            let (x, y) = ((i % nx) as i64, (i / nx) as i64);
            for &(dx, dy, v) in &kernel {
                let (cx, cy) = (x + dx, y + dy);
                if cx < 0 || cy < 0 || cx >= nx as i64 || cy >= ny as i64 {
                    continue;
                }
                let c = &mut field[cy as usize * nx + cx as usize];
                *c = c.max(v);
            }
        }
        let mut levels = vec![field];
        for h in 1..=depth.min(MAX_DEPTH) {
            let s = 1usize << (h - 1);
            let prev = &levels[h - 1];
            let at = |x: usize, y: usize| {
                if x < nx && y < ny {
                    prev[y * nx + x]
                } else {
                    0.0
                }
            };
            let mut next = vec![0.0f32; nx * ny];
            for y in 0..ny {
                for x in 0..nx {
                    next[y * nx + x] = at(x, y)
                        .max(at(x + s, y))
                        .max(at(x, y + s).max(at(x + s, y + s)));
                }
            }
            levels.push(next);
        }
        Ok(Self {
            geometry,
            rect,
            levels,
        })
    }

    /// Deepest level kept.
    pub fn depth(&self) -> usize {
        self.levels.len() - 1
    }

    /// Value of level `h` at cell (ix, iy) of the map (0 outside the field).
    #[inline]
    pub fn value(&self, h: usize, ix: i64, iy: i64) -> f32 {
        let (x, y) = (ix - self.rect.ix0, iy - self.rect.iy0);
        if x < 0 || y < 0 || x >= self.rect.nx || y >= self.rect.ny {
            return 0.0;
        }
        self.levels[h][(y * self.rect.nx + x) as usize]
    }

    pub fn geometry(&self) -> &GridGeometry {
        &self.geometry
    }
}

/// The result of a search.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CorrelativeMatch {
    /// The best pose of the window's lattice (the guess when none beats it).
    pub pose: Pose,
    /// Its penalised score.
    pub score: f64,
    /// Its mean field value under the endpoints (the share of the scan it explains).
    pub explained: f64,
    /// The mean field value at the guess.
    pub guess_score: f64,
    /// Lattice poses whose score was evaluated exactly (for the cost of a search).
    pub evaluated: usize,
}

impl CorrelativeMatch {
    /// Whether the match should replace the guess (`settings.min_score`, `settings.min_gain`).
    pub fn is_confident(&self, settings: &CorrelativeSettings) -> bool {
        self.explained >= settings.min_score && self.score >= self.guess_score + settings.min_gain
    }
}

/// The rectangle of cells a search around `guess` reads: the endpoints' reach (at most
/// `max_reach` m) plus the translation window and the field's radius.
pub fn field_rect(
    geometry: &GridGeometry,
    guess: Pose,
    max_reach: f64,
    settings: &CorrelativeSettings,
) -> Result<CellRect> {
    let res = geometry.resolution;
    let half = ((max_reach + settings.linear_window) / res).ceil() as i64 + FIELD_RADIUS + 1;
    let half = half.min(MAX_FIELD_SIDE / 2 - 1);
    let (cx, cy) = geometry.cell_of(guess[0], guess[1]);
    CellRect::checked(cx - half, cy - half, 2 * half + 1, 2 * half + 1)
}

/// The pooled depth a window of `w` cells on each side of the guess needs: the top blocks
/// (2^depth cells) tile the 2w + 1 translations in a few blocks per axis.
pub fn depth_for_window(w: i64) -> usize {
    let mut depth = 0;
    while depth < MAX_DEPTH && (1i64 << (depth + 1)) <= w {
        depth += 1;
    }
    depth
}

/// Searches the window of `settings` around `guess` for the pose at which the `endpoints`
/// (robot frame, m) score best on `field` (see the module documentation).
pub fn search(
    field: &LikelihoodField,
    endpoints: &[[f64; 2]],
    guess: Pose,
    settings: &CorrelativeSettings,
) -> Result<CorrelativeMatch> {
    search_excluding(field, endpoints, guess, settings, None)
}

/// As [`search`], with the translations within `exclude.1` m of the point `exclude.0` (world
/// frame, every heading) left out: the best pose *elsewhere*, to tell a unique match from one of
/// a corridor's look-alikes (loop closing's ambiguity test). When every pose is excluded, the
/// guess is returned with a score of 0.
pub fn search_excluding(
    field: &LikelihoodField,
    endpoints: &[[f64; 2]],
    guess: Pose,
    settings: &CorrelativeSettings,
    exclude: Option<([f64; 2], f64)>,
) -> Result<CorrelativeMatch> {
    settings.validate()?;
    crate::grid::check_pose(guess)?;
    let g = *field.geometry();
    let res = g.resolution;
    let far = field_reach(field, guess) - settings.linear_window;
    let points: Vec<[f64; 2]> = endpoints
        .iter()
        .copied()
        .filter(|e| e[0].is_finite() && e[1].is_finite() && e[0].hypot(e[1]) <= far)
        .collect();
    let n = points.len();
    let guess_match = CorrelativeMatch {
        pose: guess,
        score: 0.0,
        explained: 0.0,
        guess_score: 0.0,
        evaluated: 0,
    };
    if n == 0 {
        return Ok(guess_match);
    }
    let r_max = points.iter().map(|e| e[0].hypot(e[1])).fold(res, f64::max);
    // Headings: the farthest endpoint moves at most one cell per step.
    let step = (res / r_max).min(settings.angular_window);
    let n_side = ((settings.angular_window / step).ceil() as usize).min(MAX_HEADINGS / 2);
    let dtheta = settings.angular_window / n_side as f64;
    let w = (settings.linear_window / res).ceil() as i64;
    let depth = field.depth();
    let inv_n = 1.0 / n as f64;
    // Cells of every endpoint at every heading, the translation (0, 0) being the guess.
    let headings: Vec<(f64, Vec<(i64, i64)>)> = (-(n_side as i64)..=n_side as i64)
        .map(|k| {
            let t = k as f64 * dtheta;
            let (s, c) = (guess[2] + t).sin_cos();
            let cells = points
                .iter()
                .map(|e| {
                    g.cell_of(
                        guess[0] + c * e[0] - s * e[1],
                        guess[1] + s * e[0] + c * e[1],
                    )
                })
                .collect();
            (t, cells)
        })
        .collect();
    let penalty = |t: f64, dx2: f64| {
        settings.penalty
            * (dx2 * res * res / (settings.linear_window * settings.linear_window)
                + (t * t) / (settings.angular_window * settings.angular_window))
    };
    let mean_at = |h: usize, cells: &[(i64, i64)], dx: i64, dy: i64| -> f64 {
        let s: f32 = cells
            .iter()
            .map(|&(ix, iy)| field.value(h, ix + dx, iy + dy))
            .sum();
        s as f64 * inv_n
    };
    // The nearest translation to 0 in [lo, hi] along one axis, squared.
    let nearest2 = |lo: i64, hi: i64| -> f64 {
        let d = if lo > 0 {
            lo
        } else if hi < 0 {
            -hi
        } else {
            0
        };
        (d * d) as f64
    };
    // The excluded disc in lattice units (translations from the guess, in cells).
    let excluded =
        exclude.map(|(c, r)| ((c[0] - guess[0]) / res, (c[1] - guess[1]) / res, r / res));
    let inside = |dx: f64, dy: f64| {
        excluded.is_some_and(|(cx, cy, r)| (dx - cx).powi(2) + (dy - cy).powi(2) <= r * r)
    };
    // Whether every translation of the block [dx0, dx0 + side) × [dy0, dy0 + side) is excluded.
    let block_excluded = |dx0: i64, dy0: i64, side: i64| {
        let (x0, y0, x1, y1) = (
            dx0 as f64,
            dy0 as f64,
            (dx0 + side - 1) as f64,
            (dy0 + side - 1) as f64,
        );
        inside(x0, y0) && inside(x1, y0) && inside(x0, y1) && inside(x1, y1)
    };
    let centre = n_side;
    let guess_score = if inside(0.0, 0.0) {
        0.0
    } else {
        mean_at(0, &headings[centre].1, 0, 0)
    };
    let mut best = CorrelativeMatch {
        score: guess_score,
        explained: guess_score,
        guess_score,
        evaluated: 1,
        ..guess_match
    };
    // A node: (upper bound, heading index, level, dx0, dy0) covering the translations
    // [dx0, dx0 + 2^level) × [dy0, dy0 + 2^level) clipped to the window.
    type Node = (f64, usize, usize, i64, i64);
    let bound = |k: usize, h: usize, dx0: i64, dy0: i64| -> f64 {
        let side = 1i64 << h;
        let (hx, hy) = ((dx0 + side - 1).min(w), (dy0 + side - 1).min(w));
        mean_at(h, &headings[k].1, dx0, dy0)
            - penalty(headings[k].0, nearest2(dx0, hx) + nearest2(dy0, hy))
    };
    let top = 1i64 << depth;
    let mut roots: Vec<Node> = Vec::new();
    for k in 0..headings.len() {
        let mut dy0 = -w;
        while dy0 <= w {
            let mut dx0 = -w;
            while dx0 <= w {
                roots.push((bound(k, depth, dx0, dy0), k, depth, dx0, dy0));
                dx0 += top;
            }
            dy0 += top;
        }
    }
    roots.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut stack: Vec<Node> = Vec::new();
    for root in roots {
        if root.0 <= best.score {
            break;
        }
        stack.push(root);
        while let Some((b, k, h, dx0, dy0)) = stack.pop() {
            if b <= best.score || (excluded.is_some() && block_excluded(dx0, dy0, 1i64 << h)) {
                continue;
            }
            if h == 0 {
                // A single translation: the bound is its exact score.
                best.evaluated += 1;
                let t = headings[k].0;
                best.score = b;
                best.explained = b + penalty(t, (dx0 * dx0 + dy0 * dy0) as f64);
                best.pose = [
                    guess[0] + dx0 as f64 * res,
                    guess[1] + dy0 as f64 * res,
                    wrap(guess[2] + t),
                ];
                continue;
            }
            let half = 1i64 << (h - 1);
            let mut children: Vec<Node> = Vec::with_capacity(4);
            for (ox, oy) in [(0, 0), (half, 0), (0, half), (half, half)] {
                let (cx, cy) = (dx0 + ox, dy0 + oy);
                if cx > w || cy > w {
                    continue;
                }
                children.push((bound(k, h - 1, cx, cy), k, h - 1, cx, cy));
            }
            // Pushed worst first so that the best child is opened next.
            children.sort_by(|a, b| a.0.total_cmp(&b.0));
            stack.extend(children.into_iter().filter(|c| c.0 > best.score));
        }
    }
    Ok(best)
}

/// The farthest an endpoint may lie from `guess` and still fall inside the field at every pose
/// of a search (endpoints beyond read 0 anyway; leaving them out keeps the score's share honest).
fn field_reach(field: &LikelihoodField, guess: Pose) -> f64 {
    let g = field.geometry();
    let r = &field.rect;
    let res = g.resolution;
    let x0 = g.origin[0] + r.ix0 as f64 * res;
    let y0 = g.origin[1] + r.iy0 as f64 * res;
    let x1 = x0 + r.nx as f64 * res;
    let y1 = y0 + r.ny as f64 * res;
    (guess[0] - x0)
        .min(x1 - guess[0])
        .min(guess[1] - y0)
        .min(y1 - guess[1])
        .max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn geometry() -> GridGeometry {
        GridGeometry::new([-10.0, -10.0], 0.1).unwrap()
    }

    /// An L-shaped room with a pillar, as occupied flags over `rect`.
    fn room(g: &GridGeometry, rect: CellRect) -> Vec<bool> {
        let mut occ = vec![false; rect.n_cells()];
        let mut mark = |x: f64, y: f64| {
            let (ix, iy) = g.cell_of(x, y);
            let (lx, ly) = (ix - rect.ix0, iy - rect.iy0);
            if lx >= 0 && ly >= 0 && lx < rect.nx && ly < rect.ny {
                occ[(ly * rect.nx + lx) as usize] = true;
            }
        };
        for i in 0..=120 {
            let t = i as f64 * 0.05;
            mark(-3.0 + t, -2.0); // bottom wall, x in [-3, 3]
            mark(-3.0, -2.0 + t * 0.75); // left wall, y in [-2, 2.5]
            mark(3.0, -2.0 + t * 0.5); // right wall, y in [-2, 1]
            mark(-3.0 + t * 0.5, 2.5); // top wall, x in [-3, 0]
        }
        for i in 0..=60 {
            let t = i as f64 * 0.05;
            mark(0.0 + t, 1.0); // a step in the top wall
            mark(0.0, 1.0 + t * 0.5);
        }
        mark(1.0, 0.0);
        mark(1.05, 0.05);
        occ
    }

    /// Endpoints (robot frame) of a simulated scan from `pose` against the room's walls, by
    /// marching rays on the occupied flags.
    fn scan(g: &GridGeometry, rect: CellRect, occ: &[bool], pose: Pose) -> Vec<[f64; 2]> {
        let hit = |x: f64, y: f64| {
            let (ix, iy) = g.cell_of(x, y);
            let (lx, ly) = (ix - rect.ix0, iy - rect.iy0);
            lx >= 0 && ly >= 0 && lx < rect.nx && ly < rect.ny && occ[(ly * rect.nx + lx) as usize]
        };
        let mut out = Vec::new();
        for b in 0..180 {
            let a = -std::f64::consts::PI + b as f64 * 2.0 * std::f64::consts::PI / 180.0;
            let (s, c) = (pose[2] + a).sin_cos();
            let mut r = 0.05;
            while r < 8.0 {
                if hit(pose[0] + c * r, pose[1] + s * r) {
                    out.push([r * a.cos(), r * a.sin()]);
                    break;
                }
                r += 0.01;
            }
        }
        out
    }

    fn brute_force(
        field: &LikelihoodField,
        endpoints: &[[f64; 2]],
        guess: Pose,
        settings: &CorrelativeSettings,
    ) -> (Pose, f64) {
        let g = field.geometry();
        let res = g.resolution;
        let r_max = endpoints
            .iter()
            .map(|e| e[0].hypot(e[1]))
            .fold(res, f64::max);
        let step = (res / r_max).min(settings.angular_window);
        let n_side = (settings.angular_window / step).ceil() as i64;
        let dtheta = settings.angular_window / n_side as f64;
        let w = (settings.linear_window / res).ceil() as i64;
        let mut best = (guess, f64::NEG_INFINITY);
        for k in -n_side..=n_side {
            let t = k as f64 * dtheta;
            let (s, c) = (guess[2] + t).sin_cos();
            let cells: Vec<(i64, i64)> = endpoints
                .iter()
                .map(|e| {
                    g.cell_of(
                        guess[0] + c * e[0] - s * e[1],
                        guess[1] + s * e[0] + c * e[1],
                    )
                })
                .collect();
            for dy in -w..=w {
                for dx in -w..=w {
                    let sum: f32 = cells
                        .iter()
                        .map(|&(ix, iy)| field.value(0, ix + dx, iy + dy))
                        .sum();
                    let score = sum as f64 / endpoints.len() as f64
                        - settings.penalty
                            * (((dx * dx + dy * dy) as f64 * res * res)
                                / settings.linear_window.powi(2)
                                + t * t / settings.angular_window.powi(2));
                    if score > best.1 {
                        best = (
                            [
                                guess[0] + dx as f64 * res,
                                guess[1] + dy as f64 * res,
                                wrap(guess[2] + t),
                            ],
                            score,
                        );
                    }
                }
            }
        }
        best
    }

    fn setup(
        truth: Pose,
        guess: Pose,
        settings: &CorrelativeSettings,
    ) -> (LikelihoodField, Vec<[f64; 2]>) {
        let g = geometry();
        let rect = field_rect(&g, guess, 8.0, settings).unwrap();
        let occ = room(&g, rect);
        let w = (settings.linear_window / g.resolution).ceil() as i64;
        let field = LikelihoodField::new(g, rect, &occ, depth_for_window(w)).unwrap();
        let endpoints = scan(&g, rect, &occ, truth);
        (field, endpoints)
    }

    /// Branch and bound finds the brute force's best score (the same pose unless two tie).
    #[test]
    fn branch_and_bound_equals_brute_force() {
        let settings = CorrelativeSettings::default();
        let truth = [0.23, -0.41, 0.3];
        for (i, guess) in [
            [0.23, -0.41, 0.3],
            [0.5, -0.2, 0.55],
            [-0.1, -0.6, 0.0],
            [0.4, -0.1, 0.62],
        ]
        .into_iter()
        .enumerate()
        {
            let (field, endpoints) = setup(truth, guess, &settings);
            let got = search(&field, &endpoints, guess, &settings).unwrap();
            let (pose, score) = brute_force(&field, &endpoints, guess, &settings);
            assert!(
                (got.score - score).abs() < 1e-6,
                "case {i}: branch and bound {} at {:?}, brute force {score} at {pose:?}",
                got.score,
                got.pose
            );
            // Cutting the work is the point: far fewer exact evaluations than lattice poses.
            let w = (settings.linear_window / 0.1).ceil() as usize;
            assert!(
                got.evaluated < (2 * w + 1).pow(2) * 20,
                "case {i}: {} evaluated",
                got.evaluated
            );
        }
    }

    /// Guesses off by up to 0.35 m and 18 deg come back to within a cell and a heading step of
    /// the truth, and the match is confident; a guess at the truth stays there.
    #[test]
    fn the_search_undoes_large_odometry_errors() {
        let settings = CorrelativeSettings::default();
        let truth = [0.23, -0.41, 0.3];
        for (dx, dy, dt) in [
            (0.35, 0.0, 0.0),
            (0.0, -0.3, 0.2),
            (0.2, 0.25, -0.31),
            (0.0, 0.0, 0.0),
        ] {
            let guess = [truth[0] + dx, truth[1] + dy, truth[2] + dt];
            let (field, endpoints) = setup(truth, guess, &settings);
            let m = search(&field, &endpoints, guess, &settings).unwrap();
            let err = (
                (m.pose[0] - truth[0]).hypot(m.pose[1] - truth[1]),
                wrap(m.pose[2] - truth[2]).abs(),
            );
            assert!(
                err.0 <= 0.1 && err.1 <= 0.03,
                "offset ({dx}, {dy}, {dt}): match off by {err:?}"
            );
            if (dx, dy, dt) == (0.0, 0.0, 0.0) {
                assert!(
                    !m.is_confident(&settings),
                    "a right guess is not replaced: {m:?}"
                );
            } else {
                assert!(
                    m.is_confident(&settings),
                    "offset ({dx}, {dy}, {dt}): {m:?}"
                );
            }
        }
    }

    /// An empty map or no endpoints: the guess, never confident.
    #[test]
    fn nothing_to_match_keeps_the_guess() {
        let settings = CorrelativeSettings::default();
        let g = geometry();
        let guess = [0.0, 0.0, 0.0];
        let rect = field_rect(&g, guess, 8.0, &settings).unwrap();
        let field = LikelihoodField::new(g, rect, &vec![false; rect.n_cells()], 2).unwrap();
        let m = search(&field, &[[1.0, 0.0], [0.0, 2.0]], guess, &settings).unwrap();
        assert_eq!(m.pose, guess);
        assert!(!m.is_confident(&settings));
        let m = search(&field, &[], guess, &settings).unwrap();
        assert!(!m.is_confident(&settings));
    }

    /// Pooled level h at a cell is the maximum of level 0 over the block from it.
    #[test]
    fn pooled_levels_bound_their_blocks() {
        let settings = CorrelativeSettings::default();
        let (field, _) = setup([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], &settings);
        let r = field.rect;
        for h in 0..=field.depth() {
            let side = 1i64 << h;
            for (ix, iy) in [
                (r.ix0 + 3, r.iy0 + 5),
                (r.ix0 + 40, r.iy0 + 60),
                (r.ix0 + r.nx - 2, r.iy0 + r.ny - 2),
            ] {
                let mut m = 0.0f32;
                for y in iy..iy + side {
                    for x in ix..ix + side {
                        m = m.max(field.value(0, x, y));
                    }
                }
                assert_eq!(field.value(h, ix, iy), m);
            }
        }
    }

    #[test]
    fn settings_are_validated() {
        let ok = CorrelativeSettings::default();
        assert!(ok.validate().is_ok());
        for bad in [
            CorrelativeSettings {
                linear_window: 0.0,
                ..ok
            },
            CorrelativeSettings {
                angular_window: f64::NAN,
                ..ok
            },
            CorrelativeSettings {
                angular_window: 4.0,
                ..ok
            },
            CorrelativeSettings {
                penalty: -0.1,
                ..ok
            },
            CorrelativeSettings {
                min_gain: 2.0,
                ..ok
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }
}
