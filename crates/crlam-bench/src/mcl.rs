//! The Monte Carlo localization workload of `crlam bench` (`mcl_scans_per_s_1000p`): a fixed
//! particle count on a CRM mapped from the filter workload's room.

use crlam_core::crm::{CrmConfig, CrmMap, CrmScratch};
use crlam_core::error::Result;
use crlam_core::grid::GridGeometry;
use crlam_core::sensor::{SensorModel, SensorModelKind};

use crate::slam::{filter_figure, filter_workload, time_filter_cpu, BenchFigure};

/// Monte Carlo localization scans per second on one thread with a fixed particle count: the
/// filter workload's room mapped with known poses into a CRM at 0.05 m, then localized from a
/// Gaussian around the start, every scan processed (motion draw, CRM likelihood of every beam,
/// clusters, KLD resampling with `n_min = n_max = n_particles`), recovery on.
pub fn mcl_scans(n_scans: usize, n_particles: usize, n_beams: usize) -> Result<BenchFigure> {
    mcl_scans_with(n_scans, n_particles, n_beams, MclModel::Crm)
}

/// The measurement model of an MCL figure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MclModel {
    /// The CRM likelihood of 60 of the scan's beams spread evenly (AMCL's `max_beams`), each
    /// beam's log η low by less than 1e-6 (crlam localize's default, `--model crm`).
    Crm,
    /// The CRM likelihood of every beam to rounding (tail tolerance 2^-60, `--model crm-exact`).
    CrmExact,
    /// AMCL's likelihood field with its defaults, 60 beams.
    LikelihoodField,
    /// AMCL's beam model with its defaults, 60 beams.
    Beam,
}

impl MclModel {
    /// The figure's name for 1000 particles and 180 beams.
    pub fn figure_name(&self) -> &'static str {
        match self {
            MclModel::Crm => "mcl_scans_per_s_1000p",
            MclModel::CrmExact => "mcl_crm_exact_scans_per_s_1000p",
            MclModel::LikelihoodField => "mcl_likelihood_field_scans_per_s_1000p",
            MclModel::Beam => "mcl_beam_scans_per_s_1000p",
        }
    }
}

/// [`mcl_scans`] with the measurement model `model`.
pub fn mcl_scans_with(
    n_scans: usize,
    n_particles: usize,
    n_beams: usize,
    model: MclModel,
) -> Result<BenchFigure> {
    use crlam_core::crm::ScanOptions;
    use crlam_core::mcl::{KldSettings, LikelihoodSettings, Mcl, MclConfig, MclInit, MeanField};
    use crlam_core::motion::MotionModel;
    use crlam_core::rbpf::UpdateTrigger;
    let fov = 180.0;
    let z_max = 20.0;
    let w = filter_workload(n_scans + 1, n_beams, fov, z_max)?;
    let g = GridGeometry::new([0.0, 0.0], 0.05)?;
    let mut map = CrmMap::new(&CrmConfig::new(g))?;
    let ijrr = SensorModel::with_defaults(SensorModelKind::Ijrr, z_max, 0.05);
    let mut sc = CrmScratch::default();
    for (o, r) in w.odom.iter().zip(&w.ranges) {
        map.update_scan(*o, &w.angles, r, &ijrr, &ScanOptions::default(), &mut sc)?;
    }
    let rect = map.grid().written_bounds().unwrap_or(map.grid().bounds());
    let field = std::sync::Arc::new(MeanField::from_crm(
        &map,
        rect,
        0.25,
        (z_max / 0.05) as usize,
    )?);
    let measurement = match model {
        MclModel::Crm | MclModel::CrmExact => crlam_core::mcl::Measurement::Crm,
        MclModel::LikelihoodField => {
            crlam_core::mcl::Measurement::LikelihoodField(Default::default())
        }
        MclModel::Beam => crlam_core::mcl::Measurement::Beam(Default::default()),
    };
    let (max_beams, tail_tolerance) = match model {
        MclModel::CrmExact => (0, 1.0 / (1u64 << 60) as f64),
        _ => (60, 1e-6),
    };
    let cfg = MclConfig {
        measurement,
        likelihood: LikelihoodSettings {
            model: SensorModel::with_defaults(SensorModelKind::Mixture, z_max, 0.05),
            tail_tolerance,
            skip_no_returns: false,
        },
        motion: MotionModel::gmapping(),
        trigger: UpdateTrigger::every_scan(),
        spread_trigger: UpdateTrigger::every_scan(),
        spread_limit: 0.5,
        kld: crlam_core::mcl::KldSettings {
            n_min: n_particles,
            n_max: n_particles,
            ..KldSettings::default()
        },
        alpha_slow: 0.001,
        alpha_fast: 0.1,
        tempering: 1.0,
        min_neff: 0.0,
        sigma_max: 0.0,
        anneal: 0.0,
        beam_stride: 1,
        max_beams,
        resample_threshold: 1.0,
        min_cluster: 0,
        min_bin: 0,
        place_xy: 0.0,
        place_theta: std::f64::consts::FRAC_PI_2,
        spread_max: 0,
        spread_climb: false,
        keep_ratio: 1e-3,
        seed: 0,
    };
    let cov = [[0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.003]];
    let mut f = Mcl::new(
        cfg,
        field,
        MclInit::Pose {
            mean: w.odom[0],
            cov,
        },
    )?;
    let (secs, cpu) = time_filter_cpu(&w, n_scans, |s| {
        f.process(s).map(|m| crlam_core::rbpf::FilterStep {
            processed: m.processed,
            estimate: m.estimate,
            neff: m.neff,
            resampled: m.resampled,
        })
    })?;
    let name = match (n_particles, n_beams) {
        (1000, 180) => model.figure_name(),
        _ => "mcl_scans_per_s",
    };
    let unit: &'static str = match model {
        MclModel::Crm => "processed scan (1000 particles: motion draw, CRM likelihood of 60 of 180 beams over 180 deg (AMCL's max_beams), 20 m, 0.05 m map; clusters; KLD resampling; one thread)",
        MclModel::CrmExact => "processed scan (1000 particles: motion draw, CRM likelihood of all 180 beams to rounding, 20 m, 0.05 m map; clusters; KLD resampling; one thread)",
        MclModel::LikelihoodField => "processed scan (1000 particles: motion draw, AMCL's likelihood field on 60 of 180 beams, 20 m, 0.05 m map; clusters; KLD resampling; one thread)",
        MclModel::Beam => "processed scan (1000 particles: motion draw, AMCL's beam model on 60 of 180 beams, 20 m, 0.05 m map; clusters; KLD resampling; one thread)",
    };
    Ok(BenchFigure {
        cpu_seconds: cpu,
        ..filter_figure(name, unit, n_scans, secs)
    })
}

#[cfg(test)]
mod tests {
    #[test]
    #[ignore = "timing, run by hand"]
    fn mcl_timing() {
        let n = std::env::var("MCL_SCANS")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(20);
        for m in [
            super::MclModel::Crm,
            super::MclModel::CrmExact,
            super::MclModel::LikelihoodField,
            super::MclModel::Beam,
        ] {
            let f = super::mcl_scans_with(n, 1000, 180, m).unwrap();
            eprintln!("{f:?}");
        }
    }
}
