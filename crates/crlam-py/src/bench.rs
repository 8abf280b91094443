//! `run_benchmark`: the named micro-benchmarks of crlam-bench, for `crlam bench`.

use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{guard, shape_err, IntoPy};

/// Runs one named micro-benchmark of the core (single thread) and returns its figure.
#[pyfunction]
#[pyo3(signature = (name, size))]
pub fn run_benchmark<'py>(
    py: Python<'py>,
    name: &str,
    size: usize,
) -> PyResult<Bound<'py, PyDict>> {
    guard("run_benchmark", || {
        use crlam_bench::slam as bench;
        if let Some((us, details)) = py
            .allow_threads(|| crlam_bench::info::info_figure(name, size))
            .py_err()?
        {
            let d = PyDict::new(py);
            d.set_item("name", name)?;
            d.set_item("us_per_pose", us)?;
            d.set_item("per_second", 1e6 / us)?;
            d.set_item("operations", size)?;
            d.set_item("unit", "candidate poses")?;
            for (k, v) in details {
                d.set_item(k, v)?;
            }
            return Ok(d);
        }
        let fig = py
            .allow_threads(|| match name {
                "crm_beam_updates_per_s" => Some(bench::crm_beam_updates(
                    size,
                    bench::CrmWorkload::FortyCellHits,
                )),
                "crm_beam_updates_per_s_paper_scan" => {
                    Some(bench::crm_beam_updates(size, bench::CrmWorkload::PaperScan))
                }
                "raycast_cells_per_s" => Some(bench::raycast_cells(size)),
                "rbpf_clam_scans_per_s_1079x100" => Some(bench::rbpf_clam_scans(size, 100, 1079)),
                "rbpf_clam_likelihood_mode_scans_per_s_1079x100" => {
                    Some(bench::rbpf_clam_likelihood_mode_scans(size, 100, 1079))
                }
                "rbpf_clam_scans_per_s_1079x100_full_ray" => Some(bench::rbpf_clam_scans_with(
                    size,
                    100,
                    1079,
                    crlam_core::crm::BatchKernel::FullRay,
                )),
                "rbpf_clam_scans_per_s_180x30" => Some(bench::rbpf_clam_scans(size, 30, 180)),
                "rbpf_clam_scan_match_scans_per_s_180x30" => {
                    Some(bench::rbpf_clam_scan_match_scans(size, 30))
                }
                "rbpf_ogm_scans_per_s_180x30" => Some(bench::rbpf_ogm_scans(size, 30)),
                "rbpf_ogm_gmapping_scans_per_s_180x30" => {
                    Some(bench::rbpf_ogm_gmapping_scans(size, 30))
                }
                "rbpf_ogm_scans_per_s_1079x100" => Some(bench::rbpf_ogm_scans_table1(size)),
                "mcl_scans_per_s_1000p" => Some(crlam_bench::mcl::mcl_scans(size, 1000, 180)),
                "mcl_crm_exact_scans_per_s_1000p" => Some(crlam_bench::mcl::mcl_scans_with(
                    size,
                    1000,
                    180,
                    crlam_bench::mcl::MclModel::CrmExact,
                )),
                "mcl_likelihood_field_scans_per_s_1000p" => Some(crlam_bench::mcl::mcl_scans_with(
                    size,
                    1000,
                    180,
                    crlam_bench::mcl::MclModel::LikelihoodField,
                )),
                "mcl_beam_scans_per_s_1000p" => Some(crlam_bench::mcl::mcl_scans_with(
                    size,
                    1000,
                    180,
                    crlam_bench::mcl::MclModel::Beam,
                )),
                _ => None,
            })
            .ok_or_else(|| shape_err(format!("unknown benchmark {name:?}")))?
            .py_err()?;
        let d = PyDict::new(py);
        d.set_item("name", fig.name)?;
        d.set_item("per_second", fig.per_second)?;
        d.set_item("operations", fig.operations)?;
        d.set_item("seconds", fig.seconds)?;
        d.set_item("unit", fig.unit)?;
        d.set_item("cells_per_ray", fig.cells_per_ray)?;
        d.set_item("cpu_seconds", fig.cpu_seconds)?;
        Ok(d)
    })
}

/// The instruction-set level of the core's vector kernels in this process: `"scalar"`,
/// `"avx2"` or `"avx512"` (the best the CPU supports, lowered by `CRLAM_SIMD`).
#[pyfunction]
pub fn simd_level() -> &'static str {
    crlam_core::simd::choice().level.name()
}

/// How the level was chosen: `level`, `detected` (the best the CPU supports), `requested` (the
/// value of `CRLAM_SIMD`, or None), `warning` (why the request was not followed, or None) and
/// `features` (the CPU's vector features).
#[pyfunction]
pub fn simd_info(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    guard("simd_info", || {
        let c = crlam_core::simd::choice();
        let d = PyDict::new(py);
        d.set_item("level", c.level.name())?;
        d.set_item("detected", c.detected.name())?;
        d.set_item("requested", c.requested.as_deref())?;
        d.set_item("warning", c.warning.as_deref())?;
        d.set_item("features", crlam_core::simd::cpu_features())?;
        Ok(d)
    })
}
