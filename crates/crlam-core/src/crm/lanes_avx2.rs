//! The far phase, window and tail lanes of [`super::far_simd`] and [`super::window_simd`] with
//! AVX2: four lanes per 256-bit register, the sixteen beams of a group in four sets stepped in
//! one loop (so their dependency chains overlap, as the two sets of the AVX-512 lanes do).
//!
//! Each function does, lane for lane, what its AVX-512 counterpart does, with the same
//! operations in the same order (masks are full-width lane masks instead of mask registers,
//! masked operations are blends of the unmasked result), so every beam ends in the state the
//! scalar loop would reach, bit for bit (the tests of [`super::far_simd`] and the windowed
//! kernel's run every level against the scalar kernel).

use std::arch::x86_64::*;

use super::lane_io::{FarStop, TailLanesIo, WindowLanesIo, WindowModel, LANES};
use crate::crm::windowed::TAIL_EPS;
use crate::numeric::fastmath::{exp_for_sums_x4, exp_table_x4};
use crate::raycast::FastWalk;
use crate::sensor::{GAUSS_CUTOFF_SIGMAS, SQRT_2PI, TRUNC_SIGMAS};

/// Lanes of one AVX2 register of f64.
const SET: usize = 4;
/// Sets of lanes a call steps together.
const SETS: usize = LANES / SET;

/// A lane mask: all bits set in the lanes that are on.
type Mask = __m256d;

/// The lanes of set `s` among `n`.
fn set_range(s: usize, n: usize) -> std::ops::Range<usize> {
    (s * SET).min(n)..((s + 1) * SET).min(n)
}

#[target_feature(enable = "avx2")]
#[inline]
unsafe fn and(a: Mask, b: Mask) -> Mask {
    _mm256_and_pd(a, b)
}

/// `b` and not `a`.
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn and_not(a: Mask, b: Mask) -> Mask {
    _mm256_andnot_pd(a, b)
}

#[target_feature(enable = "avx2")]
#[inline]
unsafe fn or(a: Mask, b: Mask) -> Mask {
    _mm256_or_pd(a, b)
}

#[target_feature(enable = "avx2")]
#[inline]
unsafe fn not(a: Mask) -> Mask {
    _mm256_xor_pd(a, _mm256_castsi256_pd(_mm256_set1_epi64x(-1)))
}

#[target_feature(enable = "avx2")]
#[inline]
unsafe fn any(a: Mask) -> bool {
    _mm256_movemask_pd(a) != 0
}

#[target_feature(enable = "avx2")]
#[inline]
unsafe fn lane_bits(a: Mask) -> u8 {
    _mm256_movemask_pd(a) as u8
}

/// The mask of the lanes whose bit is set in `bits`.
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn mask_of(bits: u8) -> Mask {
    let on = |i: u8| if bits & (1 << i) != 0 { -1i64 } else { 0 };
    _mm256_castsi256_pd(_mm256_setr_epi64x(on(0), on(1), on(2), on(3)))
}

/// `m̂` of the lanes `take` from `means` at the walks' indices (1 elsewhere, no read there).
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn gather_means(means: &[f64], index: __m256i, take: Mask) -> __m256d {
    _mm256_mask_i64gather_pd::<8>(_mm256_set1_pd(1.0), means.as_ptr(), index, take)
}

/// Four [`FastWalk`]s stepped together, with the operations of `next` in its order.
#[derive(Clone, Copy)]
struct WalkLanes {
    tx: __m256d,
    ty: __m256d,
    dtx: __m256d,
    dty: __m256d,
    t_in: __m256d,
    t_end: __m256d,
    ix: __m256i,
    iy: __m256i,
    index: __m256i,
    sx: __m256i,
    sy: __m256i,
    isx: __m256i,
    isy: __m256i,
    steps: __m256i,
    /// Lanes holding a walk that has cells left.
    live: Mask,
    /// Lanes whose walk reached its end (`done`).
    ended: Mask,
}

/// The next crossing of a set of walks (as [`super::far_simd::Crossing`]).
struct Crossing {
    t_out: __m256d,
    reported: Mask,
    along_x: Mask,
}

impl WalkLanes {
    #[target_feature(enable = "avx2")]
    unsafe fn load<'w>(walks: impl Iterator<Item = &'w FastWalk>) -> Self {
        let mut f = [[0.0f64; SET]; 6];
        let mut k = [[0i64; SET]; 8];
        let mut live = 0u8;
        for (i, w) in walks.enumerate() {
            let s = w.parts();
            [f[0][i], f[1][i], f[2][i], f[3][i], f[4][i], f[5][i]] =
                [s.tx, s.ty, s.dtx, s.dty, s.t_in, s.t_end];
            [
                k[0][i], k[1][i], k[2][i], k[3][i], k[4][i], k[5][i], k[6][i],
            ] = [
                s.ix,
                s.iy,
                s.index,
                s.step_x,
                s.step_y,
                s.index_step_x,
                s.index_step_y,
            ];
            k[7][i] = s.steps_left as i64;
            if !s.done && s.steps_left > 0 {
                live |= 1 << i;
            }
        }
        let ld = |a: &[f64; SET]| _mm256_loadu_pd(a.as_ptr());
        let li = |a: &[i64; SET]| _mm256_loadu_si256(a.as_ptr() as *const __m256i);
        Self {
            tx: ld(&f[0]),
            ty: ld(&f[1]),
            dtx: ld(&f[2]),
            dty: ld(&f[3]),
            t_in: ld(&f[4]),
            t_end: ld(&f[5]),
            ix: li(&k[0]),
            iy: li(&k[1]),
            index: li(&k[2]),
            sx: li(&k[3]),
            sy: li(&k[4]),
            isx: li(&k[5]),
            isy: li(&k[6]),
            steps: li(&k[7]),
            live: mask_of(live),
            ended: _mm256_setzero_pd(),
        }
    }

    /// FastWalk::next's crossing: the nearer one, cut at the ray's end, never before t_in.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn crossing(&self) -> Crossing {
        let along_x = _mm256_cmp_pd::<_CMP_LE_OQ>(self.tx, self.ty);
        let near = _mm256_blendv_pd(self.ty, self.tx, along_x);
        let near = _mm256_blendv_pd(
            near,
            self.t_end,
            _mm256_cmp_pd::<_CMP_LT_OQ>(self.t_end, near),
        );
        let t_out = _mm256_blendv_pd(
            near,
            self.t_in,
            _mm256_cmp_pd::<_CMP_LT_OQ>(near, self.t_in),
        );
        let min_chord = _mm256_set1_pd(crate::raycast::MIN_CHORD);
        let reported = _mm256_cmp_pd::<_CMP_GE_OQ>(_mm256_sub_pd(t_out, self.t_in), min_chord);
        Crossing {
            t_out,
            reported,
            along_x,
        }
    }

    /// Moves the lanes `adv` past the cell of `c`; returns the lanes that still have cells.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn advance(&mut self, adv: Mask, c: &Crossing) -> Mask {
        let done = and(adv, _mm256_cmp_pd::<_CMP_GE_OQ>(c.t_out, self.t_end));
        let (ax, ay) = (and(adv, c.along_x), and_not(c.along_x, adv));
        self.tx = _mm256_blendv_pd(self.tx, _mm256_add_pd(self.tx, self.dtx), ax);
        self.ty = _mm256_blendv_pd(self.ty, _mm256_add_pd(self.ty, self.dty), ay);
        let (axi, ayi) = (_mm256_castpd_si256(ax), _mm256_castpd_si256(ay));
        self.ix = _mm256_add_epi64(self.ix, _mm256_and_si256(self.sx, axi));
        self.iy = _mm256_add_epi64(self.iy, _mm256_and_si256(self.sy, ayi));
        self.index = _mm256_add_epi64(self.index, _mm256_and_si256(self.isx, axi));
        self.index = _mm256_add_epi64(self.index, _mm256_and_si256(self.isy, ayi));
        self.t_in = _mm256_blendv_pd(self.t_in, c.t_out, adv);
        // The lanes of `adv` are −1 as integers.
        self.steps = _mm256_add_epi64(self.steps, _mm256_castpd_si256(adv));
        self.ended = or(self.ended, done);
        let left = _mm256_castsi256_pd(_mm256_cmpgt_epi64(self.steps, _mm256_setzero_si256()));
        and_not(done, and(adv, left))
    }

    /// Hands each live lane's state back to its walk.
    #[target_feature(enable = "avx2")]
    unsafe fn store<'w>(&self, walks: impl Iterator<Item = &'w mut FastWalk>) {
        let mut f = [[0.0f64; SET]; 3];
        let mut k = [[0i64; SET]; 4];
        let st = |v: __m256d, a: &mut [f64; SET]| _mm256_storeu_pd(a.as_mut_ptr(), v);
        let sti =
            |v: __m256i, a: &mut [i64; SET]| _mm256_storeu_si256(a.as_mut_ptr() as *mut __m256i, v);
        st(self.tx, &mut f[0]);
        st(self.ty, &mut f[1]);
        st(self.t_in, &mut f[2]);
        sti(self.ix, &mut k[0]);
        sti(self.iy, &mut k[1]);
        sti(self.index, &mut k[2]);
        sti(self.steps, &mut k[3]);
        let (live, ended) = (lane_bits(self.live), lane_bits(self.ended));
        for (i, w) in walks.enumerate() {
            if live & (1 << i) != 0 {
                w.resume(
                    [f[0][i], f[1][i], f[2][i]],
                    [k[0][i], k[1][i], k[2][i]],
                    k[3][i] as usize,
                    ended & (1 << i) != 0,
                );
            }
        }
    }
}

/// Up to four values into a register (zeros past `v`'s end).
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn load_padded(v: &[f64]) -> __m256d {
    let mut a = [0.0; SET];
    a[..v.len()].copy_from_slice(v);
    _mm256_loadu_pd(a.as_ptr())
}

#[target_feature(enable = "avx2")]
#[inline]
unsafe fn to_array(v: __m256d) -> [f64; SET] {
    let mut a = [0.0; SET];
    _mm256_storeu_pd(a.as_mut_ptr(), v);
    a
}

/// One set of far-phase lanes.
#[derive(Clone, Copy)]
struct FarLanes {
    walk: WalkLanes,
    lo: __m256d,
    reach: __m256d,
    active: Mask,
    /// The stop rule's terms ([`FarStop`]; unused without it).
    sup: __m256d,
    far_like: __m256d,
    tol: __m256d,
    /// Far cells taken per lane, and the lanes the rule stopped.
    count: __m256i,
    stopped: Mask,
}

impl FarLanes {
    /// Lanes from `walks`, their far ends and reaches, and the stop rule's terms (zero
    /// without one).
    #[target_feature(enable = "avx2")]
    unsafe fn load(
        walks: &[FastWalk],
        lo: &[f64],
        reach: &[f64],
        stop: Option<(&FarStop, std::ops::Range<usize>)>,
    ) -> Self {
        let walk = WalkLanes::load(walks.iter());
        let active = walk.live;
        let (sup, far_like, tol) = match stop {
            Some((st, r)) => (
                load_padded(&st.sup[r.clone()]),
                load_padded(&st.far_like[r]),
                _mm256_set1_pd(st.tol),
            ),
            None => (load_padded(&[]), load_padded(&[]), load_padded(&[])),
        };
        Self {
            walk,
            lo: load_padded(lo),
            reach: load_padded(reach),
            active,
            sup,
            far_like,
            tol,
            count: _mm256_setzero_si256(),
            stopped: _mm256_setzero_pd(),
        }
    }

    /// One cell of every active lane, as [`super::far_simd`]'s `FarLanes::step`.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn step<const STOP: bool>(&mut self, means: &[f64]) {
        let c = self.walk.crossing();
        let d = _mm256_mul_pd(_mm256_set1_pd(0.5), _mm256_add_pd(self.walk.t_in, c.t_out));
        let far = _mm256_cmp_pd::<_CMP_LT_OQ>(d, self.lo);
        let stop = and(self.active, and_not(far, c.reported));
        let adv = and_not(stop, self.active);
        let take = and(adv, c.reported);
        let one = _mm256_set1_pd(1.0);
        let m = gather_means(means, self.walk.index, take);
        self.reach = _mm256_blendv_pd(
            self.reach,
            _mm256_mul_pd(self.reach, _mm256_sub_pd(one, m)),
            take,
        );
        self.active = self.walk.advance(adv, &c);
        if STOP {
            // The scalar loop's `count % 16 == 0 && R·sup <= tol·(1 − R)·L_far`.
            let taken = _mm256_and_si256(_mm256_castpd_si256(take), _mm256_set1_epi64x(1));
            self.count = _mm256_add_epi64(self.count, taken);
            let sixteenth = and(
                take,
                _mm256_castsi256_pd(_mm256_cmpeq_epi64(
                    _mm256_and_si256(self.count, _mm256_set1_epi64x(15)),
                    _mm256_setzero_si256(),
                )),
            );
            if any(sixteenth) {
                let lhs = _mm256_mul_pd(self.reach, self.sup);
                let rhs = _mm256_mul_pd(
                    _mm256_mul_pd(self.tol, _mm256_sub_pd(one, self.reach)),
                    self.far_like,
                );
                let hit = and(sixteenth, _mm256_cmp_pd::<_CMP_LE_OQ>(lhs, rhs));
                self.stopped = or(self.stopped, hit);
                self.active = and_not(hit, self.active);
            }
        }
    }

    #[target_feature(enable = "avx2")]
    unsafe fn store(
        &self,
        walks: &mut [FastWalk],
        reach: &mut [f64],
        stopped: Option<&mut [bool]>,
    ) {
        let r = to_array(self.reach);
        self.walk.store(walks.iter_mut());
        let live = lane_bits(self.walk.live);
        for (i, out) in reach.iter_mut().enumerate() {
            if live & (1 << i) != 0 {
                *out = r[i];
            }
        }
        if let Some(stopped) = stopped {
            let bits = lane_bits(self.stopped);
            for (i, s) in stopped.iter_mut().enumerate() {
                *s = bits & (1 << i) != 0;
            }
        }
    }
}

/// [`super::far_simd::far_phase`] with AVX2.
///
/// # Safety
/// The CPU must support AVX2; every index the walks reach must lie in `means`.
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn far_phase_avx2(
    walks: &mut [FastWalk],
    lo: &[f64],
    reach: &mut [f64],
    means: &[f64],
    mut stop: Option<FarStop>,
) {
    let n = walks.len();
    let mut sets = [FarLanes::load(&[], &[], &[], None); SETS];
    for (s, set) in sets.iter_mut().enumerate() {
        let r = set_range(s, n);
        let st = stop.as_ref().map(|st| (st, r.clone()));
        *set = FarLanes::load(&walks[r.clone()], &lo[r.clone()], &reach[r], st);
    }
    if stop.is_some() {
        far_loop::<true>(&mut sets, means);
    } else {
        far_loop::<false>(&mut sets, means);
    }
    for (s, set) in sets.iter().enumerate() {
        let r = set_range(s, n);
        let stopped = stop.as_mut().map(|st| &mut st.stopped[r.clone()]);
        set.store(&mut walks[r.clone()], &mut reach[r], stopped);
    }
}

/// Steps the sets of far lanes until none is active.
#[target_feature(enable = "avx2")]
unsafe fn far_loop<const STOP: bool>(sets: &mut [FarLanes; SETS], means: &[f64]) {
    loop {
        let mut stepped = false;
        for set in sets.iter_mut() {
            if any(set.active) {
                set.step::<STOP>(means);
                stepped = true;
            }
        }
        if !stepped {
            break;
        }
    }
}

/// One set of tail lanes.
#[derive(Clone, Copy)]
struct TailLanes {
    walk: WalkLanes,
    reach: __m256d,
    mass: __m256d,
    short: __m256d,
    base: __m256d,
    sup_past: __m256d,
    active: Mask,
    stopped: Mask,
}

impl TailLanes {
    /// The lanes `range` of `io`.
    #[target_feature(enable = "avx2")]
    unsafe fn load(io: &TailLanesIo, range: std::ops::Range<usize>) -> Self {
        let mut walk = WalkLanes::load(io.walks[range.clone()].iter());
        let mut enabled = 0u8;
        for (i, &on) in io.enabled[range.clone()].iter().enumerate() {
            if on {
                enabled |= 1 << i;
            }
        }
        walk.live = and(walk.live, mask_of(enabled));
        let active = walk.live;
        Self {
            walk,
            reach: load_padded(&io.reach[range.clone()]),
            mass: load_padded(&io.mass[range.clone()]),
            short: load_padded(&io.short[range.clone()]),
            base: load_padded(&io.base[range.clone()]),
            sup_past: load_padded(&io.sup_past[range]),
            active,
            stopped: _mm256_setzero_pd(),
        }
    }

    /// One cell of every active lane, as [`super::far_simd`]'s `TailLanes::step`.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn step(&mut self, means: &[f64], floor: __m256d, neg_lambda: __m256d) {
        let c = self.walk.crossing();
        let take = and(self.active, c.reported);
        let d = _mm256_mul_pd(_mm256_set1_pd(0.5), _mm256_add_pd(self.walk.t_in, c.t_out));
        let one = _mm256_set1_pd(1.0);
        let m = gather_means(means, self.walk.index, take);
        let pi = _mm256_mul_pd(self.reach, m);
        let e = exp_for_sums_x4(_mm256_mul_pd(neg_lambda, d));
        let term = _mm256_div_pd(pi, _mm256_sub_pd(one, e));
        self.short = _mm256_blendv_pd(self.short, _mm256_add_pd(self.short, term), take);
        self.mass = _mm256_blendv_pd(self.mass, _mm256_add_pd(self.mass, pi), take);
        self.reach = _mm256_blendv_pd(
            self.reach,
            _mm256_mul_pd(self.reach, _mm256_sub_pd(one, m)),
            take,
        );
        let total = _mm256_add_pd(self.base, _mm256_mul_pd(floor, self.mass));
        let stop = and(
            take,
            _mm256_cmp_pd::<_CMP_LE_OQ>(
                _mm256_mul_pd(self.reach, self.sup_past),
                _mm256_mul_pd(total, _mm256_set1_pd(TAIL_EPS)),
            ),
        );
        self.stopped = or(self.stopped, stop);
        self.active = and_not(stop, self.walk.advance(self.active, &c));
    }

    #[target_feature(enable = "avx2")]
    unsafe fn store(&self, io: &mut TailLanesIo, range: std::ops::Range<usize>) {
        let (reach, mass, short) = (
            to_array(self.reach),
            to_array(self.mass),
            to_array(self.short),
        );
        self.walk.store(io.walks[range.clone()].iter_mut());
        let (live, stopped) = (lane_bits(self.walk.live), lane_bits(self.stopped));
        for (i, lane) in range.enumerate() {
            if live & (1 << i) != 0 {
                io.reach[lane] = reach[i];
                io.mass[lane] = mass[i];
                io.short[lane] = short[i];
                io.stopped[lane] = stopped & (1 << i) != 0;
            }
        }
    }
}

/// [`super::far_simd::tail_phase`] with AVX2.
///
/// # Safety
/// The CPU must support AVX2; every index the walks reach must lie in `means`.
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn tail_phase_avx2(
    mut io: TailLanesIo,
    means: &[f64],
    floor: f64,
    neg_lambda: f64,
) {
    let (floor, neg_lambda) = (_mm256_set1_pd(floor), _mm256_set1_pd(neg_lambda));
    let n = io.walks.len();
    let mut sets = [TailLanes::load(&io, 0..0); SETS];
    for (s, set) in sets.iter_mut().enumerate() {
        *set = TailLanes::load(&io, set_range(s, n));
    }
    loop {
        let mut stepped = false;
        for set in sets.iter_mut() {
            if any(set.active) {
                set.step(means, floor, neg_lambda);
                stepped = true;
            }
        }
        if !stepped {
            break;
        }
    }
    for (s, set) in sets.iter().enumerate() {
        set.store(&mut io, set_range(s, n));
    }
}

/// The broadcast constants of one window step.
struct Consts {
    sigma: __m256d,
    peak_denominator: __m256d,
    cutoff: __m256d,
    trunc: __m256d,
    z_max: __m256d,
    hit_reach: __m256d,
    neg_lambda: __m256d,
    w_hit: __m256d,
    w_short: __m256d,
    floor: __m256d,
}

/// One set of window lanes.
#[derive(Clone, Copy)]
struct WindowLanes {
    walk: WalkLanes,
    reach: __m256d,
    z: __m256d,
    map_length: __m256d,
    short_numerator: __m256d,
    reach_far: __m256d,
    entered: Mask,
    eta: __m256d,
    active: Mask,
    /// Lanes with a mapping ray (the scalar kernel's `map_on`).
    map_on: Mask,
    at_tail: Mask,
    bailed: Mask,
}

impl WindowLanes {
    /// The lanes `range` of `io`.
    #[target_feature(enable = "avx2")]
    unsafe fn load(io: &WindowLanesIo, range: std::ops::Range<usize>) -> Self {
        let walk = WalkLanes::load(io.walks[range.clone()].iter());
        let active = walk.live;
        let map_length = load_padded(&io.map_length[range.clone()]);
        let map_on = _mm256_cmp_pd::<_CMP_GT_OQ>(map_length, _mm256_set1_pd(f64::NEG_INFINITY));
        Self {
            walk,
            reach: load_padded(&io.reach[range.clone()]),
            z: load_padded(&io.z[range.clone()]),
            map_length,
            map_on,
            at_tail: _mm256_setzero_pd(),
            bailed: _mm256_setzero_pd(),
            short_numerator: load_padded(&io.short_numerator[range]),
            reach_far: _mm256_set1_pd(f64::NAN),
            entered: _mm256_setzero_pd(),
            eta: _mm256_setzero_pd(),
            active,
        }
    }

    /// One cell of every active lane, as [`super::window_simd`]'s `WindowLanes::step`.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn step(&mut self, means: &[f64], k: &Consts) {
        let c = self.walk.crossing();
        let (add, sub, mul) = (
            |a, b| _mm256_add_pd(a, b),
            |a, b| _mm256_sub_pd(a, b),
            |a, b| _mm256_mul_pd(a, b),
        );
        let t_in = self.walk.t_in;
        let d = mul(_mm256_set1_pd(0.5), add(t_in, c.t_out));
        // in_map: t_in < m_len && m_len − t_in ≥ MIN_CHORD.
        let in_map = and(
            _mm256_cmp_pd::<_CMP_LT_OQ>(t_in, self.map_length),
            _mm256_cmp_pd::<_CMP_GE_OQ>(
                sub(self.map_length, t_in),
                _mm256_set1_pd(crate::raycast::MIN_CHORD),
            ),
        );
        let abs = |v: __m256d| _mm256_andnot_pd(_mm256_set1_pd(-0.0), v);
        let in_hit = _mm256_cmp_pd::<_CMP_LE_OQ>(abs(sub(d, self.z)), k.hit_reach);
        // Not past the hit reach (the scalar tail test is d − z > hit reach).
        let in_hit_raw = _mm256_cmp_pd::<_CMP_NGT_UQ>(sub(d, self.z), k.hit_reach);
        let u = _mm256_div_pd(sub(self.z, d), k.sigma);
        let gauss = and(in_hit, _mm256_cmp_pd::<_CMP_NGT_UQ>(abs(u), k.cutoff));
        let untruncated = and(
            _mm256_cmp_pd::<_CMP_GT_OQ>(d, k.trunc),
            _mm256_cmp_pd::<_CMP_GT_OQ>(sub(k.z_max, d), k.trunc),
        );
        // The short term: 0 unless z ≤ d and d > 0 (the scalar `z > d || d <= 0.0` negated).
        let short_on = and(
            _mm256_cmp_pd::<_CMP_NGT_UQ>(self.z, d),
            _mm256_cmp_pd::<_CMP_NLE_UQ>(d, _mm256_setzero_pd()),
        );
        let x_short = mul(k.neg_lambda, d);
        let x_ok = and(
            _mm256_cmp_pd::<_CMP_GE_OQ>(x_short, _mm256_set1_pd(-708.0)),
            _mm256_cmp_pd::<_CMP_LE_OQ>(x_short, _mm256_set1_pd(709.0)),
        );
        let tail = and_not(in_hit_raw, and_not(in_map, self.map_on));
        let handled = and(
            in_map,
            and(or(not(gauss), untruncated), or(not(short_on), x_ok)),
        );
        let stop = and(self.active, and_not(handled, c.reported));
        self.at_tail = or(self.at_tail, and(stop, tail));
        self.bailed = or(self.bailed, and_not(tail, stop));
        let adv = and_not(stop, self.active);
        let take = and(adv, c.reported);
        let one = _mm256_set1_pd(1.0);
        let m = gather_means(means, self.walk.index, take);
        let first = and_not(self.entered, take);
        self.reach_far = _mm256_blendv_pd(self.reach_far, self.reach, first);
        self.entered = or(self.entered, take);
        // −0.5·u·u stays within exp_table's range (|u| ≤ 37) wherever it is used.
        let x_hit = mul(mul(_mm256_set1_pd(-0.5), u), u);
        let peak = _mm256_div_pd(exp_table_x4(x_hit), k.peak_denominator);
        let hit = and(gauss, peak);
        let short_term = _mm256_div_pd(self.short_numerator, sub(one, exp_table_x4(x_short)));
        let short = and(short_on, short_term);
        let like = add(add(mul(k.w_hit, hit), mul(k.w_short, short)), k.floor);
        let pi_l = mul(mul(self.reach, m), like);
        self.eta = _mm256_blendv_pd(self.eta, add(self.eta, pi_l), take);
        self.reach = _mm256_blendv_pd(self.reach, mul(self.reach, sub(one, m)), take);
        self.active = self.walk.advance(adv, &c);
    }

    #[target_feature(enable = "avx2")]
    unsafe fn store(&self, io: &mut WindowLanesIo, range: std::ops::Range<usize>) {
        let (reach, reach_far, eta) = (
            to_array(self.reach),
            to_array(self.reach_far),
            to_array(self.eta),
        );
        self.walk.store(io.walks[range.clone()].iter_mut());
        let live = lane_bits(self.walk.live);
        let (at_tail, bailed) = (lane_bits(self.at_tail), lane_bits(self.bailed));
        for (i, lane) in range.enumerate() {
            if live & (1 << i) != 0 {
                io.reach[lane] = reach[i];
                io.reach_far[lane] = reach_far[i];
                io.eta[lane] = eta[i];
                io.at_tail[lane] = at_tail & (1 << i) != 0;
                io.bailed[lane] = bailed & (1 << i) != 0;
            }
        }
    }
}

/// [`super::window_simd::window_phase`] with AVX2.
///
/// # Safety
/// The CPU must support AVX2; every index the walks reach must lie in `means`.
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn window_phase_avx2(mut io: WindowLanesIo, means: &[f64], w: &WindowModel) {
    let m = &w.model;
    let s = m.sigma_hit;
    let set = |v: f64| _mm256_set1_pd(v);
    // The scalar expressions, so the same constants.
    let k = Consts {
        sigma: set(s),
        peak_denominator: set(s * SQRT_2PI),
        cutoff: set(GAUSS_CUTOFF_SIGMAS),
        trunc: set(TRUNC_SIGMAS * s),
        z_max: set(m.z_max),
        hit_reach: set(w.hit_reach),
        neg_lambda: set(-m.lambda_short),
        w_hit: set(m.w_hit),
        w_short: set(m.w_short),
        floor: set(m.w_rand / m.z_max),
    };
    let n = io.walks.len();
    let mut sets = [WindowLanes::load(&io, 0..0); SETS];
    for (s, set) in sets.iter_mut().enumerate() {
        *set = WindowLanes::load(&io, set_range(s, n));
    }
    loop {
        let mut stepped = false;
        for set in sets.iter_mut() {
            if any(set.active) {
                set.step(means, &k);
                stepped = true;
            }
        }
        if !stepped {
            break;
        }
    }
    for (s, set) in sets.iter().enumerate() {
        set.store(&mut io, set_range(s, n));
    }
}
