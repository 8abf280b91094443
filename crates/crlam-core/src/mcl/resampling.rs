//! The localizer's resamplings: KLD sampling with recovery's random particles and the floor of
//! competing clusters, and the floor per place or per bin of a spread set.

use std::collections::HashMap;

use crate::mcl::cluster::Cluster;
use crate::mcl::filter::Mcl;
use crate::mcl::kld::{BinCounter, KldSettings};
use crate::pose::{wrap, Pose};
use crate::rng::Rng;

impl Mcl {
    /// KLD sampling from the weights `w` with random particles at `inject` probability, then the
    /// floor of `min_cluster` particles for every competing cluster of `found` (`labels`: each
    /// particle's cluster); returns how many were injected and how many clusters were kept.
    pub(super) fn resample(
        &mut self,
        w: &[f64],
        inject: f64,
        found: &[Cluster],
        labels: &[usize],
        kld: &KldSettings,
    ) -> (usize, usize) {
        let kld = *kld;
        let mut cumulative = Vec::with_capacity(w.len());
        let mut s = 0.0;
        for &x in w {
            s += x;
            cumulative.push(s);
        }
        let total = s;
        let draw_step = 3 * self.step + 1;
        let mut out = Vec::with_capacity(kld.n_min.max(self.poses.len()));
        // The particle each draw copied (None: a random one).
        let mut origin: Vec<Option<usize>> = Vec::with_capacity(out.capacity());
        let mut bins = BinCounter::default();
        let (mut injected, mut drawn) = (0, 0);
        while out.len() < kld.n_max {
            let mut rng = Rng::stream(self.cfg.seed, draw_step, out.len() as u64);
            let random = inject > 0.0 && rng.uniform() < inject;
            match random.then(|| self.field.sample_free(&mut rng)).flatten() {
                Some(p) => {
                    injected += 1;
                    out.push(p);
                    origin.push(None);
                }
                None => {
                    let u = rng.uniform() * total;
                    let i = cumulative.partition_point(|&c| c <= u).min(w.len() - 1);
                    let pose = self.poses[i];
                    drawn += 1;
                    let k = bins.add(&kld, &pose);
                    out.push(pose);
                    origin.push(Some(i));
                    if drawn >= kld.limit(k) {
                        break;
                    }
                }
            }
        }
        // While recovery injects, the set is AMCL's: its random particles come and go, and a
        // place they find competes once it holds on without them.
        let n_kept = if injected == 0 {
            self.keep_clusters(w, found, labels, &mut out, &mut origin, kld.n_max)
        } else {
            0
        };
        self.log_w = if n_kept > 1 {
            cluster_log_weights(&origin, found, labels, injected)
        } else {
            vec![0.0; out.len()]
        };
        self.poses = out;
        (injected, if n_kept > 1 { n_kept } else { 0 })
    }

    /// The place (see [`MclConfig::place_xy`]) of a pose: its cell of `place_xy` m and its
    /// heading sector of `place_theta` rad counted from −π (the last sector, possibly narrower,
    /// ends at π).
    pub(super) fn place_of(&self, p: &Pose) -> (i64, i64, i64) {
        let (s, t) = (self.cfg.place_xy, self.cfg.place_theta);
        let n_t = ((2.0 * std::f64::consts::PI / t).ceil() as i64).max(1);
        (
            (p[0] / s).floor() as i64,
            (p[1] / s).floor() as i64,
            (((wrap(p[2]) + std::f64::consts::PI) / t).floor() as i64).clamp(0, n_t - 1),
        )
    }

    /// The resampling of a spread set with a floor per cell of the pose space (`keys[j]`:
    /// particle j's cell; the `min_bin` floor per pose bin, or the `min_cluster` floor per
    /// place): every cell holding at least `keep_ratio` times the heaviest cell's weight first
    /// gets `floor` draws from within it by weight (heaviest cells first, while they fit in
    /// `n_max`), then KLD sampling draws the rest up to its bound or `n_max`; every particle
    /// weighs its cell's weight over the cell's new count. Returns the number of floored cells.
    pub(super) fn resample_floored(
        &mut self,
        w: &[f64],
        kld: &KldSettings,
        keys: &[(i64, i64, i64)],
        floor: usize,
    ) -> usize {
        let cfg = &self.cfg;
        let kld = *kld;
        let mut index: HashMap<(i64, i64, i64), usize> = HashMap::new();
        let mut members: Vec<Vec<usize>> = Vec::new();
        let mut bin_w: Vec<f64> = Vec::new();
        let mut label = Vec::with_capacity(w.len());
        for (j, key) in keys.iter().enumerate() {
            let n = index.len();
            let b = *index.entry(*key).or_insert(n);
            if b == members.len() {
                members.push(Vec::new());
                bin_w.push(0.0);
            }
            members[b].push(j);
            bin_w[b] += w[j];
            label.push(b);
        }
        let best = bin_w.iter().copied().fold(0.0, f64::max);
        // Bins by weight, heaviest first (ties by first member: never by hashing).
        let mut order: Vec<usize> = (0..bin_w.len())
            .filter(|&b| bin_w[b] > 0.0 && bin_w[b] >= cfg.keep_ratio * best)
            .collect();
        order.sort_by(|&a, &b| {
            bin_w[b]
                .total_cmp(&bin_w[a])
                .then(members[a][0].cmp(&members[b][0]))
        });
        let draw_step = 3 * self.step + 1;
        let mut out: Vec<Pose> = Vec::with_capacity(kld.n_max);
        let mut origin: Vec<usize> = Vec::with_capacity(kld.n_max);
        let mut counter = BinCounter::default();
        let mut stream = kld.n_max as u64;
        let mut floored = 0;
        for &b in &order {
            if out.len() + floor > kld.n_max {
                break;
            }
            floored += 1;
            for _ in 0..floor {
                let mut rng = Rng::stream(cfg.seed, draw_step, stream);
                stream += 1;
                let mut u = rng.uniform() * bin_w[b];
                let m = &members[b];
                let mut pick = m[m.len() - 1];
                for &j in m {
                    if u < w[j] {
                        pick = j;
                        break;
                    }
                    u -= w[j];
                }
                counter.add(&kld, &self.poses[pick]);
                out.push(self.poses[pick]);
                origin.push(pick);
            }
        }
        let mut cumulative = Vec::with_capacity(w.len());
        let mut s = 0.0;
        for &x in w {
            s += x;
            cumulative.push(s);
        }
        let mut k = 0u64;
        while out.len() < kld.n_max && out.len() < kld.limit(counter.len()) {
            let mut rng = Rng::stream(cfg.seed, draw_step, k);
            k += 1;
            let u = rng.uniform() * s;
            let i = cumulative.partition_point(|&c| c <= u).min(w.len() - 1);
            counter.add(&kld, &self.poses[i]);
            out.push(self.poses[i]);
            origin.push(i);
        }
        let mut count = vec![0usize; bin_w.len()];
        for &i in &origin {
            count[label[i]] += 1;
        }
        self.log_w = origin
            .iter()
            .map(|&i| {
                let b = label[i];
                (bin_w[b] / count[b] as f64).max(f64::MIN_POSITIVE).ln()
            })
            .collect();
        self.poses = out;
        floored
    }

    /// Tops up every competing cluster (weight at least `keep_ratio` times the heaviest's) to
    /// `min_cluster` particles with draws from within it by weight, while the set is below
    /// `n_max`; heaviest clusters first. Returns the number of competing clusters (0 when
    /// `min_cluster` is 0; nothing is drawn when there is one).
    pub(super) fn keep_clusters(
        &self,
        w: &[f64],
        found: &[Cluster],
        labels: &[usize],
        out: &mut Vec<Pose>,
        origin: &mut Vec<Option<usize>>,
        n_max: usize,
    ) -> usize {
        let cfg = &self.cfg;
        let best = found.first().map(|c| c.weight).unwrap_or(0.0);
        let n_comp = found
            .iter()
            .take_while(|c| c.weight > 0.0 && c.weight >= cfg.keep_ratio * best)
            .count();
        if cfg.min_cluster == 0 {
            return 0;
        }
        if n_comp < 2 {
            return n_comp;
        }
        let mut count = vec![0usize; n_comp];
        for &i in origin.iter().flatten() {
            if let Some(c) = count.get_mut(labels[i]) {
                *c += 1;
            }
        }
        let mut members: Vec<Vec<usize>> = vec![Vec::new(); n_comp];
        for (j, &l) in labels.iter().enumerate() {
            if let Some(m) = members.get_mut(l) {
                m.push(j);
            }
        }
        // Streams of their own: the KLD loop uses indices below n_max.
        let draw_step = 3 * self.step + 1;
        let mut extra = n_max as u64;
        for (c, m) in members.iter().enumerate() {
            let total: f64 = m.iter().map(|&j| w[j]).sum();
            while count[c] < cfg.min_cluster && out.len() < n_max && total > 0.0 {
                let mut rng = Rng::stream(cfg.seed, draw_step, extra);
                extra += 1;
                let mut u = rng.uniform() * total;
                let mut pick = m[m.len() - 1];
                for &j in m {
                    if u < w[j] {
                        pick = j;
                        break;
                    }
                    u -= w[j];
                }
                out.push(self.poses[pick]);
                origin.push(Some(pick));
                count[c] += 1;
            }
        }
        n_comp
    }
}

/// Log-weights after a resampling that keeps every cluster's weight: each of the `injected`
/// random particles weighs 1/n as in AMCL's resampling (n: the new set's size), and the
/// particles copied from cluster c share its weight W_c, scaled to the rest of the mass:
/// (1 − injected / n) · W_c / (particles copied from c).
pub(super) fn cluster_log_weights(
    origin: &[Option<usize>],
    found: &[Cluster],
    labels: &[usize],
    injected: usize,
) -> Vec<f64> {
    let mut count = vec![0usize; found.len()];
    for &i in origin.iter().flatten() {
        count[labels[i]] += 1;
    }
    let n = origin.len().max(1) as f64;
    let drawn_share = 1.0 - injected as f64 / n;
    origin
        .iter()
        .map(|o| match o {
            None => -n.ln(),
            Some(i) => {
                let c = labels[*i];
                (drawn_share * found[c].weight / count[c].max(1) as f64)
                    .max(f64::MIN_POSITIVE)
                    .ln()
            }
        })
        .collect()
}
