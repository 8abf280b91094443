//! Clusters of a weighted particle set, as AMCL forms them: the occupied pose bins (the KLD
//! histogram's boxes) joined to their neighbours (26-connected, the heading wrapping around) are
//! the clusters; the localizer's estimate is the weighted mean of the heaviest one. While the set
//! is spread over several places (global localization, recovery), the mean of the whole set lies
//! between them and means nothing; the heaviest cluster's mean is a pose the filter believes in.

use std::collections::HashMap;

use crate::mcl::kld::KldSettings;
use crate::pose::{wrap, Pose};

/// One cluster's weight and moments.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cluster {
    /// Sum of the normalised weights of its particles.
    pub weight: f64,
    /// Number of particles.
    pub count: usize,
    /// Weighted mean (x, y) and circular mean heading.
    pub mean: Pose,
    /// Weighted covariance of the position [xx, xy, yy] (m²).
    pub cov_xy: [f64; 3],
    /// Circular standard deviation of the heading, sqrt(−2 ln R) (rad).
    pub std_theta: f64,
}

impl Cluster {
    /// RMS distance of the particles from the mean position (m): sqrt(trace of the covariance).
    pub fn spread_xy(&self) -> f64 {
        (self.cov_xy[0] + self.cov_xy[2]).max(0.0).sqrt()
    }
}

fn find(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

/// The clusters of `poses` with normalised weights `w`, heaviest first.
pub fn clusters(poses: &[Pose], w: &[f64], kld: &KldSettings) -> Vec<Cluster> {
    clusters_with_labels(poses, w, kld).0
}

/// The clusters of `poses` with normalised weights `w`, heaviest first, and the index (into
/// that list) of the cluster of every particle.
pub fn clusters_with_labels(
    poses: &[Pose],
    w: &[f64],
    kld: &KldSettings,
) -> (Vec<Cluster>, Vec<usize>) {
    let mut index: HashMap<(i64, i64, i64), usize> = HashMap::new();
    let mut bin_of = Vec::with_capacity(poses.len());
    // Heading bins count from −π and wrap: bin n_t − 1 (the last, possibly narrower) touches 0.
    let two_pi = 2.0 * std::f64::consts::PI;
    let n_t = ((two_pi / kld.bin_theta).ceil() as i64).max(1);
    let mut keys = Vec::new();
    for p in poses {
        let t = (((wrap(p[2]) + std::f64::consts::PI) / kld.bin_theta).floor() as i64)
            .clamp(0, n_t - 1);
        let (x, y, _) = kld.bin_of(p);
        let b = (x, y, t);
        let n = index.len();
        let id = *index.entry(b).or_insert_with(|| {
            keys.push(b);
            n
        });
        bin_of.push(id);
    }
    let mut parent: Vec<usize> = (0..keys.len()).collect();
    for (i, &(x, y, t)) in keys.iter().enumerate() {
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dt in -1..=1 {
                    let tt = (t + dt).rem_euclid(n_t);
                    if let Some(&j) = index.get(&(x + dx, y + dy, tt)) {
                        let (a, b) = (find(&mut parent, i), find(&mut parent, j));
                        if a != b {
                            parent[a.max(b)] = a.min(b);
                        }
                    }
                }
            }
        }
    }
    // Accumulate per root: weight, count, Σw x, Σw y, Σw sin, Σw cos.
    let mut acc: HashMap<usize, [f64; 6]> = HashMap::new();
    let mut root_of = Vec::with_capacity(poses.len());
    for (k, (p, &wi)) in poses.iter().zip(w).enumerate() {
        let r = find(&mut parent, bin_of[k]);
        root_of.push(r);
        let a = acc.entry(r).or_insert([0.0; 6]);
        a[0] += wi;
        a[1] += 1.0;
        a[2] += wi * p[0];
        a[3] += wi * p[1];
        a[4] += wi * p[2].sin();
        a[5] += wi * p[2].cos();
    }
    let mut out: HashMap<usize, Cluster> = acc
        .iter()
        .map(|(&r, a)| {
            let ws = a[0].max(f64::MIN_POSITIVE);
            let mean = [a[2] / ws, a[3] / ws, a[4].atan2(a[5])];
            let res = (a[4].hypot(a[5]) / ws).clamp(1e-300, 1.0);
            (
                r,
                Cluster {
                    weight: a[0],
                    count: a[1] as usize,
                    mean,
                    cov_xy: [0.0; 3],
                    std_theta: (-2.0 * res.ln()).max(0.0).sqrt(),
                },
            )
        })
        .collect();
    for ((p, &wi), r) in poses.iter().zip(w).zip(&root_of) {
        if let Some(c) = out.get_mut(r) {
            let (dx, dy) = (p[0] - c.mean[0], p[1] - c.mean[1]);
            c.cov_xy[0] += wi * dx * dx;
            c.cov_xy[1] += wi * dx * dy;
            c.cov_xy[2] += wi * dy * dy;
        }
    }
    let mut v: Vec<(usize, Cluster)> = out
        .into_iter()
        .map(|(r, mut c)| {
            let ws = c.weight.max(f64::MIN_POSITIVE);
            c.cov_xy = c.cov_xy.map(|s| s / ws);
            (r, c)
        })
        .collect();
    // Heaviest first; ties (equal weights) by position, then by root, so the order never
    // depends on hashing.
    v.sort_by(|(ra, a), (rb, b)| {
        b.weight
            .total_cmp(&a.weight)
            .then(a.mean[0].total_cmp(&b.mean[0]))
            .then(a.mean[1].total_cmp(&b.mean[1]))
            .then(ra.cmp(rb))
    });
    let rank: HashMap<usize, usize> = v.iter().enumerate().map(|(k, (r, _))| (*r, k)).collect();
    let labels = root_of
        .iter()
        .map(|r| rank.get(r).copied().unwrap_or(0))
        .collect();
    (v.into_iter().map(|(_, c)| c).collect(), labels)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_groups_are_two_clusters() {
        let kld = KldSettings::default();
        let mut poses = Vec::new();
        let mut w = Vec::new();
        for i in 0..10 {
            poses.push([1.0 + 0.05 * i as f64, 1.0, 0.1]);
            w.push(0.07);
            poses.push([8.0, 5.0 + 0.05 * i as f64, -3.1]);
            w.push(0.03);
        }
        let c = clusters(&poses, &w, &kld);
        assert_eq!(c.len(), 2);
        assert!((c[0].weight - 0.7).abs() < 1e-12 && c[0].count == 10);
        assert!((c[0].mean[0] - 1.225).abs() < 1e-12 && (c[0].mean[2] - 0.1).abs() < 1e-12);
        assert!((c[1].mean[1] - 5.225).abs() < 1e-12);
        // Positions 0.05 m apart: variance of 0..9 × 0.05.
        let var = (0..10)
            .map(|i| (0.05 * i as f64 - 0.225).powi(2))
            .sum::<f64>()
            / 10.0;
        assert!((c[0].cov_xy[0] - var).abs() < 1e-12 && c[0].cov_xy[2].abs() < 1e-12);
        assert!(c[0].std_theta < 1e-6);
    }

    #[test]
    fn labels_name_each_particles_cluster() {
        let kld = KldSettings::default();
        let poses = [[0.0, 0.0, 0.0], [9.0, 9.0, 0.0], [0.1, 0.0, 0.0]];
        let (c, labels) = clusters_with_labels(&poses, &[0.2, 0.5, 0.3], &kld);
        assert_eq!(labels, vec![0, 1, 0]);
        assert!((c[0].weight - 0.5).abs() < 1e-12 && c[0].count == 2);
        assert!((c[1].weight - 0.5).abs() < 1e-12 && c[1].count == 1);
    }

    #[test]
    fn headings_across_the_cut_join() {
        let kld = KldSettings::default();
        let poses = [[0.0, 0.0, 3.13], [0.0, 0.0, -3.13]];
        let c = clusters(&poses, &[0.5, 0.5], &kld);
        assert_eq!(c.len(), 1);
        assert!(c[0].mean[2].abs() > 3.1);
    }
}
