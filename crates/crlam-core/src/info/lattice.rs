//! A dense occupancy-probability lattice and the virtual range sensor of the planner
//! (planner-spec 2.2–2.3).
//!
//! Node `(a, b)` sits at the centre of cell `(a, b)` of the geometry, so "the nearest lattice
//! node" of a point is the cell that contains it, clamped to the lattice (a kd-tree nearest
//! neighbour on an axis-aligned lattice gives the same node). Indices are `a + b·nx`.

use std::f64::consts::PI;

use crate::error::{config_err, CrlamError, Result};
use crate::grid::{CellRect, GridGeometry};
use crate::raycast::{traverse_with, RayCell};

/// Occupancy probabilities on a rectangle of cells.
#[derive(Clone, Debug, PartialEq)]
pub struct OccupancyLattice {
    geometry: GridGeometry,
    nx: usize,
    ny: usize,
    prob: Vec<f64>,
}

impl OccupancyLattice {
    /// A lattice of `nx × ny` nodes; `prob` is row-major with x fastest (index `a + b·nx`), every
    /// value in [0, 1].
    pub fn new(geometry: GridGeometry, nx: usize, ny: usize, prob: Vec<f64>) -> Result<Self> {
        if nx == 0 || ny == 0 {
            return Err(config_err("shape", "the lattice needs at least one node"));
        }
        if prob.len() != nx * ny {
            return Err(CrlamError::Shape(format!(
                "{} probabilities for a {nx} x {ny} lattice",
                prob.len()
            )));
        }
        if let Some(i) = prob.iter().position(|p| !(0.0..=1.0).contains(p)) {
            return Err(CrlamError::NonFinite {
                field: "probability",
                value: prob[i],
            });
        }
        Ok(Self {
            geometry,
            nx,
            ny,
            prob,
        })
    }

    pub fn geometry(&self) -> &GridGeometry {
        &self.geometry
    }

    pub fn shape(&self) -> (usize, usize) {
        (self.nx, self.ny)
    }

    pub fn len(&self) -> usize {
        self.prob.len()
    }

    pub fn is_empty(&self) -> bool {
        self.prob.is_empty()
    }

    /// The cell rectangle covered by the lattice.
    pub fn rect(&self) -> CellRect {
        CellRect {
            ix0: 0,
            iy0: 0,
            nx: self.nx as i64,
            ny: self.ny as i64,
        }
    }

    /// All probabilities (index `a + b·nx`).
    pub fn probabilities(&self) -> &[f64] {
        &self.prob
    }

    #[inline]
    pub fn get(&self, id: usize) -> f64 {
        self.prob[id]
    }

    #[inline]
    pub fn set(&mut self, id: usize, p: f64) {
        self.prob[id] = p;
    }

    /// Node id of cell (ix, iy), if inside.
    #[inline]
    pub fn id_of_cell(&self, ix: i64, iy: i64) -> Option<usize> {
        (ix >= 0 && iy >= 0 && (ix as usize) < self.nx && (iy as usize) < self.ny)
            .then(|| ix as usize + iy as usize * self.nx)
    }

    /// The nearest node of a world point (clamped to the lattice).
    #[inline]
    pub fn nearest(&self, x: f64, y: f64) -> usize {
        let (ix, iy) = self.geometry.cell_of(x, y);
        let a = ix.clamp(0, self.nx as i64 - 1) as usize;
        let b = iy.clamp(0, self.ny as i64 - 1) as usize;
        a + b * self.nx
    }

    /// World position (m) of node `id`.
    #[inline]
    pub fn node_position(&self, id: usize) -> [f64; 2] {
        self.geometry
            .cell_center((id % self.nx) as i64, (id / self.nx) as i64)
    }
}

/// How the beam directions of a virtual scan are chosen (planner-spec 2.3, crm-spec 5.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BeamAngles {
    /// `n` distinct directions θ + 2πj/n (clean).
    Distinct,
    /// linspace(−π, π, n) in the world frame, ignoring θ: −π and π coincide (the reference
    /// planner's 9 distinct directions for n = 10).
    Reference,
}

impl BeamAngles {
    /// Parses `"distinct" | "clean" | "reference"`.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "distinct" | "clean" => Ok(Self::Distinct),
            "reference" => Ok(Self::Reference),
            other => Err(config_err(
                "beam_angles",
                format!("unknown mode {other:?}; expected distinct (clean) or reference"),
            )),
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            Self::Distinct => "distinct",
            Self::Reference => "reference",
        }
    }

    /// World-frame beam angles (rad) for a candidate with heading `theta`.
    pub fn angles(&self, n: usize, theta: f64) -> Vec<f64> {
        match self {
            Self::Distinct => (0..n)
                .map(|j| theta + 2.0 * PI * j as f64 / n as f64)
                .collect(),
            Self::Reference => {
                if n == 1 {
                    return vec![-PI];
                }
                (0..n)
                    .map(|j| -PI + 2.0 * PI * j as f64 / (n - 1) as f64)
                    .collect()
            }
        }
    }
}

/// One step of the reference ray march.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MarchStep {
    /// Occupancy of the nearest node at the time of the march.
    pub prob: f64,
    /// Distance (m) from the sensor.
    pub range: f64,
    /// Nearest lattice node.
    pub id: usize,
}

/// A beam of the reference virtual sensor.
#[derive(Clone, Debug, PartialEq)]
pub struct MarchedBeam {
    pub angle: f64,
    /// Steps up to and including the hit (nodes may repeat: the step is below the spacing).
    pub steps: Vec<MarchStep>,
    /// World position of the hit, `None` for a max-range beam.
    pub hit: Option<[f64; 2]>,
}

/// Number of ray-march steps of the reference sensor: ⌈z_max / (0.4 Δ)⌉.
pub fn march_steps(z_max: f64, spacing: f64) -> usize {
    (z_max / (0.4 * spacing)).ceil().max(1.0) as usize
}

/// The reference virtual sensor (planner-spec 2.3): march `n_steps` equal steps up to `z_max`
/// and stop at the first step whose nearest node has probability above `p_occ`.
pub fn march_beam(
    lat: &OccupancyLattice,
    origin: [f64; 2],
    angle: f64,
    z_max: f64,
    p_occ: f64,
) -> MarchedBeam {
    let n = march_steps(z_max, lat.geometry.resolution);
    let step = z_max / n as f64;
    let (c, s) = (angle.cos(), angle.sin());
    let mut steps = Vec::with_capacity(n);
    let mut hit = None;
    for k in 1..=n {
        let r = k as f64 * step;
        let p = [origin[0] + r * c, origin[1] + r * s];
        let id = lat.nearest(p[0], p[1]);
        let o = lat.get(id);
        steps.push(MarchStep {
            prob: o,
            range: r,
            id,
        });
        if o > p_occ {
            hit = Some(p);
            break;
        }
    }
    MarchedBeam { angle, steps, hit }
}

/// One cell of an exact (clean) traversal of the lattice.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LatticeCell {
    pub id: usize,
    /// Entry and exit distances (m) along the beam.
    pub t_in: f64,
    pub t_out: f64,
}

/// The cells of the lattice crossed by a beam from `origin` for `t ∈ [0, length]`, each once, in
/// order (planner-spec 2.3 \[CLEAN\]); the walk stops at the lattice border. Clears `out` first.
pub fn traverse_lattice(
    lat: &OccupancyLattice,
    origin: [f64; 2],
    angle: f64,
    length: f64,
    out: &mut Vec<LatticeCell>,
) {
    out.clear();
    let rect = lat.rect();
    traverse_with(
        &lat.geometry,
        origin,
        angle,
        length,
        Some(&rect),
        |c: RayCell| {
            if let Some(id) = lat.id_of_cell(c.ix, c.iy) {
                out.push(LatticeCell {
                    id,
                    t_in: c.t_in,
                    t_out: c.t_out,
                });
            }
            true
        },
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lattice() -> OccupancyLattice {
        // The planner's lattice: nodes at −1, −0.8, …, 21 (111 × 111).
        let g = GridGeometry::new([-1.1, -1.1], 0.2).unwrap();
        OccupancyLattice::new(g, 111, 111, vec![0.3; 111 * 111]).unwrap()
    }

    #[test]
    fn nearest_node_is_the_containing_cell_clamped() {
        let l = lattice();
        let id = l.nearest(10.0, 2.0);
        let p = l.node_position(id);
        assert!((p[0] - 10.0).abs() < 1e-9 && (p[1] - 2.0).abs() < 1e-9);
        assert_eq!(l.nearest(-50.0, -50.0), 0);
        assert_eq!(l.nearest(99.0, 99.0), l.len() - 1);
    }

    #[test]
    fn reference_angles_repeat_one_direction() {
        let a = BeamAngles::Reference.angles(10, 1.0);
        assert!((a[0] + PI).abs() < 1e-15 && (a[9] - PI).abs() < 1e-15);
        let d = BeamAngles::Distinct.angles(10, 0.0);
        assert!((d[1] - PI / 5.0).abs() < 1e-15);
    }

    #[test]
    fn march_stops_at_the_first_occupied_node() {
        let mut l = lattice();
        let id = l.nearest(12.0, 2.0);
        l.set(id, 0.85);
        let b = march_beam(&l, [10.0, 2.0], 0.0, 5.0, 0.65);
        assert_eq!(march_steps(5.0, 0.2), 63);
        let hit = b.hit.unwrap();
        assert!((hit[0] - 11.9).abs() < 0.08, "{hit:?}");
        assert_eq!(b.steps.last().unwrap().id, id);
        let free = march_beam(&l, [10.0, 2.0], PI / 2.0, 5.0, 0.65);
        assert_eq!(free.steps.len(), 63);
        assert!(free.hit.is_none());
        assert!((free.steps[62].range - 5.0).abs() < 1e-12);
    }

    #[test]
    fn exact_traversal_visits_each_cell_once() {
        let l = lattice();
        let mut v = Vec::new();
        traverse_lattice(&l, [10.0, 2.0], 0.3, 5.0, &mut v);
        let total: f64 = v.iter().map(|c| c.t_out - c.t_in).sum();
        assert!((total - 5.0).abs() < 1e-9);
        let mut ids: Vec<_> = v.iter().map(|c| c.id).collect();
        ids.sort();
        ids.dedup();
        assert_eq!(ids.len(), v.len());
    }
}
