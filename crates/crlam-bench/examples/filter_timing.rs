//! Timing of the particle filters outside `crlam bench`, for profiling and A/B comparisons
//! (`cargo run --release -p crlam-bench --example filter_timing -- clam|clam180|clam_lm|ogm|ogm_gmapping|ogm1079 [scans]`).
use crlam_bench::slam::{
    rbpf_clam_likelihood_mode_scans, rbpf_clam_scans, rbpf_ogm_gmapping_scans, rbpf_ogm_scans,
    rbpf_ogm_scans_table1,
};

fn main() {
    let which = std::env::args().nth(1).unwrap_or_else(|| "clam".into());
    let n: usize = std::env::args()
        .nth(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or(if which == "clam_lm" { 3 } else { 10 });
    let fig = match which.as_str() {
        "clam" => rbpf_clam_scans(n, 100, 1079),
        "clam180" => rbpf_clam_scans(n, 30, 180),
        "clam_lm" => rbpf_clam_likelihood_mode_scans(n, 100, 1079),
        "ogm" => rbpf_ogm_scans(n, 30),
        "ogm_gmapping" => rbpf_ogm_gmapping_scans(n, 30),
        "ogm1079" => rbpf_ogm_scans_table1(n),
        other => panic!("unknown workload {other}"),
    }
    .expect("benchmark failed");
    println!("{} {:.3} scans/s", fig.name, fig.per_second);
}
