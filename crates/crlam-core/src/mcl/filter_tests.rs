//! Tests of the localizer's resampling floors (clusters, bins, places).

use super::*;
use crate::grid::{CellRect, GridGeometry};
use crate::mcl::kld::KldSettings;
use crate::mcl::likelihood::LikelihoodSettings;
use crate::motion::MotionModel;
use crate::rbpf::UpdateTrigger;
use crate::sensor::SensorModel;
use crate::sensor::SensorModelKind;

fn filter(min_cluster: usize) -> Mcl {
    let g = GridGeometry::new([0.0, 0.0], 0.1).unwrap();
    let rect = CellRect {
        ix0: 0,
        iy0: 0,
        nx: 100,
        ny: 100,
    };
    let field = MeanField::from_means(g, rect, vec![0.05; 10_000], 0.5, 0.2, 10).unwrap();
    let cfg = MclConfig {
        measurement: crate::mcl::Measurement::Crm,
        likelihood: LikelihoodSettings {
            model: SensorModel::with_defaults(SensorModelKind::Mixture, 8.0, 0.1),
            tail_tolerance: 1e-6,
            skip_no_returns: false,
        },
        motion: MotionModel::gmapping(),
        trigger: UpdateTrigger::every_scan(),
        spread_trigger: UpdateTrigger::every_scan(),
        spread_limit: 0.5,
        kld: KldSettings {
            n_min: 50,
            n_max: 2000,
            ..KldSettings::default()
        },
        alpha_slow: 0.0,
        alpha_fast: 0.0,
        tempering: 1.0,
        min_neff: 0.0,
        sigma_max: 0.0,
        anneal: 0.0,
        beam_stride: 1,
        max_beams: 0,
        resample_threshold: 0.5,
        min_cluster,
        keep_ratio: 1e-3,
        min_bin: 0,
        place_xy: 0.0,
        place_theta: std::f64::consts::FRAC_PI_2,
        spread_max: 0,
        spread_climb: false,
        seed: 3,
    };
    let init = MclInit::Pose {
        mean: [5.0, 5.0, 0.0],
        cov: [[0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.01]],
    };
    Mcl::new(cfg, Arc::new(field), init).unwrap()
}

/// 990 particles at A hold 0.998 of the weight, 10 at B 0.0015 and 10 at C 1e-6.
fn three_places(f: &mut Mcl) -> Vec<f64> {
    let mut poses = Vec::new();
    let mut w = Vec::new();
    for i in 0..1010 {
        let (place, weight) = match i {
            0..=989 => ([2.0, 2.0, 0.0], 0.998 / 990.0),
            990..=999 => ([8.0, 8.0, 1.0], 0.0015 / 10.0),
            _ => ([2.0, 8.0, -2.0], 1e-6 / 10.0),
        };
        poses.push([place[0] + 0.001 * (i % 7) as f64, place[1], place[2]]);
        w.push(weight);
    }
    let s: f64 = w.iter().sum();
    let w: Vec<f64> = w.iter().map(|v| v / s).collect();
    f.poses = poses;
    f.log_w = w.iter().map(|v| v.ln()).collect();
    w
}

fn weight_near(f: &Mcl, x: f64, y: f64) -> (f64, usize) {
    let w = f.weights();
    let near: Vec<usize> = (0..f.poses.len())
        .filter(|&j| (f.poses[j][0] - x).hypot(f.poses[j][1] - y) < 0.5)
        .collect();
    (near.iter().map(|&j| w[j]).sum(), near.len())
}

/// Resamples `f` with weights `w` and no injection, floored per AMCL cluster; returns the
/// number of clusters, the particles injected and the clusters kept.
fn resample_by_cluster(f: &mut Mcl, w: &[f64]) -> (usize, usize, usize) {
    let (found, labels) = clusters_with_labels(&f.poses, w, &f.cfg.kld);
    let kld = f.cfg.kld;
    let (injected, kept) = f.resample(w, 0.0, &found, &labels, &kld);
    (found.len(), injected, kept)
}

#[test]
fn competing_clusters_keep_their_particles_and_weights() {
    let mut f = filter(30);
    let w = three_places(&mut f);
    let (n_clusters, injected, kept) = resample_by_cluster(&mut f, &w);
    assert_eq!(n_clusters, 3);
    assert_eq!((injected, kept), (0, 2));
    let (wa, na) = weight_near(&f, 2.0, 2.0);
    let (wb, nb) = weight_near(&f, 8.0, 8.0);
    // B keeps at least min_cluster particles and its weight; C (below keep_ratio) is left to
    // the draw, which almost surely loses it.
    assert!(nb >= 30 && na >= 50, "{na} {nb}");
    let total = wa + wb;
    assert!(
        (wb / total - 0.0015 / (0.998 + 0.0015)).abs() < 1e-9,
        "{wb} {wa}"
    );
}

#[test]
fn without_the_floor_the_draw_decides() {
    let mut f = filter(0);
    let w = three_places(&mut f);
    let (_, _, kept) = resample_by_cluster(&mut f, &w);
    assert_eq!(kept, 0);
    // AMCL's resampling: equal weights, B holds about its share of the draws (0-3 of them).
    let (_, nb) = weight_near(&f, 8.0, 8.0);
    assert!(nb < 5, "{nb}");
    assert!(f.log_w.iter().all(|&l| l == 0.0));
}

#[test]
fn the_bin_floor_keeps_every_plausible_bin_and_its_weight() {
    let mut f = filter(0);
    f.cfg.min_bin = 5;
    let w = three_places(&mut f);
    // A, B and C are one pose bin each; C is below keep_ratio times A.
    let kld = f.cfg.kld;
    let keys: Vec<_> = f.poses.iter().map(|p| kld.bin_of(p)).collect();
    let floored = f.resample_floored(&w, &kld, &keys, 5);
    assert_eq!(floored, 2);
    let (wa, na) = weight_near(&f, 2.0, 2.0);
    let (wb, nb) = weight_near(&f, 8.0, 8.0);
    assert!(nb >= 5 && na >= 5, "{na} {nb}");
    // The bins' weights pass through unchanged (C, if drawn at all, keeps its own).
    assert!((wb / wa - 0.0015 / 0.998).abs() < 1e-12, "{wa} {wb}");
    assert!(f.poses.len() <= f.cfg.kld.n_max);
}

/// One room: 990 particles at A (2, 2) hold 0.998 of the weight, 10 at B (6, 2) 0.0015,
/// and a chain of particles 0.25 m apart between them (1e-9 each) joins their pose bins, so
/// AMCL's clusters make one cluster of the room, as they do while a set is spread.
fn one_room(f: &mut Mcl) -> Vec<f64> {
    let mut poses = Vec::new();
    let mut w = Vec::new();
    for i in 0..1000 {
        let (x, weight) = if i < 990 {
            (2.0, 0.998 / 990.0)
        } else {
            (6.0, 0.0015 / 10.0)
        };
        poses.push([x + 0.001 * (i % 7) as f64, 2.0, 0.0]);
        w.push(weight);
    }
    for k in 1..16 {
        poses.push([2.0 + 0.25 * k as f64, 2.0, 0.0]);
        w.push(1e-9);
    }
    let s: f64 = w.iter().sum();
    let w: Vec<f64> = w.iter().map(|v| v / s).collect();
    f.poses = poses;
    f.log_w = w.iter().map(|v| v.ln()).collect();
    w
}

#[test]
fn places_split_a_room_that_is_one_cluster() {
    let mut f = filter(30);
    f.cfg.place_xy = 2.0;
    assert_eq!(f.place_of(&[2.0, 2.0, 0.0]), (1, 1, 2));
    assert_eq!(f.place_of(&[-0.1, 3.9, -3.0]), (-1, 1, 0));
    // Sectors count from −π: a heading just below π lies in the last of the four.
    assert_eq!(f.place_of(&[0.0, 0.0, 3.1]), (0, 0, 3));
    let w = one_room(&mut f);
    let (found, _) = clusters_with_labels(&f.poses, &w, &f.cfg.kld);
    assert_eq!(found.len(), 1, "the chain joins A and B");
    let kld = f.cfg.kld;
    let keys: Vec<_> = f.poses.iter().map(|p| f.place_of(p)).collect();
    // A's and B's places are floored; the chain's middle place (1e-9 x 5) is not.
    let floored = f.resample_floored(&w, &kld, &keys, 30);
    assert_eq!(floored, 2);
    let (wa, na) = weight_near(&f, 2.0, 2.0);
    let (wb, nb) = weight_near(&f, 6.0, 2.0);
    assert!(nb >= 30 && na >= 30, "{na} {nb}");
    // The places' weights pass through unchanged.
    assert!((wb / wa - 0.0015 / 0.998).abs() < 1e-6, "{wa} {wb}");
    assert!(f.poses.len() <= kld.n_max);
}

#[test]
fn the_cluster_floor_cannot_keep_a_place_inside_one_cluster() {
    let mut f = filter(30);
    let w = one_room(&mut f);
    let (_, _, kept) = resample_by_cluster(&mut f, &w);
    // One cluster: AMCL's resampling, B keeps about its share of the draws (0-3 of them).
    assert_eq!(kept, 0);
    let (_, nb) = weight_near(&f, 6.0, 2.0);
    assert!(nb < 10, "{nb}");
}

#[test]
fn place_settings_are_checked() {
    let mut f = filter(30);
    f.cfg.place_xy = f64::NAN;
    assert!(f.cfg.validate().is_err());
    f.cfg.place_xy = 2.0;
    f.cfg.place_theta = 0.0;
    assert!(f.cfg.validate().is_err());
    f.cfg.place_theta = 1.0;
    assert!(f.cfg.validate().is_ok());
}
