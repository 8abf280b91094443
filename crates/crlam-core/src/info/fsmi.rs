//! OGMI: the Shannon mutual information between an occupancy map and a virtual range scan
//! (planner-spec 4.1–4.3), in nats.
//!
//! Beam model (4.1): cells 1…n along a beam, cell i spanning `[l_i, l_{i+1})` with centre μ_i and
//! occupancy o_i. Event e_j = "cell j is the first occupied cell" (P_j = o_j Π_{i<j}(1 − o_i)),
//! e_∅ = "no occupied cell" (P_∅ = Π(1 − o_i)). Given e_j the reading is N(μ_j, σ²); a reading in
//! cell k updates the odds of cells before k by δ_emp and of cell k by δ_occ, and carries the
//! information C_k = f(δ_occ, r_k) + Σ_{i<k} f(δ_emp, r_i). Max-range completion (our choice, the
//! spec's 4.2): e_∅ gives a max-range reading (a point mass) that multiplies every cell by δ_emp,
//! i.e. a virtual cell n+1 with P_{n+1} = P_∅ and C_{n+1} = Σ_i f(δ_emp, r_i). Gaussian mass that
//! leaves `[l_1, l_{n+1})` carries no information (Σ_k G_kj ≤ 1).
//!
//! [`julian_beam_mi`] integrates this model numerically (the test reference), [`fsmi_beam`] is its
//! closed form (FSMI), [`fsmi_beam_truncated`] keeps only nearby cells per Gaussian and
//! [`fsmi_beam_noise_free`] is the σ → 0 limit. [`Fsmi`] sums a beam function over a virtual scan
//! on the lattice; [`crate::info::iig_mi::IigMi`] is the IIG reference 'mi' heuristic (4.3).

use crate::error::{config_err, CrlamError, Result};
use crate::info::lattice::{traverse_lattice, BeamAngles, LatticeCell, OccupancyLattice};
use crate::info::{Candidate, Evaluation, InfoUnits, InformationFunction};
use crate::numeric::fastmath::{ln_1p_slice, normal_cdf_slice};
use crate::raycast::rect_box;
use crate::sensor::normal_cdf;

const SQRT_2PI: f64 = 2.506_628_274_631_000_7;

/// Default truncation of [`FsmiVariant::Truncated`], in standard deviations.
pub const DEFAULT_TRUNCATION_SIGMAS: f64 = 3.0;

/// f(δ, r) = ln((r + 1)/(r + 1/δ)) − ln δ/(rδ + 1) (planner-spec 4.1), in nats: the KL divergence
/// of a cell's Bernoulli belief after its odds r are multiplied by δ, from the belief before.
/// Domain δ > 0, r ∈ [0, ∞] (r = `f64::INFINITY` allowed); f(δ, 0) = f(δ, ∞) = f(1, r) = 0.
pub fn kl_factor(delta: f64, r: f64) -> f64 {
    if r == f64::INFINITY {
        return 0.0;
    }
    kl_of_prob(delta, delta.ln(), r / (1.0 + r), 1.0 / (1.0 + r))
}

/// f for a cell of occupancy `o`, with `q` = 1 − o given separately so that o ≈ 1 keeps its
/// precision. Both branches are sums of O(min(o, q)) terms, so nothing cancels at r → 0 or ∞.
#[inline]
fn kl_of_prob(delta: f64, ln_delta: f64, o: f64, q: f64) -> f64 {
    kl_with_log(delta, ln_delta, o, q, kl_log_arg(delta, o, q).ln_1p())
}

/// The x of the ln(1 + x) that [`kl_of_prob`] needs for (δ, o, q).
#[inline]
fn kl_log_arg(delta: f64, o: f64, q: f64) -> f64 {
    if o <= q {
        o * (delta - 1.0)
    } else {
        q * (1.0 / delta - 1.0)
    }
}

/// [`kl_of_prob`] given `ln_1p` = ln(1 + [`kl_log_arg`]).
#[inline]
fn kl_with_log(delta: f64, ln_delta: f64, o: f64, q: f64, ln_1p: f64) -> f64 {
    let f = if o <= q {
        // f = p′ ln δ − ln(1 + o(δ − 1)), p′ the updated occupancy.
        let post = o * delta / (q + o * delta);
        post * ln_delta - ln_1p
    } else {
        // f = −ln(1 + q(1/δ − 1)) − (1 − p′) ln δ.
        let post_free = q / (q + o * delta);
        -ln_1p - post_free * ln_delta
    };
    f.max(0.0)
}

/// Parameters of the OGMI beam model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OgmiParams {
    /// Odds factor δ_occ > 1 of the cell a reading falls in.
    pub delta_occ: f64,
    /// Odds factor δ_emp ∈ (0, 1) of the cells before the reading (and of all cells on max range).
    pub delta_emp: f64,
    /// Range noise σ (m) of the reading given its first occupied cell.
    pub sigma: f64,
    /// Beam length (m) of the per-pose functions.
    pub z_max: f64,
}

impl Default for OgmiParams {
    /// δ_occ = 1.5, δ_emp = 1/1.5 (planner-spec S6), σ = 0.05 m, z_max = 5 m.
    fn default() -> Self {
        Self {
            delta_occ: 1.5,
            delta_emp: 1.0 / 1.5,
            sigma: 0.05,
            z_max: 5.0,
        }
    }
}

impl OgmiParams {
    pub fn validate(&self) -> Result<()> {
        let checks = [
            ("delta_occ", self.delta_occ, self.delta_occ > 1.0, "> 1"),
            (
                "delta_emp",
                self.delta_emp,
                self.delta_emp > 0.0 && self.delta_emp < 1.0,
                "in (0, 1)",
            ),
            ("sigma", self.sigma, self.sigma > 0.0, "> 0"),
            ("z_max", self.z_max, self.z_max > 0.0, "> 0"),
        ];
        for (field, value, ok, want) in checks {
            if !(value.is_finite() && ok) {
                return Err(config_err(
                    field,
                    format!("must be finite and {want}, got {value}"),
                ));
            }
        }
        Ok(())
    }
}

/// How a beam's MI is computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FsmiVariant {
    /// Exact FSMI: the O(n²) double sum, evaluated over the cells within 8.5σ of each Gaussian's
    /// centre, since beyond that Φ is exactly 0 or 1 in double precision and G_kj exactly 0.
    Full,
    /// FSMI keeping, for the Gaussian of cell j, the cells less than `width_sigmas`·σ away from
    /// cell j's span (G_kj = 0 for the others): Δ_c = ⌈wσ/Δ⌉ neighbours on a beam of equal cells Δ.
    Truncated { width_sigmas: f64 },
    /// σ → 0: the reading falls in the first occupied cell, O(n).
    NoiseFree,
    /// Julian et al.'s midpoint-rule integral, `points_per_cell` points per cell, O(n² λ_z).
    Julian { points_per_cell: usize },
}

impl FsmiVariant {
    pub fn validate(&self) -> Result<()> {
        match *self {
            Self::Truncated { width_sigmas }
                if !(width_sigmas.is_finite() && width_sigmas > 0.0) =>
            {
                Err(config_err(
                    "width_sigmas",
                    format!("must be finite and > 0, got {width_sigmas}"),
                ))
            }
            Self::Julian { points_per_cell: 0 } => {
                Err(config_err("points_per_cell", "must be ≥ 1"))
            }
            _ => Ok(()),
        }
    }
}

/// Per-beam terms of the model, in reusable buffers: P_j, P_∅ and C_k (k = 1…n+1).
#[derive(Clone, Debug, Default)]
pub struct BeamTerms {
    p_first: Vec<f64>,
    p_none: f64,
    gains: Vec<f64>,
    /// Standardised edges (l_e − μ_j)/σ of every Gaussian's window, back to back, and their Φ
    /// (first used for the arguments of ln(1 + x) and their logarithms).
    xs: Vec<f64>,
    cdf: Vec<f64>,
    /// (j, first cell, last cell) of each window, in the order of `xs`.
    windows: Vec<(usize, usize, usize)>,
}

impl BeamTerms {
    pub fn new() -> Self {
        Self::default()
    }

    /// Fills the terms for occupancies `o` (each in [0, 1]).
    pub fn compute(&mut self, o: &[f64], params: &OgmiParams) -> Result<()> {
        params.validate()?;
        refuse("occupancy", o, is_probability)?;
        self.fill(o, params);
        Ok(())
    }

    fn fill(&mut self, o: &[f64], params: &OgmiParams) {
        let deltas = [params.delta_occ, params.delta_emp];
        let ln_deltas = deltas.map(f64::ln);
        // The ln(1 + x) of both KL terms of every cell first, in one vectorised pass.
        // Buffers sized first and written by index: a push per cell would carry each vector's
        // length through memory from one cell to the next.
        let n = o.len();
        self.xs.resize(2 * n, 0.0);
        for (x, &oi) in self.xs.chunks_exact_mut(2).zip(o) {
            let q = 1.0 - oi;
            x.copy_from_slice(&deltas.map(|d| kl_log_arg(d, oi, q)));
        }
        self.cdf.resize(2 * n, 0.0);
        ln_1p_slice(&self.xs, &mut self.cdf);
        self.p_first.resize(n, 0.0);
        self.gains.resize(n + 1, 0.0);
        let (mut survive, mut loss) = (1.0, 0.0);
        let rows = o.iter().zip(self.cdf.chunks_exact(2));
        for ((&oi, ln_1p), (p, g)) in rows.zip(self.p_first.iter_mut().zip(&mut self.gains)) {
            let q = 1.0 - oi;
            let kl = |i: usize| kl_with_log(deltas[i], ln_deltas[i], oi, q, ln_1p[i]);
            *p = oi * survive;
            survive *= q;
            *g = loss + kl(0);
            loss += kl(1);
        }
        self.gains[n] = loss;
        self.p_none = survive;
    }

    /// P(e_j), j = 1…n.
    pub fn p_first(&self) -> &[f64] {
        &self.p_first
    }

    /// P(e_∅) = Π(1 − o_i).
    pub fn p_none(&self) -> f64 {
        self.p_none
    }

    /// C_k (nats) for k = 1…n, then C_{n+1} of the max-range reading (length n + 1).
    pub fn gains(&self) -> &[f64] {
        &self.gains
    }
}

/// Refuses the first value that fails `ok` (a NaN, an infinity or a probability outside [0, 1]).
pub(crate) fn refuse(field: &'static str, values: &[f64], ok: impl Fn(f64) -> bool) -> Result<()> {
    match values.iter().find(|&&v| !ok(v)) {
        Some(&value) => Err(CrlamError::NonFinite { field, value }),
        None => Ok(()),
    }
}

pub(crate) fn is_probability(p: f64) -> bool {
    (0.0..=1.0).contains(&p)
}

fn check_beam(o: &[f64], edges: &[f64], params: &OgmiParams) -> Result<()> {
    params.validate()?;
    refuse("occupancy", o, is_probability)?;
    if edges.len() != o.len() + 1 {
        return Err(CrlamError::Shape(format!(
            "{} edges for {} cells (need n + 1)",
            edges.len(),
            o.len()
        )));
    }
    refuse("edges", edges, f64::is_finite)?;
    if edges.windows(2).any(|w| w[1] < w[0]) {
        return Err(config_err("edges", "must be non-decreasing"));
    }
    Ok(())
}

/// Beam MI (nats) with caller-owned buffers: no allocation once `terms` has grown.
pub fn beam_mi(
    terms: &mut BeamTerms,
    o: &[f64],
    edges: &[f64],
    params: &OgmiParams,
    variant: FsmiVariant,
) -> Result<f64> {
    check_beam(o, edges, params)?;
    variant.validate()?;
    Ok(beam_mi_unchecked(terms, o, edges, params, variant))
}

/// Julian et al.'s integral (nats) of the beam model: `points_per_cell` midpoint-rule points per
/// cell over `[l_1, l_{n+1}]`, plus the max-range point mass. `edges` holds l_1…l_{n+1} (m).
pub fn julian_beam_mi(
    o: &[f64],
    edges: &[f64],
    params: &OgmiParams,
    points_per_cell: usize,
) -> Result<f64> {
    let variant = FsmiVariant::Julian { points_per_cell };
    beam_mi(&mut BeamTerms::new(), o, edges, params, variant)
}

/// Exact FSMI (nats): see [`FsmiVariant::Full`].
pub fn fsmi_beam(o: &[f64], edges: &[f64], params: &OgmiParams) -> Result<f64> {
    beam_mi(&mut BeamTerms::new(), o, edges, params, FsmiVariant::Full)
}

/// Truncated FSMI (nats): see [`FsmiVariant::Truncated`].
pub fn fsmi_beam_truncated(
    o: &[f64],
    edges: &[f64],
    params: &OgmiParams,
    width_sigmas: f64,
) -> Result<f64> {
    let variant = FsmiVariant::Truncated { width_sigmas };
    beam_mi(&mut BeamTerms::new(), o, edges, params, variant)
}

/// Noise-free FSMI (nats) = Σ_j P_j C_j + P_∅ C_{n+1}, O(n); `params.sigma` is unused.
pub fn fsmi_beam_noise_free(o: &[f64], edges: &[f64], params: &OgmiParams) -> Result<f64> {
    beam_mi(
        &mut BeamTerms::new(),
        o,
        edges,
        params,
        FsmiVariant::NoiseFree,
    )
}

/// G_kj for k = 1…n: the probability that the reading given e_j (N(μ_j, σ²)) falls in cell k.
/// `j` is 0-based.
pub fn reading_cell_probabilities(edges: &[f64], sigma: f64, j: usize) -> Result<Vec<f64>> {
    let n = edges.len().saturating_sub(1);
    if j >= n {
        return Err(CrlamError::OutOfBounds(format!(
            "cell {j} of a {n}-cell beam"
        )));
    }
    check_beam(
        &vec![0.0; n],
        edges,
        &OgmiParams {
            sigma,
            ..OgmiParams::default()
        },
    )?;
    let mu = 0.5 * (edges[j] + edges[j + 1]);
    let cdf = |e: usize| normal_cdf((edges[e] - mu) / sigma);
    Ok((0..n).map(|k| cdf(k + 1) - cdf(k)).collect())
}

fn beam_mi_unchecked(
    terms: &mut BeamTerms,
    o: &[f64],
    edges: &[f64],
    params: &OgmiParams,
    variant: FsmiVariant,
) -> f64 {
    terms.fill(o, params);
    let n = o.len();
    let (p, c) = (&terms.p_first, &terms.gains);
    let max_range = terms.p_none * c[n];
    let body = match variant {
        FsmiVariant::NoiseFree => p.iter().zip(c).map(|(pj, cj)| pj * cj).sum(),
        // Beyond CDF_SATURATION σ, Φ is exactly 0 or 1 in double precision, so every G_kj outside
        // that window is exactly 0: the full sum is the window's.
        FsmiVariant::Full => terms.windowed_sum(edges, params.sigma, CDF_SATURATION, true),
        FsmiVariant::Truncated { width_sigmas } => {
            terms.windowed_sum(edges, params.sigma, width_sigmas, false)
        }
        FsmiVariant::Julian { points_per_cell } => {
            julian_integral(p, c, edges, params.sigma, points_per_cell)
        }
    };
    body + max_range
}

/// |x| beyond which Φ(x) is 0 or 1 in double precision (Φ(−8.5) < 1e-17, and 1 − 1e-17 rounds
/// to 1): skipping erfc there changes nothing.
const CDF_SATURATION: f64 = 8.5;

impl BeamTerms {
    /// Σ_j P_j Σ_{k ∈ W_j} C_k G_kj (nats) over the filled terms, W_j being the cells less than
    /// `width_sigmas`·σ away from cell j's span, or from its centre μ_j when `from_centre` (the
    /// cells that can hold reading mass when Φ saturates there). Each inner sum is taken by parts
    /// over the edges (each edge's Φ once: |W_j| + 1 evaluations), and all the Φ of the beam in
    /// one vectorised pass ([`normal_cdf_slice`]).
    fn windowed_sum(
        &mut self,
        edges: &[f64],
        sigma: f64,
        width_sigmas: f64,
        from_centre: bool,
    ) -> f64 {
        let (p, c) = (&self.p_first, &self.gains);
        let n = p.len();
        let (reach, inv_sigma) = (width_sigmas * sigma, 1.0 / sigma);
        // The windows first (at most one per cell), then every standardised edge written by
        // index: pushes would carry the vectors' lengths through memory from one cell to the next.
        self.windows.resize(n, (0, 0, 0));
        let (mut lo, mut hi, mut count, mut len) = (0, 0, 0, 0);
        for j in 0..n {
            let mu = 0.5 * (edges[j] + edges[j + 1]);
            let (from, to) = if from_centre {
                (mu, mu)
            } else {
                (edges[j], edges[j + 1])
            };
            // Both ends of the window only move forward with j.
            while edges[lo + 1] <= from - reach {
                lo += 1;
            }
            while hi + 1 < n && edges[hi + 1] < to + reach {
                hi += 1;
            }
            if p[j] > 0.0 {
                self.windows[count] = (j, lo, hi);
                count += 1;
                len += hi - lo + 2;
            }
        }
        self.windows.truncate(count);
        self.xs.resize(len, 0.0);
        let mut at = 0;
        for &(j, lo, hi) in &self.windows {
            let mu = 0.5 * (edges[j] + edges[j + 1]);
            let xs = &mut self.xs[at..at + hi - lo + 2];
            for (x, &e) in xs.iter_mut().zip(&edges[lo..=hi + 1]) {
                *x = (e - mu) * inv_sigma;
            }
            at += hi - lo + 2;
        }
        self.cdf.resize(self.xs.len(), 0.0);
        normal_cdf_slice(&self.xs, &mut self.cdf);
        let (mut sum, mut at) = (0.0, 0);
        for &(j, lo, hi) in &self.windows {
            let cdf = &self.cdf[at..at + hi - lo + 2];
            at += hi - lo + 2;
            let mut acc = c[hi] * cdf[hi + 1 - lo] - c[lo] * cdf[0];
            for e in lo + 1..=hi {
                acc += (c[e - 1] - c[e]) * cdf[e - lo];
            }
            sum += p[j] * acc;
        }
        sum
    }
}

/// ∫ p(z) C_{k(z)} dz over the cells by the midpoint rule; p(z) is summed over all j at each
/// point (O(n) per point). C uses the same prefix sums as FSMI, so FSMI's speed-up measured
/// against this is that of the analytic integration alone.
fn julian_integral(p: &[f64], c: &[f64], edges: &[f64], sigma: f64, points: usize) -> f64 {
    let n = p.len();
    let inv_sigma = 1.0 / sigma;
    let mut total = 0.0;
    for k in 0..n {
        let width = edges[k + 1] - edges[k];
        if width <= 0.0 || c[k] == 0.0 {
            continue;
        }
        let h = width / points as f64;
        let mut mass = 0.0;
        for m in 0..points {
            let z = edges[k] + (m as f64 + 0.5) * h;
            for j in 0..n {
                if p[j] > 0.0 {
                    let u = (z - 0.5 * (edges[j] + edges[j + 1])) * inv_sigma;
                    mass += p[j] * (-0.5 * u * u).exp();
                }
            }
        }
        total += c[k] * mass * h;
    }
    total * inv_sigma / SQRT_2PI
}

/// A map update: (lattice node id, new occupancy probability) pairs, sorted by id.
pub type ProbabilityUpdate = Vec<(usize, f64)>;

/// Refuses non-finite positions and positions outside the lattice.
pub(crate) fn lattice_origin(map: &OccupancyLattice, pose: &[f64; 3]) -> Result<[f64; 2]> {
    refuse("pose", pose, f64::is_finite)?;
    let (lo, hi) = rect_box(map.geometry(), &map.rect());
    if pose[0] < lo[0] || pose[0] > hi[0] || pose[1] < lo[1] || pose[1] > hi[1] {
        return Err(CrlamError::OutOfBounds(format!(
            "position ({}, {}) is outside the lattice",
            pose[0], pose[1]
        )));
    }
    Ok([pose[0], pose[1]])
}

/// OGMI on the lattice: the sum over a virtual scan's beams of a beam MI (nats). Name `"fsmi"`,
/// or `"ogmi_julian"` for the [`FsmiVariant::Julian`] reference.
///
/// Each beam is an exact traversal of the lattice (each cell once, with its entry and exit
/// distances as edges) from the candidate position for `z_max`, cut at the lattice border.
///
/// Map mutation (our design; the papers do not define one): the virtual scan of the inverse
/// sensor model. Each beam reads the first traversed cell with o > `p_occ` (the reference
/// sensor's threshold); the odds of the cells before it are multiplied by δ_emp and its own by
/// δ_occ, and every cell of a max-range beam by δ_emp. A cell crossed by several beams gets every
/// beam's factor. The update lists (node id, new probability), sorted by id.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fsmi {
    pub params: OgmiParams,
    pub variant: FsmiVariant,
    /// Beams per scan (10).
    pub n_beams: usize,
    pub beam_angles: BeamAngles,
    /// Occupancy above which the virtual scan stops (0.65).
    pub p_occ: f64,
}

impl Default for Fsmi {
    fn default() -> Self {
        Self::new(FsmiVariant::Full)
    }
}

impl Fsmi {
    /// Defaults: [`OgmiParams::default`], 10 distinct beams, p_occ = 0.65.
    pub fn new(variant: FsmiVariant) -> Self {
        Self {
            params: OgmiParams::default(),
            variant,
            n_beams: 10,
            beam_angles: BeamAngles::Distinct,
            p_occ: 0.65,
        }
    }

    pub fn validate(&self) -> Result<()> {
        self.params.validate()?;
        self.variant.validate()?;
        if self.n_beams == 0 {
            return Err(config_err("n_beams", "must be ≥ 1"));
        }
        if !(0.0..=1.0).contains(&self.p_occ) {
            return Err(config_err(
                "p_occ",
                format!("must be in [0, 1], got {}", self.p_occ),
            ));
        }
        Ok(())
    }

    /// Scan MI (nats) at `pose` (x, y, θ in m, m, rad) without building the map update.
    pub fn scan_mi(&self, map: &OccupancyLattice, pose: [f64; 3]) -> Result<f64> {
        self.scan(map, pose, None)
    }

    /// The scan MI; when `factors` is given, also pushes (id, ln odds factor) per traversed cell.
    fn scan(
        &self,
        map: &OccupancyLattice,
        pose: [f64; 3],
        factors: Option<&mut Vec<(usize, f64)>>,
    ) -> Result<f64> {
        self.validate()?;
        let origin = lattice_origin(map, &pose)?;
        thread_local! {
            static SCRATCH: std::cell::RefCell<ScanScratch> = std::cell::RefCell::default();
        }
        SCRATCH.with(|sc| Ok(self.scan_with(map, origin, pose[2], factors, &mut sc.borrow_mut())))
    }

    /// [`Self::scan`] after its checks, in reusable buffers.
    fn scan_with(
        &self,
        map: &OccupancyLattice,
        origin: [f64; 2],
        heading: f64,
        mut factors: Option<&mut Vec<(usize, f64)>>,
        sc: &mut ScanScratch,
    ) -> f64 {
        let (ln_occ, ln_emp) = (self.params.delta_occ.ln(), self.params.delta_emp.ln());
        let ScanScratch {
            cells,
            o,
            edges,
            terms,
        } = sc;
        let mut total = 0.0;
        for angle in self.beam_angles.angles(self.n_beams, heading) {
            traverse_lattice(map, origin, angle, self.params.z_max, cells);
            o.clear();
            o.extend(cells.iter().map(|cell| map.get(cell.id)));
            edges.clear();
            edges.extend(cells.iter().map(|cell| cell.t_in));
            edges.push(cells.last().map_or(0.0, |c| c.t_out));
            total += beam_mi_unchecked(terms, o, edges, &self.params, self.variant);
            if let Some(out) = factors.as_deref_mut() {
                let hit = o.iter().position(|&p| p > self.p_occ);
                for (i, cell) in cells.iter().enumerate() {
                    match hit {
                        Some(h) if i > h => break,
                        Some(h) if i == h => out.push((cell.id, ln_occ)),
                        _ => out.push((cell.id, ln_emp)),
                    }
                }
            }
        }
        total
    }
}

/// The per-thread buffers of [`Fsmi`]'s scans.
#[derive(Debug, Default)]
struct ScanScratch {
    cells: Vec<LatticeCell>,
    o: Vec<f64>,
    edges: Vec<f64>,
    terms: BeamTerms,
}

impl InformationFunction for Fsmi {
    type Map = OccupancyLattice;
    type Belief = ();
    type Update = ProbabilityUpdate;

    fn name(&self) -> &'static str {
        match self.variant {
            FsmiVariant::Julian { .. } => "ogmi_julian",
            _ => "fsmi",
        }
    }

    fn units(&self) -> InfoUnits {
        InfoUnits::Nats
    }

    fn gain(
        &self,
        map: &OccupancyLattice,
        _parent: &(),
        candidate: &Candidate,
        _seed: u64,
    ) -> Result<f64> {
        self.scan(map, candidate.pose, None)
    }

    fn evaluate(
        &self,
        map: &OccupancyLattice,
        _parent: &(),
        candidate: &Candidate,
        _seed: u64,
    ) -> Result<Evaluation<(), Self::Update>> {
        let mut factors = Vec::new();
        let gain = self.scan(map, candidate.pose, Some(&mut factors))?;
        factors.sort_unstable_by_key(|&(id, _)| id);
        let mut update: Vec<(usize, f64)> = Vec::new();
        for (id, ln_factor) in factors {
            match update.last_mut() {
                Some(last) if last.0 == id => last.1 += ln_factor,
                _ => update.push((id, ln_factor)),
            }
        }
        for (id, value) in update.iter_mut() {
            // Odds r·F as a probability; o ∈ {0, 1} stays put.
            let (o, f) = (map.get(*id), value.exp());
            *value = o * f / (o * f + (1.0 - o));
        }
        Ok(Evaluation {
            gain,
            belief: (),
            update,
        })
    }

    fn commit(&self, map: &mut OccupancyLattice, update: &Self::Update) -> Result<()> {
        commit_probabilities(map, update)
    }
}

/// Writes (id, probability) pairs after checking all of them.
pub(crate) fn commit_probabilities(
    map: &mut OccupancyLattice,
    update: &[(usize, f64)],
) -> Result<()> {
    for &(id, p) in update {
        if id >= map.len() {
            return Err(CrlamError::OutOfBounds(format!(
                "node {id} of {}",
                map.len()
            )));
        }
        refuse("probability", &[p], is_probability)?;
    }
    for &(id, p) in update {
        map.set(id, p);
    }
    Ok(())
}
