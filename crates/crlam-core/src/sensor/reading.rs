//! The mixture's likelihoods of one reading, with its per-reading terms computed once.

use super::{CauseKernel, SensorModel, SensorModelKind, GAUSS_CUTOFF_SIGMAS, SQRT_2PI};

/// The mixture's on-ray likelihoods L_l of one reading, with the terms that depend only on the
/// reading computed once ([`Self::cell`] is [`SensorModel::on_ray_cell`] bit for bit), and an
/// upper bound on the likelihood of every cause beyond a distance, for walks that stop once the
/// rest of the ray cannot change η.
#[derive(Clone, Copy, Debug)]
pub struct MixtureReading<'a> {
    model: &'a SensorModel,
    z: f64,
    no_return: bool,
    short_numerator: f64,
    rand: f64,
}

impl<'a> MixtureReading<'a> {
    /// The reading `z` (∞ or ≥ z_max: a no-return) under `model`; `None` unless it is the mixture.
    pub fn new(model: &'a SensorModel, z: f64) -> Option<Self> {
        let mut r = Self::new_without_short(model, z)?;
        let l = model.lambda_short;
        // The operations of `short_density` and `on_ray`, in their order.
        r.short_numerator = l * (-l * z).exp();
        Some(r)
    }

    /// L_l for a cause occupying the chord [t_in, t_out].
    #[inline]
    pub fn cell(&self, t_in: f64, t_out: f64) -> f64 {
        let m = self.model;
        if self.no_return {
            return m.w_max;
        }
        let z = self.z;
        let d = 0.5 * (t_in + t_out);
        let hit = if m.kernel == CauseKernel::Chord {
            m.chord_hit_density(z, t_in, t_out)
        } else {
            m.hit_density(z, d)
        };
        let short = if z > d || d <= 0.0 {
            0.0
        } else {
            self.short_numerator / -(-m.lambda_short * d).exp_m1()
        };
        m.w_hit * hit + m.w_short * short + self.rand
    }

    /// [`Self::cell`] for a midpoint cause at `d` of a range reading, to rounding: the hit term
    /// `hit` is given (e.g. [`SensorModel::hit_density_fast`], or 0 where it is negligible) and
    /// e^{−λd} comes from [`crate::numeric::fastmath::exp_table`].
    #[inline]
    pub fn range_cell_fast(&self, d: f64, hit: f64) -> f64 {
        let m = self.model;
        let short = if self.z > d || d <= 0.0 {
            0.0
        } else {
            self.short_numerator / (1.0 - crate::numeric::fastmath::exp_table(-m.lambda_short * d))
        };
        m.w_hit * hit + m.w_short * short + self.rand
    }

    /// The model.
    pub fn model(&self) -> &SensorModel {
        self.model
    }

    /// [`Self::new`] with λ e^{−λz} already known (from an earlier `new` for the same model and
    /// reading: [`Self::short_numerator`]), which is then not recomputed.
    pub fn with_short_numerator(
        model: &'a SensorModel,
        z: f64,
        short_numerator: f64,
    ) -> Option<Self> {
        let mut r = Self::new_without_short(model, z)?;
        r.short_numerator = short_numerator;
        Some(r)
    }

    fn new_without_short(model: &'a SensorModel, z: f64) -> Option<Self> {
        if model.kind != SensorModelKind::Mixture {
            return None;
        }
        Some(Self {
            model,
            z,
            no_return: model.is_no_return(z),
            short_numerator: f64::NAN,
            rand: model.w_rand / model.z_max,
        })
    }

    /// λ e^{−λz}, the numerator of the reading's short terms.
    pub fn short_numerator(&self) -> f64 {
        self.short_numerator
    }

    /// The reading (m; z_max or more for a no-return).
    pub fn z(&self) -> f64 {
        self.z
    }

    /// True for a no-return.
    pub fn is_no_return(&self) -> bool {
        self.no_return
    }

    /// w_short · λ e^{−λz}: a range cell's short term is this over 1 − e^{−λd} (d ≥ z).
    pub fn short_scale(&self) -> f64 {
        self.model.w_short * self.short_numerator
    }

    /// w_rand / z_max: the floor of every L_l of a range reading.
    pub fn rand_floor(&self) -> f64 {
        self.rand
    }

    /// L_l of a cause far before the reading, where the hit term is negligible and the short
    /// term is 0: w_r/z_max for a range, w_max for a no-return (every on-ray cause's value).
    #[inline]
    pub fn far_before(&self) -> f64 {
        if self.no_return {
            self.model.w_max
        } else {
            self.rand
        }
    }

    /// L_∞, the likelihood of the reading if the beam reaches z_max.
    #[inline]
    pub fn infinity(&self) -> f64 {
        self.model.infinity(self.z)
    }

    /// An upper bound of L_l for every cause whose chord starts at or beyond `d`, and of L_∞;
    /// +∞ while `d` has not passed the reading (the hit term can still peak).
    pub fn bound_beyond(&self, d: f64) -> f64 {
        let m = self.model;
        if self.no_return {
            return m.w_max.max(m.w_hit + m.w_max);
        }
        if d <= self.z {
            return f64::INFINITY;
        }
        let u = (d - self.z) / m.sigma_hit;
        // Beyond the reading the Gaussian falls with d; the truncation normaliser (at least 1/2
        // inside [0, z_max]) at most doubles it, and a chord's mean density is below its start's.
        let hit = if u > GAUSS_CUTOFF_SIGMAS {
            0.0
        } else {
            2.0 * (-0.5 * u * u).exp() / (m.sigma_hit * SQRT_2PI)
        };
        // ε(z; d) falls with d, and L_∞ uses d = z_max.
        let short = self.short_numerator / -(-m.lambda_short * d).exp_m1();
        m.w_hit * hit + m.w_short * short + self.rand
    }
}
