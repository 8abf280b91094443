//! Cell addressing: a grid's origin and cell size, rectangles of cells, and the limits on
//! coordinates and indices that keep every index computation from overflowing.

use crate::error::{config_err, CrlamError, Result};

/// `x.floor() as i64` (saturating, NaN to 0), bit for bit, without the call to libm's `floor`
/// that the baseline x86-64 target makes of `f64::floor` (no SSE4.1 `roundsd`): every walk
/// starts with two of them.
#[inline(always)]
pub fn floor_to_i64(x: f64) -> i64 {
    // Truncation saturates and maps NaN to 0; |t| <= |x| and t is an integer, so `t as f64` is
    // exact (below 2^53 every integer is, above it x is itself an integer).
    let t = x as i64;
    if (t as f64) > x {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// Origin and cell size of a grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridGeometry {
    /// World coordinates (m) of the lower-left corner of cell (0, 0).
    pub origin: [f64; 2],
    /// Cell edge length Δ (m).
    pub resolution: f64,
}

impl GridGeometry {
    /// Validated constructor: `resolution` in [[`MIN_RESOLUTION`], [`MAX_COORD`]] and the origin
    /// within [`MAX_COORD`] of (0, 0), so that every cell index of a valid pose fits an `i64`
    /// with room to spare (|index| < 2^45).
    pub fn new(origin: [f64; 2], resolution: f64) -> Result<Self> {
        if !(resolution.is_finite() && (MIN_RESOLUTION..=MAX_COORD).contains(&resolution)) {
            return Err(config_err(
                "resolution",
                format!("must be a finite cell size in [{MIN_RESOLUTION:e}, {MAX_COORD:e}] m, got {resolution}"),
            ));
        }
        if !(origin[0].is_finite() && origin[1].is_finite())
            || origin[0].abs() > MAX_COORD
            || origin[1].abs() > MAX_COORD
        {
            return Err(config_err(
                "origin",
                format!("must be finite and within {MAX_COORD:e} m of (0, 0), got {origin:?}"),
            ));
        }
        Ok(Self { origin, resolution })
    }

    /// Index of the cell containing the world point (x, y) (saturating; NaN gives 0: check the
    /// point first with [`Self::checked_cell_of`] when it comes from input).
    #[inline]
    pub fn cell_of(&self, x: f64, y: f64) -> (i64, i64) {
        (
            floor_to_i64((x - self.origin[0]) / self.resolution),
            floor_to_i64((y - self.origin[1]) / self.resolution),
        )
    }

    /// Index of the cell containing (x, y), refusing non-finite points and points farther than
    /// [`MAX_COORD`] from the origin.
    pub fn checked_cell_of(&self, x: f64, y: f64) -> Result<(i64, i64)> {
        for (field, v) in [("x", x), ("y", y)] {
            if !v.is_finite() {
                return Err(CrlamError::NonFinite { field, value: v });
            }
        }
        if (x - self.origin[0]).abs() > MAX_COORD || (y - self.origin[1]).abs() > MAX_COORD {
            return Err(CrlamError::OutOfBounds(format!(
                "point ({x:.3e}, {y:.3e}) is more than {MAX_COORD:.0e} m from the map origin"
            )));
        }
        Ok(self.cell_of(x, y))
    }

    /// World coordinates of the centre of cell (ix, iy).
    #[inline]
    pub fn cell_center(&self, ix: i64, iy: i64) -> [f64; 2] {
        [
            self.origin[0] + (ix as f64 + 0.5) * self.resolution,
            self.origin[1] + (iy as f64 + 0.5) * self.resolution,
        ]
    }
}

/// Poses farther than this (m) from the grid origin are refused: they would overflow cell indices.
pub const MAX_COORD: f64 = 1e7;

/// Smallest cell size (m): with [`MAX_COORD`] it bounds every cell index of a valid pose by 2^45.
pub const MIN_RESOLUTION: f64 = 1e-6;

/// Largest |cell index| (and rectangle side) accepted from input: far beyond any valid pose
/// (2^45 > 2 x 10^7 m / 10^-6 m), and small enough that sums of two indices never overflow.
pub const MAX_CELL_INDEX: i64 = 1 << 46;

/// Checks that a pose (x, y, θ) is finite and within [`MAX_COORD`] of the origin.
pub fn check_pose(pose: [f64; 3]) -> Result<()> {
    for (i, name) in ["x", "y", "theta"].iter().enumerate() {
        if !pose[i].is_finite() {
            return Err(CrlamError::NonFinite {
                field: name,
                value: pose[i],
            });
        }
    }
    if pose[0].abs() > MAX_COORD || pose[1].abs() > MAX_COORD {
        return Err(CrlamError::OutOfBounds(format!(
            "pose ({:.3e}, {:.3e}) is more than {MAX_COORD:.0e} m from the map origin",
            pose[0], pose[1]
        )));
    }
    Ok(())
}

/// A rectangle of cells `[ix0, ix0 + nx) × [iy0, iy0 + ny)`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CellRect {
    pub ix0: i64,
    pub iy0: i64,
    pub nx: i64,
    pub ny: i64,
}

impl CellRect {
    /// A rectangle from input, refused unless `nx, ny > 0` and every index lies within
    /// [`MAX_CELL_INDEX`] (so that no arithmetic on it can overflow).
    pub fn checked(ix0: i64, iy0: i64, nx: i64, ny: i64) -> Result<Self> {
        let r = CellRect { ix0, iy0, nx, ny };
        r.validate()?;
        Ok(r)
    }

    /// See [`Self::checked`].
    pub fn validate(&self) -> Result<()> {
        let ok = |v: i64| v.unsigned_abs() <= MAX_CELL_INDEX as u64;
        if !(self.nx > 0 && self.ny > 0) {
            return Err(CrlamError::Shape(format!(
                "a cell rectangle (ix0, iy0, nx, ny) needs nx, ny > 0, got {self:?}"
            )));
        }
        if !(ok(self.ix0) && ok(self.iy0) && ok(self.nx) && ok(self.ny)) {
            return Err(CrlamError::OutOfBounds(format!(
                "cell rectangle {self:?}: indices and sizes must lie within +-2^46"
            )));
        }
        Ok(())
    }

    /// True when (ix, iy) lies inside.
    #[inline]
    pub fn contains(&self, ix: i64, iy: i64) -> bool {
        ix >= self.ix0 && iy >= self.iy0 && ix < self.ix0 + self.nx && iy < self.iy0 + self.ny
    }

    /// Smallest rectangle containing both.
    pub fn union(&self, other: &CellRect) -> CellRect {
        let ix0 = self.ix0.min(other.ix0);
        let iy0 = self.iy0.min(other.iy0);
        let ix1 = (self.ix0 + self.nx).max(other.ix0 + other.nx);
        let iy1 = (self.iy0 + self.ny).max(other.iy0 + other.ny);
        CellRect {
            ix0,
            iy0,
            nx: ix1 - ix0,
            ny: iy1 - iy0,
        }
    }

    /// Number of cells (saturating at `usize::MAX` for an absurd rectangle).
    pub fn n_cells(&self) -> usize {
        (self.nx.max(0) as u128 * self.ny.max(0) as u128).min(usize::MAX as u128) as usize
    }

    /// Number of cells as a float (exact below 2^53), for limit checks that must not overflow.
    pub fn cells_f64(&self) -> f64 {
        self.nx.max(0) as f64 * self.ny.max(0) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_to_i64_is_floor_as_i64() {
        let specials = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            -1e-300,
            1e-300,
            f64::EPSILON,
            -f64::EPSILON,
            1.0 - f64::EPSILON / 2.0,
            -1.0 + f64::EPSILON / 2.0,
            4503599627370495.5,
            -4503599627370495.5,
            9007199254740993.0,
            -9007199254740993.0,
            9_223_372_036_854_775_807i64 as f64,
            i64::MIN as f64,
            1e19,
            -1e19,
            f64::MAX,
            f64::MIN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        for x in specials {
            assert_eq!(floor_to_i64(x), x.floor() as i64, "x = {x:e}");
        }
        // A deterministic sweep of magnitudes and fractions.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..200_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let x = f64::from_bits(state);
            if x.is_finite() {
                assert_eq!(floor_to_i64(x), x.floor() as i64, "x = {x:e}");
                let y = (state >> 11) as f64 / (1u64 << 40) as f64 - 4096.0;
                assert_eq!(floor_to_i64(y), y.floor() as i64, "y = {y:e}");
            }
        }
    }

    #[test]
    fn cell_of_floors_negative_coordinates() {
        let g = GridGeometry::new([0.0, 0.0], 0.5).unwrap();
        assert_eq!(g.cell_of(0.1, 0.1), (0, 0));
        assert_eq!(g.cell_of(-0.1, 0.6), (-1, 1));
        let c = g.cell_center(-1, 1);
        assert_eq!(g.cell_of(c[0], c[1]), (-1, 1));
    }
}
