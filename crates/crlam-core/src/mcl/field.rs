//! The per-map structure Monte Carlo localization weighs scans against: the expected occupancy
//! m̂ of every cell of a rectangle, stored densely, and the cells a robot may stand on.
//!
//! The CRM predictive likelihood of a beam (crm-spec 4.1) depends on the beliefs only through m̂
//! along the ray, so a fixed map is fully described, for localization, by this one layer: the
//! likelihood computed from it is the map's own (see [`super::likelihood`]). Reading m̂ from a
//! flat array instead of summing a tiled pmf per visited cell is what makes it fast. The array
//! extends past the map by a margin holding the outside value, so that a ray shorter than the
//! margin, cast from inside the map, never leaves it: its walk reads the array at the walk's own
//! running index, with no bounds check per cell.

use crate::crm::CrmMap;
use crate::error::{config_err, CrlamError, Result};
use crate::grid::{floor_to_i64, CellRect, GridGeometry};
use crate::pose::{wrap, Pose};
use crate::rng::Rng;

/// Expected occupancy over a rectangle of cells, with the value every cell outside it reads, and
/// the free cells (m̂ at most a threshold) that global initialisation and recovery sample from.
#[derive(Clone, Debug)]
pub struct MeanField {
    geometry: GridGeometry,
    /// The map's cells.
    rect: CellRect,
    /// The stored cells: `rect` and a margin around it.
    store: CellRect,
    /// m̂ per stored cell, row-major `[iy − store.iy0][ix − store.ix0]`.
    values: Vec<f64>,
    /// m̂ of every cell outside `rect` (a CRM's prior mean).
    outside: f64,
    /// Row-major indices of the free cells.
    free: Vec<u32>,
    free_threshold: f64,
}

impl MeanField {
    /// The field of `map` over `rect`; cells outside read the map's prior mean. Free cells are
    /// those with m̂ ≤ `free_threshold`; `margin` cells are stored around the map.
    pub fn from_crm(
        map: &CrmMap,
        rect: CellRect,
        free_threshold: f64,
        margin: usize,
    ) -> Result<Self> {
        check_rect(rect)?;
        let mut mean = crate::limits::try_filled(rect.n_cells(), 0.0, "the localization field")?;
        map.means_into(rect, &mut mean)?;
        let outside: f64 = map
            .levels()
            .iter()
            .zip(map.prior())
            .map(|(m, p)| m * p)
            .sum();
        Self::from_means(*map.geometry(), rect, mean, outside, free_threshold, margin)
    }

    /// A field from given means (row-major over `rect`, each in [0, 1]), the outside value and
    /// the margin (cells) stored around the map.
    pub fn from_means(
        geometry: GridGeometry,
        rect: CellRect,
        mean: Vec<f64>,
        outside: f64,
        free_threshold: f64,
        margin: usize,
    ) -> Result<Self> {
        check_rect(rect)?;
        let m = margin.min(1 << 20) as i64;
        let store = CellRect {
            ix0: rect.ix0 - m,
            iy0: rect.iy0 - m,
            nx: rect.nx + 2 * m,
            ny: rect.ny + 2 * m,
        };
        check_rect(store)?;
        if mean.len() != rect.n_cells() {
            return Err(CrlamError::Shape(format!(
                "a field of {} x {} cells needs {} means, got {}",
                rect.nx,
                rect.ny,
                rect.n_cells(),
                mean.len()
            )));
        }
        let unit = |v: f64| v.is_finite() && (0.0..=1.0).contains(&v);
        if let Some(i) = mean.iter().position(|&v| !unit(v)) {
            return Err(config_err(
                "mean",
                format!("cell {i} has m̂ = {} (must be in [0, 1])", mean[i]),
            ));
        }
        if !unit(outside) {
            return Err(config_err(
                "outside",
                format!("must be in [0, 1], got {outside}"),
            ));
        }
        if !(free_threshold.is_finite() && (0.0..1.0).contains(&free_threshold)) {
            return Err(config_err(
                "free_threshold",
                format!("must be in [0, 1), got {free_threshold}"),
            ));
        }
        let free = mean
            .iter()
            .enumerate()
            .filter(|(_, &m)| m <= free_threshold)
            .map(|(i, _)| i as u32)
            .collect();
        let mut values =
            crate::limits::try_filled(store.n_cells(), outside, "the localization field")?;
        for (row, src) in mean.chunks(rect.nx as usize).enumerate() {
            let start = (row as i64 + m) * store.nx + m;
            values[start as usize..start as usize + src.len()].copy_from_slice(src);
        }
        Ok(Self {
            geometry,
            rect,
            store,
            values,
            outside,
            free,
            free_threshold,
        })
    }

    pub fn geometry(&self) -> &GridGeometry {
        &self.geometry
    }

    pub fn rect(&self) -> CellRect {
        self.rect
    }

    /// The stored cells (the map and its margin).
    pub fn store(&self) -> CellRect {
        self.store
    }

    /// m̂ of the stored cells, row-major over [`Self::store`].
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// The window of a walk that indexes [`Self::values`]: (ix0, iy0, nx) of the store.
    pub fn window(&self) -> (i64, i64, i64) {
        (self.store.ix0, self.store.iy0, self.store.nx)
    }

    /// True if every cell a ray of `length` metres from `origin` can visit is stored.
    #[inline]
    pub fn holds_ray(&self, origin: [f64; 2], length: f64) -> bool {
        let (cx, cy) = self.geometry.cell_of(origin[0], origin[1]);
        let reach = (length / self.geometry.resolution).ceil();
        if reach.is_nan() || reach >= 1e15 {
            return false;
        }
        // One cell of slack each side. In i128: a sensor far off the map (a particle spread by a
        // huge initial covariance) has a cell index near i64::MAX, where `cx + k` in i64 would
        // wrap to a negative index that passes the test and then reads out of bounds.
        let k = reach as i128 + 2;
        let s = self.store;
        let (cx, cy) = (i128::from(cx), i128::from(cy));
        let (ix0, iy0) = (i128::from(s.ix0), i128::from(s.iy0));
        cx - k >= ix0
            && cy - k >= iy0
            && cx + k < ix0 + i128::from(s.nx)
            && cy + k < iy0 + i128::from(s.ny)
    }

    /// m̂ of every cell outside the rectangle.
    pub fn outside(&self) -> f64 {
        self.outside
    }

    pub fn free_threshold(&self) -> f64 {
        self.free_threshold
    }

    /// Number of free cells.
    pub fn n_free(&self) -> usize {
        self.free.len()
    }

    /// m̂ of cell (ix, iy).
    #[inline(always)]
    pub fn mean_at(&self, ix: i64, iy: i64) -> f64 {
        let (dx, dy) = (
            ix.wrapping_sub(self.store.ix0),
            iy.wrapping_sub(self.store.iy0),
        );
        if (dx as u64) < self.store.nx as u64 && (dy as u64) < self.store.ny as u64 {
            self.values[(dy * self.store.nx + dx) as usize]
        } else {
            self.outside
        }
    }

    /// m̂ of the cell holding the world point (x, y).
    pub fn mean_at_point(&self, x: f64, y: f64) -> f64 {
        let (ix, iy) = self.geometry.cell_of(x, y);
        self.mean_at(ix, iy)
    }

    /// True if the point lies in a free cell.
    pub fn is_free(&self, x: f64, y: f64) -> bool {
        let (ix, iy) = self.geometry.cell_of(x, y);
        self.rect.contains(ix, iy) && self.mean_at(ix, iy) <= self.free_threshold
    }

    /// A pose drawn uniformly over the free cells' area, with a uniform heading; `None` when the
    /// field has no free cell.
    pub fn sample_free(&self, rng: &mut Rng) -> Option<Pose> {
        if self.free.is_empty() {
            return None;
        }
        let k = ((rng.uniform() * self.free.len() as f64) as usize).min(self.free.len() - 1);
        let i = self.free[k] as i64;
        let (ix, iy) = (
            self.rect.ix0 + i % self.rect.nx,
            self.rect.iy0 + i / self.rect.nx,
        );
        let r = self.geometry.resolution;
        let x = self.geometry.origin[0] + (ix as f64 + rng.uniform()) * r;
        let y = self.geometry.origin[1] + (iy as f64 + rng.uniform()) * r;
        let theta = wrap(std::f64::consts::PI * (2.0 * rng.uniform() - 1.0));
        Some([x, y, theta])
    }

    /// Distance (m) from each cell centre of the rectangle to the nearest cell with
    /// m̂ ≥ `occupied` (row-major; +∞ where there is none), by an exact Euclidean distance
    /// transform (Felzenszwalb and Huttenlocher 2012). For the scan-fit diagnostics.
    pub fn occupied_distance(&self, occupied: f64) -> Vec<f64> {
        let (nx, ny) = (self.rect.nx as usize, self.rect.ny as usize);
        let big = 1e20;
        let r0 = self.rect;
        let mut f: Vec<f64> = (0..r0.ny)
            .flat_map(|iy| (0..r0.nx).map(move |ix| (ix, iy)))
            .map(|(ix, iy)| {
                let m = self.mean_at(r0.ix0 + ix, r0.iy0 + iy);
                if m >= occupied {
                    0.0
                } else {
                    big
                }
            })
            .collect();
        let mut line = Vec::new();
        let mut out = Vec::new();
        for y in 0..ny {
            line.clear();
            line.extend_from_slice(&f[y * nx..(y + 1) * nx]);
            edt_1d(&line, &mut out);
            f[y * nx..(y + 1) * nx].copy_from_slice(&out);
        }
        for x in 0..nx {
            line.clear();
            line.extend((0..ny).map(|y| f[y * nx + x]));
            edt_1d(&line, &mut out);
            for y in 0..ny {
                f[y * nx + x] = out[y];
            }
        }
        let r = self.geometry.resolution;
        f.iter()
            .map(|&d2| {
                if d2 >= big {
                    f64::INFINITY
                } else {
                    d2.sqrt() * r
                }
            })
            .collect()
    }

    /// The cell (ix, iy) of a world point and whether it lies in the rectangle.
    pub fn locate(&self, x: f64, y: f64) -> (i64, i64, bool) {
        let ix = floor_to_i64((x - self.geometry.origin[0]) / self.geometry.resolution);
        let iy = floor_to_i64((y - self.geometry.origin[1]) / self.geometry.resolution);
        (ix, iy, self.rect.contains(ix, iy))
    }
}

fn check_rect(rect: CellRect) -> Result<()> {
    if rect.nx <= 0 || rect.ny <= 0 {
        return Err(config_err(
            "rect",
            format!("needs at least one cell, got {} x {}", rect.nx, rect.ny),
        ));
    }
    // The map-cell limit in force (`crate::limits`), before the dense layer is allocated.
    crate::limits::check_map_cells(
        &format!("the localization field of {} x {} cells", rect.nx, rect.ny),
        rect.cells_f64(),
    )
}

/// Squared distance transform of a sampled function along one line: the lower envelope of the
/// parabolas (q − p)² + f(p) (Felzenszwalb and Huttenlocher 2012, Algorithm 1).
fn edt_1d(f: &[f64], out: &mut Vec<f64>) {
    let n = f.len();
    out.clear();
    out.resize(n, 0.0);
    if n == 0 {
        return;
    }
    let mut v = vec![0usize; n];
    let mut z = vec![0.0f64; n + 1];
    let mut k = 0usize;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    let meet = |q: usize, p: usize| {
        ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * (q as f64 - p as f64))
    };
    for q in 1..n {
        let mut s = meet(q, v[k]);
        // z[0] = −∞ ends the loop at k = 0 at the latest.
        while s <= z[k] {
            k -= 1;
            s = meet(q, v[k]);
        }
        k += 1;
        v[k] = q;
        z[k] = s;
        z[k + 1] = f64::INFINITY;
    }
    k = 0;
    for (q, o) in out.iter_mut().enumerate() {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let p = v[k];
        let d = q as f64 - p as f64;
        *o = d * d + f[p];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field(mean: Vec<f64>, nx: i64, ny: i64) -> MeanField {
        let g = GridGeometry::new([0.0, 0.0], 0.1).unwrap();
        let rect = CellRect {
            ix0: 0,
            iy0: 0,
            nx,
            ny,
        };
        MeanField::from_means(g, rect, mean, 0.5, 0.2, 3).unwrap()
    }

    #[test]
    fn outside_cells_read_the_outside_value() {
        let f = field(vec![0.1, 0.9, 0.3, 0.05], 2, 2);
        assert_eq!(f.mean_at(1, 0), 0.9);
        assert_eq!(f.mean_at(0, 1), 0.3);
        assert_eq!(f.mean_at(-1, 0), 0.5);
        assert_eq!(f.mean_at(0, 2), 0.5);
        assert_eq!(f.n_free(), 2);
    }

    #[test]
    fn free_samples_lie_in_free_cells() {
        let f = field(vec![0.1, 0.9, 0.3, 0.05], 2, 2);
        let mut rng = Rng::new(3);
        for _ in 0..200 {
            let p = f.sample_free(&mut rng).unwrap();
            assert!(f.is_free(p[0], p[1]), "{p:?}");
            assert!(p[2] > -std::f64::consts::PI - 1e-12 && p[2] <= std::f64::consts::PI);
        }
        let none = field(vec![0.9; 4], 2, 2);
        assert!(none.sample_free(&mut rng).is_none());
    }

    #[test]
    fn invalid_fields_are_refused() {
        let g = GridGeometry::new([0.0, 0.0], 0.1).unwrap();
        let rect = CellRect {
            ix0: 0,
            iy0: 0,
            nx: 2,
            ny: 1,
        };
        assert!(MeanField::from_means(g, rect, vec![0.1], 0.5, 0.2, 0).is_err());
        assert!(MeanField::from_means(g, rect, vec![0.1, 1.5], 0.5, 0.2, 0).is_err());
        assert!(MeanField::from_means(g, rect, vec![0.1, f64::NAN], 0.5, 0.2, 0).is_err());
        let huge = CellRect {
            ix0: 0,
            iy0: 0,
            nx: 1 << 20,
            ny: 1 << 20,
        };
        assert!(MeanField::from_means(g, huge, vec![], 0.5, 0.2, 0).is_err());
    }

    #[test]
    fn distance_transform_is_euclidean() {
        let mut mean = vec![0.1; 7 * 5];
        mean[2 * 7 + 3] = 0.9;
        let f = field(mean, 7, 5);
        let d = f.occupied_distance(0.5);
        for iy in 0..5i64 {
            for ix in 0..7i64 {
                let want = (((ix - 3).pow(2) + (iy - 2).pow(2)) as f64).sqrt() * 0.1;
                assert!((d[(iy * 7 + ix) as usize] - want).abs() < 1e-12);
            }
        }
        assert!(field(vec![0.1; 4], 2, 2)
            .occupied_distance(0.5)
            .iter()
            .all(|d| d.is_infinite()));
    }
}
