use crlam_core::info::bench::crmi_us_per_pose;
use crlam_core::info::crmi::CrmiConfig;
use crlam_core::sensor::{SensorModel, SensorModelKind};
fn main() {
    let which = std::env::args().nth(1).unwrap_or_default();
    let c = CrmiConfig::new(5.0, 0.2);
    if which != "mixture" {
        println!(
            "crmi ijrr {:.1} us/pose",
            crmi_us_per_pose(c, 3000).unwrap()
        );
    }
    if which != "ijrr" {
        let mut m = c;
        m.model = SensorModel::with_defaults(SensorModelKind::Mixture, 5.0, 0.2);
        println!(
            "crmi mixture {:.1} us/pose",
            crmi_us_per_pose(m, 500).unwrap()
        );
    }
}
