//! Tests of the IIG planner against planner-spec 9.1 (items 1–13, planner side): tree, cost,
//! edge-length, clearance, RIC, stopping, budget, path, bookkeeping, covariance and determinism
//! invariants, plus a brute-force replay of the spec's loop and end-to-end runs.

use crlam_core::grid::GridGeometry;
use crlam_core::info::fsmi::{Fsmi, FsmiVariant};
use crlam_core::info::gp::{GpVarianceMap, Gpvr};
use crlam_core::info::lattice::OccupancyLattice;
use crlam_core::info::posecov::{root_covariance, Cov3, EdgeNoise, PoseJacobian};
use crlam_core::info::{candidate_seed, Candidate, Evaluation, InfoUnits, InformationFunction};
use crlam_core::planner::primitives;
use crlam_core::planner::*;
use crlam_core::rng::Rng;
use crlam_core::Result;

/// A `size` m square world on the planner's 0.2 m lattice (nodes −1 … size + 1): prior 0.3,
/// 0.85 on the border walls x, y ∈ {0, size} and on an inner wall x = size/2, y ≤ 0.6·size.
fn world(size: f64) -> (OccupancyLattice, PlannerWorld) {
    let n = ((size + 2.0) / 0.2).round() as usize + 1;
    let on = |v: f64, c: f64| (v - c).abs() < 0.05;
    let inside = |v: f64| (-0.05..=size + 0.05).contains(&v);
    let prob = (0..n * n)
        .map(|id| {
            let (x, y) = (-1.0 + 0.2 * (id % n) as f64, -1.0 + 0.2 * (id / n) as f64);
            let border = (on(x, 0.0) || on(x, size)) && inside(y)
                || (on(y, 0.0) || on(y, size)) && inside(x);
            let inner = on(x, 0.5 * size) && y <= 0.6 * size + 0.05 && inside(y);
            if border || inner {
                0.85
            } else {
                0.3
            }
        })
        .collect();
    let g = GridGeometry::new([-1.1, -1.1], 0.2).unwrap();
    let lat = OccupancyLattice::new(g, n, n, prob).unwrap();
    let w = PlannerWorld::from_lattice(lat.clone(), 0.5).unwrap();
    (lat, w)
}

fn settings(start: [f64; 2]) -> IigSettings {
    IigSettings {
        start,
        max_iterations: 20_000,
        ..IigSettings::reference()
    }
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (b[0] - a[0]).hypot(b[1] - a[1])
}

/// A cheap function with decaying gains: w(x)/(1 + #committed scans within 2 m) plus a 1e-3
/// jitter from the evaluation seed; with `Mock(true)` the gain is always 0. The belief is the
/// depth, so parent beliefs are checkable. The map lists the committed scans.
struct Mock(bool);
const MOCK: Mock = Mock(false);
const ZERO: Mock = Mock(true);

#[derive(Default)]
struct MockMap {
    scans: Vec<[f64; 2]>,
}

impl InformationFunction for Mock {
    type Map = MockMap;
    type Belief = u32;
    type Update = [f64; 2];
    fn name(&self) -> &'static str {
        "mock"
    }
    fn units(&self) -> InfoUnits {
        InfoUnits::Nats
    }
    fn evaluate(
        &self,
        map: &MockMap,
        parent: &u32,
        c: &Candidate,
        seed: u64,
    ) -> Result<Evaluation<u32, [f64; 2]>> {
        let p = [c.pose[0], c.pose[1]];
        assert_eq!(c.pose[2], 0.0);
        let near = map.scans.iter().filter(|q| dist(p, **q) < 2.0).count();
        let jitter = (seed >> 11) as f64 / (1u64 << 53) as f64 * 1e-3;
        Ok(Evaluation {
            gain: if self.0 {
                0.0
            } else {
                (1.0 + 0.1 * p[0]) / (1 + near) as f64 + jitter
            },
            belief: parent + u32::from(c.parent != p),
            update: p,
        })
    }
    fn commit(&self, map: &mut MockMap, u: &[f64; 2]) -> Result<()> {
        map.scans.push(*u);
        Ok(())
    }
}

/// Items 1, 2, 5, 6, 8 and the logs' shapes.
fn check_tree<B>(r: &IigResult<B>, s: &IigSettings) {
    let n = r.nodes.len();
    assert!(r.nodes[0].parent.is_none() && r.nodes[0].cost == 0.0 && r.nodes[0].gain == 0.0);
    assert_eq!(r.nodes[0].info, r.root_gain);
    assert_eq!(r.nodes[0].covariance, s.root_covariance);
    assert_eq!(r.nodes.iter().filter(|v| v.parent.is_some()).count(), n - 1);
    let mut edges = 0.0;
    for (u, node) in r.nodes.iter().enumerate().skip(1) {
        let p = node.parent.unwrap();
        assert!(p < u);
        let len = dist(r.nodes[p].position, node.position);
        edges += len;
        assert!((node.cost - (r.nodes[p].cost + len)).abs() < 1e-12);
        assert!(node.cost > r.nodes[p].cost);
        assert!(!r.nodes[p].closed, "node {u} has a closed parent");
        assert_eq!(node.closed, node.cost > s.budget);
        // One node per sample: acceptance iterations strictly increase.
        assert!(node.iteration > r.nodes[u - 1].iteration);
    }
    assert!(n <= r.iterations + 1);
    assert!(r.evaluations >= n);
    assert_eq!(r.iteration_gain.len(), r.iterations);
    assert!((r.total_cost - edges).abs() < 1e-9 * (1.0 + edges));
    assert_eq!(r.total_info, r.nodes.iter().map(|v| v.gain).sum::<f64>());
    // Item 6: cumRIC has one entry per node, starts at 0, is non-decreasing; penalized ≤ raw with
    // n_s = the samples since the previous acceptance (iteration differences) ≥ 1.
    assert_eq!(r.cum_ric.len(), n);
    assert_eq!(r.cum_ric[0], 0.0);
    assert_eq!(r.ric.len() + r.ric_skipped, n - 1);
    assert!(r.cum_ric.windows(2).all(|w| w[1] >= w[0]));
    if r.ric_skipped == 0 {
        for (k, &pen) in r.ric.iter().enumerate() {
            let u = &r.nodes[k + 1];
            let v = &r.nodes[u.parent.unwrap()];
            let raw = u.info / v.info - 1.0;
            let n_s = u.iteration - r.nodes[k].iteration;
            assert!(n_s >= 1 && raw >= 0.0 && pen <= raw);
            assert!((pen - raw / n_s as f64).abs() <= 1e-15 * raw.abs().max(1.0));
            assert!((r.cum_ric[k + 1] - r.cum_ric[k] - pen).abs() < 1e-12);
        }
    }
    // Item 7: the run stops at the first acceptance whose window mean reaches δ.
    let w = s.ric_window;
    let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
    if r.stop == StopReason::Converged {
        assert!(r.ric.len() >= w);
        assert!(mean(&r.ric[r.ric.len() - w..]) <= s.delta_ric);
        assert_eq!(
            r.nodes[n - 1].iteration,
            r.iterations,
            "last event is an acceptance"
        );
        for end in w..r.ric.len() {
            assert!(
                mean(&r.ric[end - w..end]) > s.delta_ric,
                "converged earlier at {end}"
            );
        }
    }
    // Item 10 on a real tree.
    let best = &r.max_info_path;
    assert_eq!(best[0], 0);
    let leaf = *best.last().unwrap();
    assert!(r.nodes.iter().all(|v| v.parent != Some(leaf)));
    let gains = r.gains();
    assert!(r.main_paths.contains(best));
    for p in &r.main_paths {
        assert!(path_gain(p, &gains) <= r.max_info_path_info);
    }
    assert_eq!(r.max_info_path_length, r.nodes[leaf].cost);
}

fn depth<B>(r: &IigResult<B>, mut u: usize) -> u32 {
    let mut d = 0;
    while let Some(p) = r.nodes[u].parent {
        d += 1;
        u = p;
    }
    d
}

#[test]
fn reference_run_invariants_with_the_mock() {
    let (_, w) = world(10.0);
    let s = settings([2.0, 2.0]);
    let r = run_iig(&MOCK, &mut MockMap::default(), 0, &w, &s, 7).unwrap();
    assert_eq!(r.stop, StopReason::Converged);
    assert!(r.nodes.len() > 40, "{}", r.nodes.len());
    check_tree(&r, &s);
    for (u, node) in r.nodes.iter().enumerate().skip(1) {
        // Item 3: reference steer edges in [0.5, 3] m.
        let p = node.parent.unwrap();
        let len = dist(r.nodes[p].position, node.position);
        assert!((0.5 - 1e-12..=3.0 + 1e-12).contains(&len), "edge {len}");
        // Item 11, reference: I_u = ΔI_u + I_{π(π(u))}, the root its own parent.
        let pp = r.nodes[p].parent.unwrap_or(p);
        assert_eq!(node.info, node.gain + r.nodes[pp].info);
        // The parent's belief was passed: beliefs are depths.
        assert_eq!(node.belief, depth(&r, u));
    }
}

#[test]
fn clean_run_keeps_the_clearance_and_sums_the_path() {
    let (_, w) = world(10.0);
    let s = IigSettings {
        start: [2.0, 2.0],
        max_iterations: 20_000,
        ..IigSettings::clean()
    };
    let r = run_iig(&MOCK, &mut MockMap::default(), 0, &w, &s, 3).unwrap();
    check_tree(&r, &s);
    assert_eq!(r.stop, StopReason::Converged);
    // Item 4: the 0.08 m walk checks points at most 0.04 m from any edge point, so the true
    // clearance is at least √(0.8² − 0.04²) = 0.799; check at 0.01 m spacing, brute force.
    let bound = (0.8f64 * 0.8 - 0.04 * 0.04).sqrt();
    let obstacles = w.obstacle_points();
    let mut worst = f64::INFINITY;
    for node in r.nodes.iter().skip(1) {
        let (a, b) = (r.nodes[node.parent.unwrap()].position, node.position);
        let k = (dist(a, b) / 0.01).ceil() as usize;
        for i in 0..=k {
            let t = i as f64 / k as f64;
            let p = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
            for o in obstacles {
                worst = worst.min(dist(p, *o));
            }
        }
        for c in node.position {
            assert!((0.8 - 0.01..=9.2 + 0.01).contains(&c));
        }
        assert!(dist(a, b) <= 0.5 + 1e-12);
    }
    assert!(worst > bound, "closest approach {worst}");
    // Item 11, path_sum: I_u = I_root + Σ ΔI over the non-root nodes of the path.
    for u in 1..r.nodes.len() {
        let path = root_path(&r.parents(), u);
        let want = path
            .iter()
            .skip(1)
            .fold(r.root_gain, |acc, &v| acc + r.nodes[v].gain);
        assert_eq!(r.nodes[u].info, want);
    }
}

#[test]
fn matches_a_brute_force_replay_of_the_spec_loop() {
    let (_, w) = world(10.0);
    let mut modes = [settings([2.0, 2.0]), IigSettings::clean()];
    modes[1].start = [8.0, 7.0];
    modes[1].budget = 6.0;
    for (k, s) in modes.iter().enumerate() {
        let seed = 11 + k as u64;
        let r = run_iig(&MOCK, &mut MockMap::default(), 0, &w, s, seed).unwrap();
        let b = replay(&w, s, seed);
        assert_eq!(r.nodes.len(), b.nodes.len(), "mode {k}");
        for (x, y) in r.nodes.iter().zip(&b.nodes) {
            assert_eq!((x.position, x.parent, x.closed), (y.0, y.1, y.4));
            assert_eq!(
                (x.cost.to_bits(), x.info.to_bits()),
                (y.2.to_bits(), y.3.to_bits())
            );
        }
        assert_eq!(r.ric, b.ric);
        assert_eq!(r.iteration_gain, b.iteration_gain);
        assert_eq!((r.iterations, r.evaluations), (b.iterations, b.evaluations));
        assert_eq!(r.stop, StopReason::Converged);
    }
}

/// (position, parent, cost, info, closed)
type ReplayNode = ([f64; 2], Option<usize>, f64, f64, bool);

struct Replay {
    nodes: Vec<ReplayNode>,
    ric: Vec<f64>,
    iteration_gain: Vec<f64>,
    iterations: usize,
    evaluations: usize,
}

/// planner-spec 3.3 written out with brute-force searches (no spatial index).
fn replay(w: &PlannerWorld, s: &IigSettings, seed: u64) -> Replay {
    let lat = w.prior();
    let free: Vec<[f64; 2]> = (0..lat.len())
        .filter(|&i| lat.get(i) < s.sample_threshold)
        .map(|i| lat.node_position(i))
        .collect();
    let mut rng = Rng::new(seed);
    let mut map = MockMap::default();
    let eval = |map: &MockMap, pose: [f64; 2], parent: [f64; 2], k: usize| {
        let c = Candidate {
            pose: [pose[0], pose[1], 0.0],
            parent,
        };
        MOCK.evaluate(map, &0, &c, candidate_seed(seed, k as u64))
            .unwrap()
            .gain
    };
    // Steer and the walks are unit-tested in `planner::primitives`; the searches here are brute
    // force over all nodes and all obstacle points.
    let steer = |a: [f64; 2], b: [f64; 2]| primitives::steer(a, b, s.steer);
    let free_edge = |a: [f64; 2], b: [f64; 2]| {
        let obstacles = w.obstacle_points();
        primitives::collision_walk(a, b, s.collision)
            .iter()
            .all(|&p| obstacles.iter().all(|o| dist(p, *o) > s.clearance))
    };
    let g0 = eval(&map, s.start, s.start, 0);
    map.scans.push(s.start);
    let mut out = Replay {
        nodes: vec![(s.start, None, 0.0, g0, false)],
        ric: vec![],
        iteration_gain: vec![],
        iterations: 0,
        evaluations: 1,
    };
    let (mut cont, mut n_s) = (f64::INFINITY, 0);
    while cont > s.delta_ric && out.iterations < s.max_iterations {
        out.iterations += 1;
        let xs = free[((rng.uniform() * free.len() as f64) as usize).min(free.len() - 1)];
        n_s += 1;
        let mut gains = vec![];
        let d2 = |v: &ReplayNode, q: [f64; 2]| (v.0[0] - q[0]).powi(2) + (v.0[1] - q[1]).powi(2);
        let nodes = &out.nodes;
        let nn = (0..nodes.len())
            .filter(|&i| s.nearest == NearestMode::AllNodes || !nodes[i].4)
            .min_by(|&a, &b| {
                d2(&nodes[a], xs)
                    .total_cmp(&d2(&nodes[b], xs))
                    .then(a.cmp(&b))
            })
            .unwrap();
        if let (false, Some(xf)) = (nodes[nn].4, steer(nodes[nn].0, xs)) {
            let mut near: Vec<usize> = (0..nodes.len())
                .filter(|&i| d2(&nodes[i], xf) <= s.r_near * s.r_near)
                .collect();
            near.sort_by(|&a, &b| {
                d2(&nodes[a], xf)
                    .total_cmp(&d2(&nodes[b], xf))
                    .then(a.cmp(&b))
            });
            for v in near {
                let (xv, pv, cv, iv, closed) = out.nodes[v];
                let Some(xn) = steer(xv, xf).filter(|&xn| !closed && free_edge(xv, xn)) else {
                    continue;
                };
                let g = eval(&map, xn, xv, out.evaluations);
                out.evaluations += 1;
                if s.mutation == MapMutation::EveryEvaluation {
                    map.scans.push(xn);
                }
                gains.push(g);
                let inew = if s.accumulation == InfoAccumulation::Reference {
                    g + out.nodes[pv.unwrap_or(v)].3
                } else {
                    iv + g
                };
                let cnew = cv + dist(xv, xn);
                if inew < iv && cnew > cv {
                    continue;
                }
                if s.mutation == MapMutation::AcceptedOnly {
                    map.scans.push(xn);
                }
                out.nodes.push((xn, Some(v), cnew, inew, cnew > s.budget));
                out.ric.push((inew / iv - 1.0) / n_s as f64);
                n_s = 0;
                if out.ric.len() >= 31 {
                    cont = out.ric[out.ric.len() - 31..].iter().sum::<f64>() / 31.0;
                }
                break;
            }
        }
        out.iteration_gain.push(if gains.is_empty() {
            0.0
        } else {
            gains.iter().sum::<f64>() / gains.len() as f64
        });
    }
    out
}

#[test]
fn runs_are_deterministic_and_seeded() {
    let (lat, w) = world(8.0);
    let s = settings([2.0, 2.0]);
    let run = |seed| {
        let mut map = GpVarianceMap::new(lat.clone());
        let r = run_iig(&Gpvr::reference(), &mut map, (), &w, &s, seed).unwrap();
        (r, map)
    };
    let (a, ma) = run(5);
    let (b, mb) = run(5);
    assert_eq!(a.nodes, b.nodes);
    let bits = |r: &IigResult<()>| {
        r.nodes
            .iter()
            .flat_map(|n| [n.position[0], n.position[1], n.cost, n.info, n.gain])
            .map(f64::to_bits)
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(
        (&a.ric, &a.cum_ric, &a.iteration_gain),
        (&b.ric, &b.cum_ric, &b.iteration_gain)
    );
    assert_eq!(ma.variances(), mb.variances());
    let (c, _) = run(6);
    assert_ne!(bits(&a), bits(&c));
}

#[test]
fn a_tiny_budget_closes_nodes_and_never_extends_them() {
    let (_, w) = world(10.0);
    for nearest in [NearestMode::AllNodes, NearestMode::OpenOnly] {
        let s = IigSettings {
            budget: 2.5,
            nearest,
            max_iterations: 3000,
            ..settings([2.0, 2.0])
        };
        let r = run_iig(&MOCK, &mut MockMap::default(), 0, &w, &s, 1).unwrap();
        check_tree(&r, &s);
        let closed = r.nodes.iter().filter(|v| v.closed).count();
        assert!(closed > 0, "no node closed");
        assert!(r.nodes.iter().filter(|v| v.closed).all(|v| v.cost > 2.5));
    }
    // With B = 1e5 nothing closes.
    let r = run_iig(
        &MOCK,
        &mut MockMap::default(),
        0,
        &w,
        &settings([2.0, 2.0]),
        1,
    )
    .unwrap();
    assert!(r.nodes.iter().all(|v| !v.closed));
}

#[test]
fn guards_fire_and_are_recorded() {
    let (_, w) = world(10.0);
    let s = IigSettings {
        max_iterations: 25,
        ..settings([2.0, 2.0])
    };
    let r = run_iig(&MOCK, &mut MockMap::default(), 0, &w, &s, 1).unwrap();
    assert_eq!((r.stop, r.iterations), (StopReason::MaxIterations, 25));
    assert_eq!(r.stop.name(), "max_iterations");
    let s = IigSettings {
        max_wall_seconds: 1e-12,
        ..settings([2.0, 2.0])
    };
    let r = run_iig(&MOCK, &mut MockMap::default(), 0, &w, &s, 1).unwrap();
    assert_eq!(
        (r.stop, r.iterations, r.nodes.len()),
        (StopReason::WallClock, 0, 1)
    );
    for stop in [
        StopReason::Converged,
        StopReason::NoOpenNodes,
        StopReason::WallClock,
    ] {
        assert_eq!(StopReason::parse(stop.name()).unwrap(), stop);
    }
    // I_v = 0 everywhere: every RIC entry is skipped and counted, cumRIC stays flat.
    let s = IigSettings {
        max_iterations: 300,
        ..settings([2.0, 2.0])
    };
    let mut map = MockMap::default();
    let r = run_iig(&ZERO, &mut map, 0, &w, &s, 1).unwrap();
    assert!(r.nodes.len() > 5 && r.ric.is_empty());
    assert_eq!(r.ric_skipped, r.nodes.len() - 1);
    assert!(r.cum_ric.iter().all(|&c| c == 0.0) && r.cum_ric.len() == r.nodes.len());
    assert_eq!(
        map.scans.len(),
        r.evaluations,
        "every evaluation is committed"
    );
    let s = IigSettings {
        mutation: MapMutation::AcceptedOnly,
        ..s
    };
    let mut map = MockMap::default();
    let r = run_iig(&ZERO, &mut map, 0, &w, &s, 1).unwrap();
    assert_eq!(
        map.scans.len(),
        r.nodes.len(),
        "root and accepted nodes only"
    );
    // Bad inputs are errors, not panics.
    let bad = IigSettings {
        r_near: f64::NAN,
        ..s
    };
    assert!(run_iig(&ZERO, &mut MockMap::default(), 0, &w, &bad, 1).is_err());
    let none_free = IigSettings {
        sample_threshold: 0.1,
        ..s
    };
    assert!(run_iig(&ZERO, &mut MockMap::default(), 0, &w, &none_free, 1).is_err());
    let (lat, w) = world(6.0);
    let outside = IigSettings {
        start: [50.0, 2.0],
        ..s
    };
    assert!(run_iig(
        &Gpvr::reference(),
        &mut GpVarianceMap::new(lat),
        (),
        &w,
        &outside,
        1
    )
    .is_err());
}

/// Independent form of planner-spec 3.9: explicit F, W and triple products.
fn propagate_by_hand(s: &Cov3, a: [f64; 2], b: [f64; 2], q: &Cov3, jac: PoseJacobian) -> Cov3 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let (d, h) = (dx.hypot(dy), dy.atan2(dx));
    let c = match jac {
        PoseJacobian::Reference => [-d * (2.0 * h).sin(), d * (2.0 * h).cos()],
        PoseJacobian::Unicycle => [-d * h.sin(), d * h.cos()],
    };
    let f = [[1.0, 0.0, c[0]], [0.0, 1.0, c[1]], [0.0, 0.0, 1.0]];
    let w = [
        [h.cos(), -h.sin(), 0.0],
        [h.sin(), h.cos(), 0.0],
        [0.0, 0.0, 1.0],
    ];
    let mut out = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            for k in 0..3 {
                for l in 0..3 {
                    out[i][j] += f[i][k] * s[k][l] * f[j][l] + w[i][k] * q[k][l] * w[j][l];
                }
            }
        }
    }
    out
}

#[test]
fn node_covariances_follow_the_edge_recursion() {
    let (_, w) = world(10.0);
    for jacobian in [PoseJacobian::Reference, PoseJacobian::Unicycle] {
        let s = IigSettings {
            jacobian,
            ..settings([2.0, 2.0])
        };
        let r = run_iig(&MOCK, &mut MockMap::default(), 0, &w, &s, 2).unwrap();
        let q = EdgeNoise::default();
        assert_eq!(r.nodes[0].covariance, root_covariance());
        for node in r.nodes.iter().skip(1) {
            let p = &r.nodes[node.parent.unwrap()];
            let (sp, su) = (&p.covariance, &node.covariance);
            assert_eq!(su[2][2], sp[2][2] + q.q()[2][2]);
            if p.parent.is_none() {
                assert_eq!(
                    [su[0][0], su[1][1], su[0][1]],
                    [sp[0][0] + 0.01, sp[1][1] + 0.01, 0.0]
                );
            }
            let want = propagate_by_hand(sp, p.position, node.position, q.q(), jacobian);
            for i in 0..3 {
                for j in 0..3 {
                    assert!((su[i][j] - want[i][j]).abs() < 1e-12 * (1.0 + want[i][j].abs()));
                    assert_eq!(su[i][j], su[j][i]);
                }
                assert!(su[i][i] >= 0.0);
            }
            let m2 = su[0][0] * su[1][1] - su[0][1] * su[0][1];
            assert!(m2 >= -1e-12, "xy block not PSD");
        }
    }
}

#[test]
fn end_to_end_gpvr_and_fsmi_converge() {
    let (lat, w) = world(10.0);
    let s = settings([2.0, 2.0]);
    let mut map = GpVarianceMap::new(lat.clone());
    let before = map.total_log_variance();
    let r = run_iig(&Gpvr::reference(), &mut map, (), &w, &s, 0).unwrap();
    assert_eq!(r.stop, StopReason::Converged);
    check_tree(&r, &s);
    assert!(r.nodes.len() >= 32 && r.root_gain > 0.0);
    assert!(map.total_log_variance() < before, "the map was mutated");
    let mut lattice = lat.clone();
    let f = Fsmi::new(FsmiVariant::NoiseFree);
    let r = run_iig(&f, &mut lattice, (), &w, &s, 0).unwrap();
    assert_eq!(r.stop, StopReason::Converged);
    check_tree(&r, &s);
    assert_ne!(lattice.probabilities(), lat.probabilities());
}

/// One full run per function on a world (printed; timing only, run with `--ignored`).
fn time_functions(lat: &OccupancyLattice, w: &PlannerWorld, s: &IigSettings, seed: u64) {
    use crlam_core::info::crmi::{Crmi, CrmiConfig};
    use crlam_core::info::gp::Ugpvr;
    use crlam_core::info::prior::crm_from_lattice;
    use crlam_core::info::ucrmi::{Ucrmi, UcrmiConfig};
    fn show<B>(name: &str, r: &IigResult<B>) {
        println!(
            "{name:>6}: {:>5} nodes {:>6} iterations {:>6} evaluations  stop {:<14} {:>8.2} s  \
             cost {:.1} m",
            r.nodes.len(),
            r.iterations,
            r.evaluations,
            r.stop.name(),
            r.seconds,
            r.total_cost
        );
    }
    let gp = || GpVarianceMap::new(lat.clone());
    show(
        "gpvr",
        &run_iig(&Gpvr::reference(), &mut gp(), (), w, s, seed).unwrap(),
    );
    let r = run_iig(
        &Ugpvr::reference(),
        &mut gp(),
        root_covariance(),
        w,
        s,
        seed,
    );
    show("ugpvr", &r.unwrap());
    let f = Fsmi::default();
    show(
        "fsmi",
        &run_iig(&f, &mut lat.clone(), (), w, s, seed).unwrap(),
    );
    let crm = || crm_from_lattice(lat, 10).unwrap();
    let f = Crmi::new(CrmiConfig::new(5.0, 0.2)).unwrap();
    show("crmi", &run_iig(&f, &mut crm(), (), w, s, seed).unwrap());
    let f = Ucrmi::new(UcrmiConfig::new(5.0, 0.2)).unwrap();
    let root = f.root_belief([s.start[0], s.start[1], 0.0], seed).unwrap();
    show("ucrmi", &run_iig(&f, &mut crm(), root, w, s, seed).unwrap());
}

/// The 111 × 111 Cave-like benchmark lattice (walls at 0, 5, 10, 15, 20 m; its 1.4 m door gaps
/// between obstacle points are narrower than 2 × 0.8 m, so the tree stays in the start room).
#[test]
#[ignore]
fn timing_on_the_synthetic_cave() {
    let lat = crlam_bench::info::synthetic_cave_lattice().unwrap();
    let w = PlannerWorld::from_lattice(lat.clone(), 0.5).unwrap();
    for (name, base) in [
        ("reference", IigSettings::reference()),
        ("clean", IigSettings::clean()),
    ] {
        println!("synthetic cave, {name} settings, start (2.5, 2.5), seed 0");
        let s = IigSettings {
            start: [2.5, 2.5],
            ..base
        };
        time_functions(&lat, &w, &s, 0);
    }
}
