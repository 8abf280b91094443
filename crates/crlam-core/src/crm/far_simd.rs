//! The far phase and the tail of up to sixteen weighed beams at once, in two sets of eight
//! AVX-512 lanes (or four sets of four AVX2 lanes, [`super::lanes_avx2`], by the level of
//! [`crate::simd`]).
//!
//! A weight needs nothing from the cells far before a reading (or from any cell of a no-return)
//! but the reach R = Π (1 − m̂) ([`super::windowed`]): a walk, a mean and a product per cell,
//! which a scalar loop does at the speed of its walk's branch. Here each lane walks one beam
//! (a [`FastWalk`], the same operations in the same order as its `next`), reads its cells' means
//! by a gather from the scan's mean table and multiplies its reach, until the lane reaches a cell
//! that is not far (left unconsumed, for the window lanes of [`super::window_simd`] or the scalar
//! kernel to take up), or its ray ends. Every lane ends in the state the scalar loop would have
//! reached, bit for bit, so what follows goes on as if the beam had been walked alone.
//!
//! The tail of a weighed beam, past the mapping ray and the weight's hit reach, is again a walk
//! with a little arithmetic per cell: each cause's probability π = R·m̂ goes into Σ π and, with
//! e^{−λd}, into Σ π/(1 − e^{−λd}), until the stop rule of [`super::windowed`] holds or the ray
//! ends. [`tail_phase`] walks the tails of the beams whose window lanes stopped at their first
//! tail cell, with the scalar loop's operations in its order (the exponential is
//! [`exp_for_sums_avx512`], lane for lane the scalar one), so every lane ends as the scalar
//! loop would, bit for bit. [`super::lanes`] drives the three phases.
//!
//! A lane's step is a chain of dependent operations (crossing, midpoint, compare, gather,
//! product), so one set of eight lanes leaves the core waiting on latencies; two independent sets
//! stepped in the same loop overlap their chains.

pub(crate) use super::lane_io::FarStop;
use super::lane_io::{TailLanesIo, LANES};
#[cfg(target_arch = "x86_64")]
use crate::crm::windowed::TAIL_EPS;
#[cfg(target_arch = "x86_64")]
use crate::numeric::fastmath::exp_for_sums_avx512;
use crate::raycast::FastWalk;
use crate::simd::SimdLevel;
#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;

/// Lanes of one AVX-512 register of f64.
pub(crate) const SET: usize = 8;

const _: () = assert!(LANES == 2 * SET, "a call steps two sets of AVX-512 lanes");

/// Runs the far phase of `walks` (at most [`LANES`]) at `level` (lowered to the best the CPU
/// supports): lane i consumes cells while their chord midpoint is below `lo[i]` (+∞ for a
/// no-return), multiplying `reach[i]` by 1 − m̂ with m̂ read from `means` at the walk's window
/// index, and, with `stop`, stops early by its rule. Every walk's cells must lie inside `means`'
/// window. Returns false, touching nothing, at the scalar level (the scalar kernel walks the
/// beams instead).
pub(crate) fn far_phase(
    level: SimdLevel,
    walks: &mut [FastWalk],
    lo: &[f64],
    reach: &mut [f64],
    means: &[f64],
    stop: Option<FarStop>,
) -> bool {
    assert!(walks.len() <= LANES && lo.len() == walks.len() && reach.len() == walks.len());
    if let Some(st) = &stop {
        assert!(
            st.sup.len() == walks.len()
                && st.far_like.len() == walks.len()
                && st.stopped.len() == walks.len()
        );
    }
    // SAFETY: the CPU supports the level (`runnable`); the caller guarantees every index the
    // walks reach lies in `means`.
    #[cfg(target_arch = "x86_64")]
    match level.runnable() {
        SimdLevel::Avx512 => {
            unsafe { far_phase_avx512(walks, lo, reach, means, stop) };
            return true;
        }
        SimdLevel::Avx2 => {
            unsafe { super::lanes_avx2::far_phase_avx2(walks, lo, reach, means, stop) };
            return true;
        }
        SimdLevel::Scalar => {}
    }
    let _ = (level, walks, lo, reach, means, stop);
    false
}

/// Walks the tails of `io`'s beams (at most [`LANES`]) at `level` (lowered to the best the CPU
/// supports), reading m̂ from `means` at the walk's window index; `floor` is the mixture's
/// w_r/z_max and `neg_lambda` its −λ. Every walk's cells must lie inside `means`' window.
/// Returns false, touching nothing, at the scalar level.
pub(crate) fn tail_phase(
    level: SimdLevel,
    io: TailLanesIo,
    means: &[f64],
    floor: f64,
    neg_lambda: f64,
) -> bool {
    assert!(io.walks.len() <= LANES);
    // SAFETY: the CPU supports the level (`runnable`); the caller guarantees every index the
    // walks reach lies in `means`.
    #[cfg(target_arch = "x86_64")]
    match level.runnable() {
        SimdLevel::Avx512 => {
            unsafe { tail_phase_avx512(io, means, floor, neg_lambda) };
            return true;
        }
        SimdLevel::Avx2 => {
            unsafe { super::lanes_avx2::tail_phase_avx2(io, means, floor, neg_lambda) };
            return true;
        }
        SimdLevel::Scalar => {}
    }
    let _ = (level, io, means, floor, neg_lambda);
    false
}

/// Eight [`FastWalk`]s stepped together, with the operations of `next` in its order.
#[cfg(target_arch = "x86_64")]
pub(crate) struct WalkLanes {
    tx: __m512d,
    ty: __m512d,
    dtx: __m512d,
    dty: __m512d,
    pub(crate) t_in: __m512d,
    t_end: __m512d,
    ix: __m512i,
    iy: __m512i,
    pub(crate) index: __m512i,
    sx: __m512i,
    sy: __m512i,
    isx: __m512i,
    isy: __m512i,
    steps: __m512i,
    /// Lanes holding a walk that has cells left.
    pub(crate) live: __mmask8,
    /// Lanes whose walk reached its end (`done`).
    ended: __mmask8,
}

/// The next crossing of a set of walks: where the current cell is left, whether its chord is
/// reported (≥ MIN_CHORD), and whether the walk leaves it through an x crossing.
#[cfg(target_arch = "x86_64")]
pub(crate) struct Crossing {
    pub(crate) t_out: __m512d,
    pub(crate) reported: __mmask8,
    along_x: __mmask8,
}

#[cfg(target_arch = "x86_64")]
impl WalkLanes {
    #[target_feature(enable = "avx512f")]
    pub(crate) unsafe fn load<'w>(walks: impl Iterator<Item = &'w FastWalk>) -> Self {
        let mut f = [[0.0f64; SET]; 6];
        let mut k = [[0i64; SET]; 8];
        let mut live: __mmask8 = 0;
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
        let ld = |a: &[f64; SET]| _mm512_loadu_pd(a.as_ptr());
        let li = |a: &[i64; SET]| _mm512_loadu_si512(a.as_ptr() as *const _);
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
            live,
            ended: 0,
        }
    }

    /// FastWalk::next's crossing: the nearer one, cut at the ray's end, never before t_in.
    #[target_feature(enable = "avx512f")]
    #[inline]
    pub(crate) unsafe fn crossing(&self) -> Crossing {
        let along_x = _mm512_cmp_pd_mask::<_CMP_LE_OQ>(self.tx, self.ty);
        let near = _mm512_mask_blend_pd(along_x, self.ty, self.tx);
        let near = _mm512_mask_blend_pd(
            _mm512_cmp_pd_mask::<_CMP_LT_OQ>(self.t_end, near),
            near,
            self.t_end,
        );
        let t_out = _mm512_mask_blend_pd(
            _mm512_cmp_pd_mask::<_CMP_LT_OQ>(near, self.t_in),
            near,
            self.t_in,
        );
        let min_chord = _mm512_set1_pd(crate::raycast::MIN_CHORD);
        let reported = _mm512_cmp_pd_mask::<_CMP_GE_OQ>(_mm512_sub_pd(t_out, self.t_in), min_chord);
        Crossing {
            t_out,
            reported,
            along_x,
        }
    }

    /// Moves the lanes `adv` past the cell of `c`; returns the lanes that still have cells.
    #[target_feature(enable = "avx512f")]
    #[inline]
    pub(crate) unsafe fn advance(&mut self, adv: __mmask8, c: &Crossing) -> __mmask8 {
        let done = adv & _mm512_cmp_pd_mask::<_CMP_GE_OQ>(c.t_out, self.t_end);
        let (ax, ay) = (adv & c.along_x, adv & !c.along_x);
        self.tx = _mm512_mask_add_pd(self.tx, ax, self.tx, self.dtx);
        self.ty = _mm512_mask_add_pd(self.ty, ay, self.ty, self.dty);
        self.ix = _mm512_mask_add_epi64(self.ix, ax, self.ix, self.sx);
        self.iy = _mm512_mask_add_epi64(self.iy, ay, self.iy, self.sy);
        self.index = _mm512_mask_add_epi64(self.index, ax, self.index, self.isx);
        self.index = _mm512_mask_add_epi64(self.index, ay, self.index, self.isy);
        self.t_in = _mm512_mask_mov_pd(self.t_in, adv, c.t_out);
        self.steps = _mm512_mask_sub_epi64(self.steps, adv, self.steps, _mm512_set1_epi64(1));
        self.ended |= done;
        adv & !done & _mm512_cmpgt_epi64_mask(self.steps, _mm512_setzero_si512())
    }

    /// Hands each live lane's state back to its walk.
    #[target_feature(enable = "avx512f")]
    pub(crate) unsafe fn store<'w>(&self, walks: impl Iterator<Item = &'w mut FastWalk>) {
        let mut f = [[0.0f64; SET]; 3];
        let mut k = [[0i64; SET]; 4];
        let st = |v: __m512d, a: &mut [f64; SET]| _mm512_storeu_pd(a.as_mut_ptr(), v);
        let sti = |v: __m512i, a: &mut [i64; SET]| _mm512_storeu_si512(a.as_mut_ptr() as *mut _, v);
        st(self.tx, &mut f[0]);
        st(self.ty, &mut f[1]);
        st(self.t_in, &mut f[2]);
        sti(self.ix, &mut k[0]);
        sti(self.iy, &mut k[1]);
        sti(self.index, &mut k[2]);
        sti(self.steps, &mut k[3]);
        for (i, w) in walks.enumerate() {
            if self.live & (1 << i) != 0 {
                w.resume(
                    [f[0][i], f[1][i], f[2][i]],
                    [k[0][i], k[1][i], k[2][i]],
                    k[3][i] as usize,
                    self.ended & (1 << i) != 0,
                );
            }
        }
    }
}

/// One set of far-phase lanes.
#[cfg(target_arch = "x86_64")]
struct FarLanes {
    walk: WalkLanes,
    lo: __m512d,
    reach: __m512d,
    active: __mmask8,
    /// The stop rule's terms ([`FarStop`]; unused without it).
    sup: __m512d,
    far_like: __m512d,
    tol: __m512d,
    /// Far cells taken per lane, and the lanes the rule stopped.
    count: __m512i,
    stopped: __mmask8,
}

#[cfg(target_arch = "x86_64")]
impl FarLanes {
    /// Lanes from `walks`, their far ends and reaches, and the stop rule's terms of `range`
    /// (zero without one).
    #[target_feature(enable = "avx512f")]
    unsafe fn load(
        walks: &[FastWalk],
        lo: &[f64],
        reach: &[f64],
        stop: Option<(&FarStop, std::ops::Range<usize>)>,
    ) -> Self {
        let pad = |v: &[f64]| {
            let mut a = [0.0; SET];
            a[..v.len()].copy_from_slice(v);
            _mm512_loadu_pd(a.as_ptr())
        };
        let walk = WalkLanes::load(walks.iter());
        let active = walk.live;
        let (sup, far_like, tol) = match stop {
            Some((st, r)) => (
                pad(&st.sup[r.clone()]),
                pad(&st.far_like[r]),
                _mm512_set1_pd(st.tol),
            ),
            None => (pad(&[]), pad(&[]), pad(&[])),
        };
        Self {
            walk,
            lo: pad(lo),
            reach: pad(reach),
            active,
            sup,
            far_like,
            tol,
            count: _mm512_setzero_si512(),
            stopped: 0,
        }
    }

    /// One cell of every active lane: a reported cell that is not far stays for the scalar
    /// kernel (its lane stops unmoved); a far one multiplies the reach, and with `STOP`, after
    /// every 16th far cell of a lane, the lane stops if [`FarStop`]'s rule holds.
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn step<const STOP: bool>(&mut self, means: &[f64]) {
        let c = self.walk.crossing();
        let d = _mm512_mul_pd(_mm512_set1_pd(0.5), _mm512_add_pd(self.walk.t_in, c.t_out));
        let far = _mm512_cmp_pd_mask::<_CMP_LT_OQ>(d, self.lo);
        let stop = self.active & c.reported & !far;
        let adv = self.active & !stop;
        let take = adv & c.reported;
        let one = _mm512_set1_pd(1.0);
        let m = _mm512_mask_i64gather_pd::<8>(one, take, self.walk.index, means.as_ptr());
        self.reach = _mm512_mask_mul_pd(self.reach, take, self.reach, _mm512_sub_pd(one, m));
        self.active = self.walk.advance(adv, &c);
        if STOP {
            // The scalar loop's `count % 16 == 0 && R·sup <= tol·(1 − R)·L_far`.
            self.count = _mm512_mask_add_epi64(self.count, take, self.count, _mm512_set1_epi64(1));
            let sixteenth = take
                & _mm512_cmpeq_epi64_mask(
                    _mm512_and_si512(self.count, _mm512_set1_epi64(15)),
                    _mm512_setzero_si512(),
                );
            if sixteenth != 0 {
                let lhs = _mm512_mul_pd(self.reach, self.sup);
                let rhs = _mm512_mul_pd(
                    _mm512_mul_pd(self.tol, _mm512_sub_pd(one, self.reach)),
                    self.far_like,
                );
                let hit = sixteenth & _mm512_cmp_pd_mask::<_CMP_LE_OQ>(lhs, rhs);
                self.stopped |= hit;
                self.active &= !hit;
            }
        }
    }

    #[target_feature(enable = "avx512f")]
    unsafe fn store(
        &self,
        walks: &mut [FastWalk],
        reach: &mut [f64],
        stopped: Option<&mut [bool]>,
    ) {
        let mut r = [0.0; SET];
        _mm512_storeu_pd(r.as_mut_ptr(), self.reach);
        self.walk.store(walks.iter_mut());
        for (i, out) in reach.iter_mut().enumerate() {
            if self.walk.live & (1 << i) != 0 {
                *out = r[i];
            }
        }
        if let Some(stopped) = stopped {
            for (i, s) in stopped.iter_mut().enumerate() {
                *s = self.stopped & (1 << i) != 0;
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn far_phase_avx512(
    walks: &mut [FastWalk],
    lo: &[f64],
    reach: &mut [f64],
    means: &[f64],
    mut stop: Option<FarStop>,
) {
    let n = walks.len();
    let split = n.min(SET);
    let (wa, wb) = walks.split_at_mut(split);
    let (la, lb) = lo.split_at(split);
    let (ra, rb) = reach.split_at_mut(split);
    let mut a = FarLanes::load(wa, la, ra, stop.as_ref().map(|s| (s, 0..split)));
    let mut b = FarLanes::load(wb, lb, rb, stop.as_ref().map(|s| (s, split..n)));
    if stop.is_some() {
        far_loop::<true>(&mut a, &mut b, means);
    } else {
        far_loop::<false>(&mut a, &mut b, means);
    }
    let (sa, sb) = match stop.as_mut() {
        Some(st) => {
            let (x, y) = st.stopped.split_at_mut(split);
            (Some(x), Some(y))
        }
        None => (None, None),
    };
    a.store(wa, ra, sa);
    b.store(wb, rb, sb);
}

/// Steps two sets of far lanes until none is active.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn far_loop<const STOP: bool>(a: &mut FarLanes, b: &mut FarLanes, means: &[f64]) {
    while a.active | b.active != 0 {
        if a.active != 0 {
            a.step::<STOP>(means);
        }
        if b.active != 0 {
            b.step::<STOP>(means);
        }
    }
}

/// One set of tail lanes.
#[cfg(target_arch = "x86_64")]
struct TailLanes {
    walk: WalkLanes,
    reach: __m512d,
    mass: __m512d,
    short: __m512d,
    base: __m512d,
    sup_past: __m512d,
    active: __mmask8,
    stopped: __mmask8,
}

#[cfg(target_arch = "x86_64")]
impl TailLanes {
    /// The lanes `range` of `io`.
    #[target_feature(enable = "avx512f")]
    unsafe fn load(io: &TailLanesIo, range: std::ops::Range<usize>) -> Self {
        let ld = |v: &[f64]| {
            let mut a = [0.0; SET];
            a[..v.len()].copy_from_slice(v);
            _mm512_loadu_pd(a.as_ptr())
        };
        let mut walk = WalkLanes::load(io.walks[range.clone()].iter());
        for (i, &on) in io.enabled[range.clone()].iter().enumerate() {
            if !on {
                walk.live &= !(1 << i);
            }
        }
        let active = walk.live;
        Self {
            walk,
            reach: ld(&io.reach[range.clone()]),
            mass: ld(&io.mass[range.clone()]),
            short: ld(&io.short[range.clone()]),
            base: ld(&io.base[range.clone()]),
            sup_past: ld(&io.sup_past[range]),
            active,
            stopped: 0,
        }
    }

    /// One cell of every active lane (every reported cell is a tail cell): π = R m̂; Σ π;
    /// Σ π/(1 − e^{−λd}); R ← R (1 − m̂); then the stop rule on the new R.
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn step(&mut self, means: &[f64], floor: __m512d, neg_lambda: __m512d) {
        let c = self.walk.crossing();
        let take = self.active & c.reported;
        let d = _mm512_mul_pd(_mm512_set1_pd(0.5), _mm512_add_pd(self.walk.t_in, c.t_out));
        let one = _mm512_set1_pd(1.0);
        let m = _mm512_mask_i64gather_pd::<8>(one, take, self.walk.index, means.as_ptr());
        let pi = _mm512_mul_pd(self.reach, m);
        let e = exp_for_sums_avx512(_mm512_mul_pd(neg_lambda, d));
        let term = _mm512_div_pd(pi, _mm512_sub_pd(one, e));
        self.short = _mm512_mask_add_pd(self.short, take, self.short, term);
        self.mass = _mm512_mask_add_pd(self.mass, take, self.mass, pi);
        self.reach = _mm512_mask_mul_pd(self.reach, take, self.reach, _mm512_sub_pd(one, m));
        let total = _mm512_add_pd(self.base, _mm512_mul_pd(floor, self.mass));
        let stop = take
            & _mm512_cmp_pd_mask::<_CMP_LE_OQ>(
                _mm512_mul_pd(self.reach, self.sup_past),
                _mm512_mul_pd(total, _mm512_set1_pd(TAIL_EPS)),
            );
        self.stopped |= stop;
        self.active = self.walk.advance(self.active, &c) & !stop;
    }

    #[target_feature(enable = "avx512f")]
    unsafe fn store(&self, io: &mut TailLanesIo, range: std::ops::Range<usize>) {
        let mut f = [[0.0f64; SET]; 3];
        _mm512_storeu_pd(f[0].as_mut_ptr(), self.reach);
        _mm512_storeu_pd(f[1].as_mut_ptr(), self.mass);
        _mm512_storeu_pd(f[2].as_mut_ptr(), self.short);
        self.walk.store(io.walks[range.clone()].iter_mut());
        for (i, lane) in range.enumerate() {
            if self.walk.live & (1 << i) != 0 {
                io.reach[lane] = f[0][i];
                io.mass[lane] = f[1][i];
                io.short[lane] = f[2][i];
                io.stopped[lane] = self.stopped & (1 << i) != 0;
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn tail_phase_avx512(mut io: TailLanesIo, means: &[f64], floor: f64, neg_lambda: f64) {
    let (floor, neg_lambda) = (_mm512_set1_pd(floor), _mm512_set1_pd(neg_lambda));
    let n = io.walks.len();
    let (ra, rb) = (0..n.min(SET), n.min(SET)..n);
    let mut a = TailLanes::load(&io, ra.clone());
    let mut b = TailLanes::load(&io, rb.clone());
    while a.active | b.active != 0 {
        if a.active != 0 {
            a.step(means, floor, neg_lambda);
        }
        if b.active != 0 {
            b.step(means, floor, neg_lambda);
        }
    }
    a.store(&mut io, ra);
    b.store(&mut io, rb);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::GridGeometry;

    /// The scalar far phase the lanes must reproduce: consume reported cells while their
    /// midpoint is below `lo`, multiplying the reach; stop before the first that is not.
    fn scalar(walk: &mut FastWalk, lo: f64, means: &[f64]) -> f64 {
        let mut reach = 1.0;
        loop {
            let before = walk.clone();
            let Some(c) = walk.next() else {
                return reach;
            };
            if 0.5 * (c.cell.t_in + c.cell.t_out) >= lo {
                *walk = before;
                return reach;
            }
            reach *= 1.0 - means[c.index as usize];
        }
    }

    #[test]
    fn lanes_equal_the_scalar_far_phase_bit_for_bit_at_every_level() {
        for level in [SimdLevel::Avx2, SimdLevel::Avx512] {
            if level.supported() {
                far_lanes_equal_the_scalar_far_phase_at(level);
            } else {
                crate::simd::report_skip("lanes_equal_the_scalar_far_phase", level);
            }
        }
    }

    fn far_lanes_equal_the_scalar_far_phase_at(level: SimdLevel) {
        let g = GridGeometry::new([0.013, -0.027], 0.2).unwrap();
        let (ix0, iy0, nx) = (-60i64, -60i64, 121i64);
        let mut state = 3u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let means: Vec<f64> = (0..nx * nx).map(|_| 0.05 + 0.9 * next()).collect();
        for round in 0..400 {
            let n = 1 + round % LANES;
            let mut walks = Vec::new();
            let mut lo = Vec::new();
            for i in 0..n {
                let angle = if round % 7 == 0 {
                    (i as f64) * std::f64::consts::FRAC_PI_4
                } else {
                    7.0 * next() - 3.5
                };
                let origin = [2.0 * next() - 1.0, 2.0 * next() - 1.0];
                let length = if i == 3 { 0.0 } else { 8.0 * next() };
                walks.push(FastWalk::new(&g, origin, angle, length, (ix0, iy0, nx)));
                lo.push(if i % 3 == 0 {
                    f64::INFINITY
                } else {
                    9.0 * next()
                });
            }
            let mut want = walks.clone();
            let want_reach: Vec<f64> = want
                .iter_mut()
                .zip(&lo)
                .map(|(w, &l)| scalar(w, l, &means))
                .collect();
            let mut reach = vec![1.0; n];
            assert!(far_phase(level, &mut walks, &lo, &mut reach, &means, None));
            for i in 0..n {
                assert_eq!(
                    reach[i].to_bits(),
                    want_reach[i].to_bits(),
                    "{level} round {round} lane {i}"
                );
                let (a, b) = (walks[i].parts(), want[i].parts());
                assert_eq!(
                    (
                        a.ix,
                        a.iy,
                        a.index,
                        a.steps_left,
                        a.done,
                        a.tx.to_bits(),
                        a.ty.to_bits(),
                        a.t_in.to_bits()
                    ),
                    (
                        b.ix,
                        b.iy,
                        b.index,
                        b.steps_left,
                        b.done,
                        b.tx.to_bits(),
                        b.ty.to_bits(),
                        b.t_in.to_bits()
                    ),
                    "{level} round {round} lane {i}"
                );
                // And the rest of the walk is the same.
                assert_eq!(
                    walks[i].clone().collect::<Vec<_>>(),
                    want[i].clone().collect::<Vec<_>>()
                );
            }
        }
    }
}
