//! The far phase and the tail of up to eight weighed beams at once, eight AVX-512 lanes wide.
//!
//! A weight needs nothing from the cells far before a reading (or from any cell of a no-return)
//! but the reach R = Π (1 − m̂) ([`super::windowed`]): a walk, a mean and a product per cell,
//! which a scalar loop does at the speed of its walk's branch. Here each lane walks one beam
//! (a [`FastWalk`], the same operations in the same order as its `next`), reads its cells' means
//! by a gather from the scan's mean table and multiplies its reach, until the lane reaches a cell
//! that is not far (left unconsumed, for the scalar kernel to take up), or its ray ends. Every
//! lane ends in the state the scalar loop would have reached, bit for bit, so the kernel goes on
//! from there as if it had walked alone.
//!
//! The tail of a weighed beam, past the mapping ray and the weight's hit reach, is again a walk
//! with a little arithmetic per cell: each cause's probability π = R·m̂ goes into Σ π and, with
//! e^{−λd}, into Σ π/(1 − e^{−λd}), until the stop rule of [`super::windowed`] holds or the ray
//! ends. [`tail_phase`] walks the tails of the beams the kernel paused there
//! ([`TailLane`]), with the scalar loop's operations in its order (the exponential is
//! [`exp_for_sums_avx512`], lane for lane the scalar one), so every lane ends as the scalar
//! loop would, bit for bit.

use crate::crm::windowed::{TailLane, TAIL_EPS};
#[cfg(target_arch = "x86_64")]
use crate::info::fastmath::exp_for_sums_avx512;
use crate::raycast::FastWalk;

/// Lanes of the wide kernel.
pub(crate) const LANES: usize = 8;

/// Runs the far phase of `walks` (at most [`LANES`]): lane i consumes cells while their chord
/// midpoint is below `lo[i]` (+∞ for a no-return), multiplying `reach[i]` by 1 − m̂ with m̂ read
/// from `means` at the walk's window index. Every walk's cells must lie inside `means`' window.
/// Returns false, touching nothing, where the CPU lacks AVX-512F.
pub(crate) fn far_phase(
    walks: &mut [FastWalk],
    lo: &[f64],
    reach: &mut [f64],
    means: &[f64],
) -> bool {
    assert!(walks.len() <= LANES && lo.len() == walks.len() && reach.len() == walks.len());
    #[cfg(target_arch = "x86_64")]
    {
        if crate::info::fastlog::has_avx512() {
            // SAFETY: the CPU has AVX-512F; the caller guarantees every index the walks reach
            // lies in `means`.
            unsafe { far_phase_avx512(walks, lo, reach, means) };
            return true;
        }
    }
    let _ = (walks, lo, reach, means);
    false
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn far_phase_avx512(walks: &mut [FastWalk], lo: &[f64], reach: &mut [f64], means: &[f64]) {
    use std::arch::x86_64::*;
    let n = walks.len();
    let mut f = [[0.0f64; LANES]; 8];
    let mut k = [[0i64; LANES]; 8];
    let mut live: u8 = 0;
    for (i, w) in walks.iter().enumerate() {
        let s = w.parts();
        f[0][i] = s.tx;
        f[1][i] = s.ty;
        f[2][i] = s.dtx;
        f[3][i] = s.dty;
        f[4][i] = s.t_in;
        f[5][i] = s.t_end;
        f[6][i] = lo[i];
        f[7][i] = reach[i];
        k[0][i] = s.ix;
        k[1][i] = s.iy;
        k[2][i] = s.index;
        k[3][i] = s.step_x;
        k[4][i] = s.step_y;
        k[5][i] = s.index_step_x;
        k[6][i] = s.index_step_y;
        k[7][i] = s.steps_left as i64;
        if !s.done && s.steps_left > 0 {
            live |= 1 << i;
        }
    }
    let ld = |a: &[f64; LANES]| _mm512_loadu_pd(a.as_ptr());
    let li = |a: &[i64; LANES]| _mm512_loadu_si512(a.as_ptr() as *const _);
    let (mut tx, mut ty, dtx, dty) = (ld(&f[0]), ld(&f[1]), ld(&f[2]), ld(&f[3]));
    let (mut t_in, t_end, lo_v, mut r) = (ld(&f[4]), ld(&f[5]), ld(&f[6]), ld(&f[7]));
    let (mut ix, mut iy, mut index) = (li(&k[0]), li(&k[1]), li(&k[2]));
    let (sx, sy, isx, isy, mut steps) = (li(&k[3]), li(&k[4]), li(&k[5]), li(&k[6]), li(&k[7]));
    let (half, one, min_chord) = (
        _mm512_set1_pd(0.5),
        _mm512_set1_pd(1.0),
        _mm512_set1_pd(crate::raycast::MIN_CHORD),
    );
    let (zero_i, one_i) = (_mm512_setzero_si512(), _mm512_set1_epi64(1));
    let mut active: __mmask8 = live;
    let mut ended: __mmask8 = 0;
    while active != 0 {
        // FastWalk::next: the nearer crossing, cut at the ray's end, never before t_in.
        let along_x = _mm512_cmp_pd_mask::<_CMP_LE_OQ>(tx, ty);
        let near = _mm512_mask_blend_pd(along_x, ty, tx);
        let near = _mm512_mask_blend_pd(_mm512_cmp_pd_mask::<_CMP_LT_OQ>(t_end, near), near, t_end);
        let t_out = _mm512_mask_blend_pd(_mm512_cmp_pd_mask::<_CMP_LT_OQ>(near, t_in), near, t_in);
        let chord_ok = _mm512_cmp_pd_mask::<_CMP_GE_OQ>(_mm512_sub_pd(t_out, t_in), min_chord);
        let d = _mm512_mul_pd(half, _mm512_add_pd(t_in, t_out));
        let far = _mm512_cmp_pd_mask::<_CMP_LT_OQ>(d, lo_v);
        // A reported cell that is not far stays for the scalar kernel: its lane stops unmoved.
        let stop = active & chord_ok & !far;
        let adv = active & !stop;
        let take = adv & chord_ok;
        let m = _mm512_mask_i64gather_pd::<8>(one, take, index, means.as_ptr());
        r = _mm512_mask_mul_pd(r, take, r, _mm512_sub_pd(one, m));
        let done = adv & _mm512_cmp_pd_mask::<_CMP_GE_OQ>(t_out, t_end);
        let (ax, ay) = (adv & along_x, adv & !along_x);
        tx = _mm512_mask_add_pd(tx, ax, tx, dtx);
        ty = _mm512_mask_add_pd(ty, ay, ty, dty);
        ix = _mm512_mask_add_epi64(ix, ax, ix, sx);
        iy = _mm512_mask_add_epi64(iy, ay, iy, sy);
        index = _mm512_mask_add_epi64(index, ax, index, isx);
        index = _mm512_mask_add_epi64(index, ay, index, isy);
        t_in = _mm512_mask_mov_pd(t_in, adv, t_out);
        steps = _mm512_mask_sub_epi64(steps, adv, steps, one_i);
        ended |= done;
        active = adv & !done & _mm512_cmpgt_epi64_mask(steps, zero_i);
    }
    let st = |v: __m512d, a: &mut [f64; LANES]| _mm512_storeu_pd(a.as_mut_ptr(), v);
    let sti = |v: __m512i, a: &mut [i64; LANES]| _mm512_storeu_si512(a.as_mut_ptr() as *mut _, v);
    st(tx, &mut f[0]);
    st(ty, &mut f[1]);
    st(t_in, &mut f[4]);
    st(r, &mut f[7]);
    sti(ix, &mut k[0]);
    sti(iy, &mut k[1]);
    sti(index, &mut k[2]);
    sti(steps, &mut k[7]);
    for (i, w) in walks.iter_mut().enumerate().take(n) {
        if live & (1 << i) == 0 {
            continue;
        }
        w.resume(
            [f[0][i], f[1][i], f[4][i]],
            [k[0][i], k[1][i], k[2][i]],
            k[7][i] as usize,
            ended & (1 << i) != 0,
        );
        reach[i] = f[7][i];
    }
}

/// Walks the tails of `lanes` (at most [`LANES`], each paused by the windowed kernel at its
/// first tail cell), reading m̂ from `means` at the walk's window index; `neg_lambda` is −λ of
/// the weight model. Every walk's cells must lie inside `means`' window. Returns false, touching
/// nothing, where the CPU lacks AVX-512F.
pub(crate) fn tail_phase(lanes: &mut [TailLane], means: &[f64], neg_lambda: f64) -> bool {
    assert!(lanes.len() <= LANES);
    #[cfg(target_arch = "x86_64")]
    {
        if crate::info::fastlog::has_avx512() {
            // SAFETY: the CPU has AVX-512F; the caller guarantees every index the walks reach
            // lies in `means`.
            unsafe { tail_phase_avx512(lanes, means, neg_lambda) };
            return true;
        }
    }
    let _ = (lanes, means, neg_lambda);
    false
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn tail_phase_avx512(lanes: &mut [TailLane], means: &[f64], neg_lambda: f64) {
    use std::arch::x86_64::*;
    let mut f = [[0.0f64; LANES]; 12];
    let mut k = [[0i64; LANES]; 8];
    let mut live: u8 = 0;
    for (i, l) in lanes.iter().enumerate() {
        let s = l.walk.parts();
        f[0][i] = s.tx;
        f[1][i] = s.ty;
        f[2][i] = s.dtx;
        f[3][i] = s.dty;
        f[4][i] = s.t_in;
        f[5][i] = s.t_end;
        f[6][i] = l.reach;
        f[7][i] = l.mass;
        f[8][i] = l.short;
        f[9][i] = l.base;
        f[10][i] = l.floor;
        f[11][i] = l.sup_past;
        k[0][i] = s.ix;
        k[1][i] = s.iy;
        k[2][i] = s.index;
        k[3][i] = s.step_x;
        k[4][i] = s.step_y;
        k[5][i] = s.index_step_x;
        k[6][i] = s.index_step_y;
        k[7][i] = s.steps_left as i64;
        if !s.done && s.steps_left > 0 {
            live |= 1 << i;
        }
    }
    let ld = |a: &[f64; LANES]| _mm512_loadu_pd(a.as_ptr());
    let li = |a: &[i64; LANES]| _mm512_loadu_si512(a.as_ptr() as *const _);
    let (mut tx, mut ty, dtx, dty) = (ld(&f[0]), ld(&f[1]), ld(&f[2]), ld(&f[3]));
    let (mut t_in, t_end, mut reach) = (ld(&f[4]), ld(&f[5]), ld(&f[6]));
    let (mut mass, mut short, base) = (ld(&f[7]), ld(&f[8]), ld(&f[9]));
    let (floor, sup_past) = (ld(&f[10]), ld(&f[11]));
    let (mut ix, mut iy, mut index) = (li(&k[0]), li(&k[1]), li(&k[2]));
    let (sx, sy, isx, isy, mut steps) = (li(&k[3]), li(&k[4]), li(&k[5]), li(&k[6]), li(&k[7]));
    let (half, one, min_chord) = (
        _mm512_set1_pd(0.5),
        _mm512_set1_pd(1.0),
        _mm512_set1_pd(crate::raycast::MIN_CHORD),
    );
    let (neg_l, eps) = (_mm512_set1_pd(neg_lambda), _mm512_set1_pd(TAIL_EPS));
    let (zero_i, one_i) = (_mm512_setzero_si512(), _mm512_set1_epi64(1));
    let mut active: __mmask8 = live;
    let mut ended: __mmask8 = 0;
    let mut stopped: __mmask8 = 0;
    while active != 0 {
        // FastWalk::next, as in the far phase; every reported cell is a tail cell.
        let along_x = _mm512_cmp_pd_mask::<_CMP_LE_OQ>(tx, ty);
        let near = _mm512_mask_blend_pd(along_x, ty, tx);
        let near = _mm512_mask_blend_pd(_mm512_cmp_pd_mask::<_CMP_LT_OQ>(t_end, near), near, t_end);
        let t_out = _mm512_mask_blend_pd(_mm512_cmp_pd_mask::<_CMP_LT_OQ>(near, t_in), near, t_in);
        let take = active & _mm512_cmp_pd_mask::<_CMP_GE_OQ>(_mm512_sub_pd(t_out, t_in), min_chord);
        let d = _mm512_mul_pd(half, _mm512_add_pd(t_in, t_out));
        let m = _mm512_mask_i64gather_pd::<8>(one, take, index, means.as_ptr());
        // π = R m̂; Σ π; Σ π/(1 − e^{−λd}); R ← R (1 − m̂); the stop rule on the new R.
        let pi = _mm512_mul_pd(reach, m);
        let e = exp_for_sums_avx512(_mm512_mul_pd(neg_l, d));
        let term = _mm512_div_pd(pi, _mm512_sub_pd(one, e));
        short = _mm512_mask_add_pd(short, take, short, term);
        mass = _mm512_mask_add_pd(mass, take, mass, pi);
        reach = _mm512_mask_mul_pd(reach, take, reach, _mm512_sub_pd(one, m));
        let total = _mm512_add_pd(base, _mm512_mul_pd(floor, mass));
        let stop = take
            & _mm512_cmp_pd_mask::<_CMP_LE_OQ>(
                _mm512_mul_pd(reach, sup_past),
                _mm512_mul_pd(total, eps),
            );
        stopped |= stop;
        let done = active & _mm512_cmp_pd_mask::<_CMP_GE_OQ>(t_out, t_end);
        let (ax, ay) = (active & along_x, active & !along_x);
        tx = _mm512_mask_add_pd(tx, ax, tx, dtx);
        ty = _mm512_mask_add_pd(ty, ay, ty, dty);
        ix = _mm512_mask_add_epi64(ix, ax, ix, sx);
        iy = _mm512_mask_add_epi64(iy, ay, iy, sy);
        index = _mm512_mask_add_epi64(index, ax, index, isx);
        index = _mm512_mask_add_epi64(index, ay, index, isy);
        t_in = _mm512_mask_mov_pd(t_in, active, t_out);
        steps = _mm512_mask_sub_epi64(steps, active, steps, one_i);
        ended |= done;
        active = active & !done & !stop & _mm512_cmpgt_epi64_mask(steps, zero_i);
    }
    let st = |v: __m512d, a: &mut [f64; LANES]| _mm512_storeu_pd(a.as_mut_ptr(), v);
    let sti = |v: __m512i, a: &mut [i64; LANES]| _mm512_storeu_si512(a.as_mut_ptr() as *mut _, v);
    st(tx, &mut f[0]);
    st(ty, &mut f[1]);
    st(t_in, &mut f[4]);
    st(reach, &mut f[6]);
    st(mass, &mut f[7]);
    st(short, &mut f[8]);
    sti(ix, &mut k[0]);
    sti(iy, &mut k[1]);
    sti(index, &mut k[2]);
    sti(steps, &mut k[7]);
    for (i, l) in lanes.iter_mut().enumerate() {
        if live & (1 << i) == 0 {
            continue;
        }
        l.walk.resume(
            [f[0][i], f[1][i], f[4][i]],
            [k[0][i], k[1][i], k[2][i]],
            k[7][i] as usize,
            ended & (1 << i) != 0,
        );
        l.reach = f[6][i];
        l.mass = f[7][i];
        l.short = f[8][i];
        l.stopped = stopped & (1 << i) != 0;
    }
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
    fn lanes_equal_the_scalar_far_phase_bit_for_bit() {
        if !crate::info::fastlog::has_avx512() {
            eprintln!("skipped: this CPU has no AVX-512F (the scalar kernel runs instead)");
            return;
        }
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
            assert!(far_phase(&mut walks, &lo, &mut reach, &means));
            for i in 0..n {
                assert_eq!(
                    reach[i].to_bits(),
                    want_reach[i].to_bits(),
                    "round {round} lane {i}"
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
                    "round {round} lane {i}"
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
