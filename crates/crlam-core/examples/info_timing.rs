//! Timing of the information functions outside `crlam bench`, for profiling
//! (`cargo run --release -p crlam-core --example info_timing -- crmi|mixture|ucrmi`).
use crlam_core::info::bench::{crmi_us_per_pose, info_figure};
use crlam_core::info::crmi::CrmiConfig;
use crlam_core::sensor::{SensorModel, SensorModelKind};

fn main() {
    let which = std::env::args().nth(1).unwrap_or_else(|| "crmi".into());
    let c = CrmiConfig::new(5.0, 0.2);
    match which.as_str() {
        "crmi" => println!(
            "crmi ijrr {:.1} us/pose",
            crmi_us_per_pose(c, 3000).unwrap()
        ),
        "mixture" => {
            let mut m = c;
            m.model = SensorModel::with_defaults(SensorModelKind::Mixture, 5.0, 0.2);
            println!(
                "crmi mixture {:.1} us/pose",
                crmi_us_per_pose(m, 500).unwrap()
            );
        }
        "ucrmi" => {
            // Best of 7 short runs: the VM's timing noise is one-sided.
            let best = (0..7)
                .map(|_| info_figure("ucrmi_us_per_pose", 150).unwrap().unwrap().0)
                .fold(f64::INFINITY, f64::min);
            println!("ucrmi {best:.1} us/pose (one thread, best of 7)")
        }
        other => eprintln!("unknown workload {other:?}: crmi, mixture or ucrmi"),
    }
}
