//! The per-reading constants of a scan's weighed beams, computed once per scan and thread.
//!
//! A filter weighs the same scan under every particle's map. What the windowed kernel needs of a
//! reading apart from the walk depends only on the reading and the models, not on the pose: the
//! mixture's short-term numerator λ e^{−λz}, its L_∞, and the bound of every cause's likelihood
//! past the mapping ray (which ends at a length that depends only on the reading). Each costs
//! libm exponentials; computed per particle they were a tenth of the weighing. The table holds
//! them for the last scan seen (the same operations, so the same bits), and is rebuilt when the
//! ranges, the models or the options change.

use crate::crm::beam::{plan_beam, ScanOptions};
use crate::sensor::{MixtureReading, SensorModel};

/// The pose-independent constants of one weighed reading.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ReadingConstants {
    /// λ e^{−λz} (see [`MixtureReading`]).
    pub(crate) short_numerator: f64,
    /// L_∞ of the reading.
    pub(crate) infinity: f64,
    /// [`MixtureReading::bound_beyond`] at the end of the mapping ray (+∞ without one).
    pub(crate) sup_past: f64,
}

/// What a table was built for.
#[derive(Clone, Debug, PartialEq)]
struct TableKey {
    weight: SensorModel,
    mapping: SensorModel,
    resolution: f64,
    weight_opts: ScanOptions,
    map_opts: ScanOptions,
    ranges: Vec<u64>,
}

/// [`ReadingConstants`] of every beam of the last scan seen.
#[derive(Debug, Default)]
pub(crate) struct ReadingTable {
    key: Option<TableKey>,
    consts: Vec<Option<ReadingConstants>>,
}

impl ReadingTable {
    /// Makes the table match a scan weighed with `weight` (options `weight_opts`) and mapped
    /// with `mapping` (`map_opts`) on a grid of `resolution`.
    pub(crate) fn prepare(
        &mut self,
        weight: &SensorModel,
        weight_opts: &ScanOptions,
        mapping: &SensorModel,
        map_opts: &ScanOptions,
        resolution: f64,
        ranges: &[f64],
    ) {
        let same = self.key.as_ref().is_some_and(|k| {
            k.weight == *weight
                && k.mapping == *mapping
                && k.resolution.to_bits() == resolution.to_bits()
                && k.weight_opts == *weight_opts
                && k.map_opts == *map_opts
                && k.ranges.len() == ranges.len()
                && k.ranges.iter().zip(ranges).all(|(&a, b)| a == b.to_bits())
        });
        if same {
            return;
        }
        let at = |b: usize, z: f64| -> Option<ReadingConstants> {
            if !b.is_multiple_of(weight_opts.beam_stride) {
                return None;
            }
            // A plan's reading and length depend on the range alone, not on the pose.
            let w_plan = plan_beam(weight, weight_opts, resolution, [0.0; 2], 0.0, z).ok()?;
            let r = MixtureReading::new(weight, w_plan.z)?;
            let m_plan = if b.is_multiple_of(map_opts.beam_stride) {
                plan_beam(mapping, map_opts, resolution, [0.0; 2], 0.0, z).ok()
            } else {
                None
            };
            Some(ReadingConstants {
                short_numerator: r.short_numerator(),
                infinity: r.infinity(),
                sup_past: m_plan.map_or(f64::INFINITY, |p| r.bound_beyond(p.length)),
            })
        };
        self.consts = ranges.iter().enumerate().map(|(b, &z)| at(b, z)).collect();
        self.key = Some(TableKey {
            weight: *weight,
            mapping: *mapping,
            resolution,
            weight_opts: *weight_opts,
            map_opts: *map_opts,
            ranges: ranges.iter().map(|z| z.to_bits()).collect(),
        });
    }

    /// The constants of beam `b` (`None` if it is not weighed or not a mixture reading).
    #[inline]
    pub(crate) fn get(&self, b: usize) -> Option<ReadingConstants> {
        self.consts.get(b).copied().flatten()
    }
}
