//! UCRMI at a candidate node (crm-spec 6.3–6.4, invariant 28) on a shared CRM.

use crlam_core::grid::GridGeometry;
use crlam_core::info::crmi::{Crmi, CrmiScratch};
use crlam_core::info::entropy::root_entropy;
use crlam_core::info::lattice::OccupancyLattice;
use crlam_core::info::prior::crm_from_lattice;
use crlam_core::info::ucrmi::{Ucrmi, UcrmiConfig};
use crlam_core::info::{evaluate_batch, Candidate, InformationFunction};

/// A 20 m × 20 m lattice (0.2 m) with a walled 6 m room in one corner and open space elsewhere.
fn world() -> crlam_core::crm::CrmMap {
    let g = GridGeometry::new([0.0, 0.0], 0.2).unwrap();
    let n = 100;
    let mut p = vec![0.3; n * n];
    for b in 0..n {
        for a in 0..n {
            let room = (a == 5 || a == 35) && (5..=35).contains(&b)
                || (b == 5 || b == 35) && (5..=35).contains(&a);
            if room {
                p[a + b * n] = 0.85;
            }
        }
    }
    crm_from_lattice(&OccupancyLattice::new(g, n, n, p).unwrap(), 10).unwrap()
}

fn ucrmi(alpha: f64) -> Ucrmi {
    let mut c = UcrmiConfig::new(5.0, 0.2);
    c.alpha = alpha;
    Ucrmi::new(c).unwrap()
}

#[test]
fn root_belief_is_the_gaussian_prior() {
    let u = ucrmi(0.5);
    let b = u.root_belief([4.0, 4.0, 0.0], 1).unwrap();
    assert_eq!(b.particles.len(), 100);
    assert!((b.entropy_nats - root_entropy([0.16, 0.01, 1e-6]).unwrap()).abs() < 1e-12);
    let w = b.weights();
    assert!(w.iter().all(|x| (x - 0.01).abs() < 1e-12));
}

#[test]
fn alpha_selects_the_map_or_the_pose_term() {
    // Invariant 28: I_c = I_m at α = 1 and I_p at α = 0, in bits.
    let m = world();
    let cand = Candidate {
        pose: [4.0, 3.0, 0.0],
        parent: [3.0, 3.0],
    };
    let crmi_only = {
        let c = UcrmiConfig::new(5.0, 0.2).crmi;
        Crmi::new(c)
            .unwrap()
            .gain_with(&m, cand.pose, &mut CrmiScratch::default())
            .unwrap()
    };
    let u1 = ucrmi(1.0);
    let root = u1.root_belief([3.0, 3.0, 0.0], 4).unwrap();
    let e1 = u1.evaluate(&m, &root, &cand, 17).unwrap();
    assert!((e1.gain - crmi_only).abs() < 1e-12);
    let e0 = ucrmi(0.0).evaluate(&m, &root, &cand, 17).unwrap();
    assert!((e0.gain - e0.belief.pose_gain_bits).abs() < 1e-12);
    let eh = ucrmi(0.5).evaluate(&m, &root, &cand, 17).unwrap();
    let want = 0.5 * eh.belief.map_gain_bits + 0.5 * eh.belief.pose_gain_bits;
    assert!((eh.gain - want).abs() < 1e-12);
    assert_eq!(eh.belief.map_gain_bits, crmi_only);
}

#[test]
fn walls_in_range_localize_better_than_open_space() {
    // Near the room's walls the virtual scan pins the position; in the open every beam is a
    // no-return and the edge noise only adds entropy (I_p < 0).
    let m = world();
    let u = ucrmi(0.5);
    let near = Candidate {
        pose: [3.0, 3.0, 0.0],
        parent: [2.0, 3.0],
    };
    let open = Candidate {
        pose: [16.0, 16.0, 0.0],
        parent: [15.0, 16.0],
    };
    let rn = u.root_belief([2.0, 3.0, 0.0], 2).unwrap();
    let ro = u.root_belief([15.0, 16.0, 0.0], 2).unwrap();
    let en = u.evaluate(&m, &rn, &near, 5).unwrap();
    let eo = u.evaluate(&m, &ro, &open, 5).unwrap();
    assert!(
        eo.belief.pose_gain_bits < 0.0,
        "{}",
        eo.belief.pose_gain_bits
    );
    assert!(
        en.belief.pose_gain_bits > eo.belief.pose_gain_bits + 1.0,
        "near {} open {}",
        en.belief.pose_gain_bits,
        eo.belief.pose_gain_bits
    );
}

#[test]
fn same_seed_same_result_and_batch_equals_serial() {
    let m = world();
    let u = ucrmi(0.5);
    let root = u.root_belief([3.0, 3.0, 0.0], 3).unwrap();
    let cands: Vec<Candidate> = (0..8)
        .map(|i| Candidate {
            pose: [3.0 + 0.5 * i as f64, 3.5, 0.0],
            parent: [3.0, 3.0],
        })
        .collect();
    let batch = evaluate_batch(&u, &m, &root, &cands, 11).unwrap();
    for (i, c) in cands.iter().enumerate() {
        let s = crlam_core::info::candidate_seed(11, i as u64);
        let e = u.evaluate(&m, &root, c, s).unwrap();
        assert_eq!(e.gain, batch[i].gain);
        assert_eq!(e.belief, batch[i].belief);
    }
}

#[test]
fn commit_records_the_scan_and_a_surface_candidate_works() {
    let mut m = world();
    let u = ucrmi(1.0);
    let c = Candidate::at([3.0, 3.0, 0.0]);
    let root = u.root_belief([3.0, 3.0, 0.0], 0).unwrap();
    let e1 = u.evaluate(&m, &root, &c, 1).unwrap();
    assert!(e1.gain > 0.0);
    u.commit(&mut m, &e1.update).unwrap();
    let e2 = u.evaluate(&m, &root, &c, 1).unwrap();
    assert!(e2.gain < e1.gain, "{} then {}", e1.gain, e2.gain);
}

#[test]
fn bad_settings_and_beliefs_are_refused() {
    let mut c = UcrmiConfig::new(5.0, 0.2);
    c.alpha = 1.5;
    assert!(Ucrmi::new(c).is_err());
    let mut c = UcrmiConfig::new(5.0, 0.2);
    c.n_particles = 0;
    assert!(Ucrmi::new(c).is_err());
    let u = ucrmi(0.5);
    let mut b = u.root_belief([3.0, 3.0, 0.0], 0).unwrap();
    b.log_weights.pop();
    assert!(u
        .evaluate(&world(), &b, &Candidate::at([3.0, 3.0, 0.0]), 0)
        .is_err());
}
