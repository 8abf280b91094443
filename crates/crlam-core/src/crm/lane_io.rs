//! What the lane kernels take and return: the group size and the per-phase inputs and outputs
//! of the far phase and tail ([`super::far_simd`]) and of the window ([`super::window_simd`]),
//! the same at every instruction-set level ([`super::lanes_avx2`] runs them with AVX2). The
//! driver ([`super::lanes`]) and the windowed kernel ([`super::windowed`]) fill them in.

use crate::raycast::FastWalk;
use crate::sensor::SensorModel;

/// Beams a call takes: two sets of eight AVX-512 lanes (four sets of four AVX2 lanes).
pub(crate) const LANES: usize = 16;

/// Weighed beams at the first cell of their tails (past the mapping ray and the weight's hit
/// reach), one per lane: the walk and the reach there, Σ π and Σ π/(1 − e^{−λd}) so far (0 at
/// the start), the part `base` of the stop rule's lower bound of η that the tail does not change
/// ((1 − R_far)·far_like + η_w) and the bound `sup_past` of every cause's likelihood past the
/// mapping ray. On return: where each walk ended, the sums, and whether the stop rule ended it.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
pub(crate) struct TailLanesIo<'a> {
    /// Lanes to walk (the others are left untouched).
    pub(crate) enabled: &'a [bool],
    pub(crate) walks: &'a mut [FastWalk],
    pub(crate) reach: &'a mut [f64],
    pub(crate) mass: &'a mut [f64],
    pub(crate) short: &'a mut [f64],
    pub(crate) base: &'a [f64],
    pub(crate) sup_past: &'a [f64],
    pub(crate) stopped: &'a mut [bool],
}

/// Weighed beams entering their windows, one per lane: the walk and reach where the far phase
/// ended, the reading, the end of the mapping ray (−∞ without one: the lane then stops at once)
/// and the reading's λ e^{−λz}. On return `walks` and `reach` are where the lanes left the
/// beams, `reach_far` the reach at the window's first cell (`NaN` if the window was not
/// entered), `eta` the window's Σ π·L so far, and each lane either stopped before its first tail
/// cell (`at_tail`: past the mapping ray and the hit reach), or before a cell only the scalar
/// kernel handles (`bailed`), or reached the end of its ray (neither).
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
pub(crate) struct WindowLanesIo<'a> {
    pub(crate) walks: &'a mut [FastWalk],
    pub(crate) reach: &'a mut [f64],
    pub(crate) z: &'a [f64],
    pub(crate) map_length: &'a [f64],
    pub(crate) short_numerator: &'a [f64],
    pub(crate) reach_far: &'a mut [f64],
    pub(crate) eta: &'a mut [f64],
    pub(crate) at_tail: &'a mut [bool],
    pub(crate) bailed: &'a mut [bool],
}

/// The weight model's constants the window needs; `hit_reach` is the kernel's (beyond it the
/// hit term is left out).
#[derive(Clone, Copy, Debug)]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
pub(crate) struct WindowModel {
    pub(crate) model: SensorModel,
    pub(crate) hit_reach: f64,
}

/// The localizer's stop rule of a far phase (`mcl::likelihood`; shared by `far_simd` and `lanes_avx2`), per lane: after every 16th
/// far cell a lane has taken, it stops when R·sup ≤ tol·(1 − R)·L_far (every cause past there
/// has a likelihood below `sup[i]`, so the rest of the ray changes η by less than `tol` of
/// what the far causes already give), and `stopped[i]` says so. The operations are the scalar
/// loop's, in its order, so a lane stops where it would.
pub(crate) struct FarStop<'a> {
    pub sup: &'a [f64],
    pub far_like: &'a [f64],
    pub tol: f64,
    pub stopped: &'a mut [bool],
}
