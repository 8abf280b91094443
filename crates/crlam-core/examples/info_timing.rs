//! Timing of the information functions outside `crlam bench`, for profiling
//! (`cargo run --release -p crlam-core --example info_timing -- crmi|mixture|ucrmi`).
use crlam_core::info::bench::{crmi_us_per_pose, ucrmi_us_per_pose};
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
        "ucrmi" => println!("ucrmi {:.1} us/pose", ucrmi_us_per_pose(500).unwrap()),
        other => eprintln!("unknown workload {other:?}: crmi, mixture or ucrmi"),
    }
}
