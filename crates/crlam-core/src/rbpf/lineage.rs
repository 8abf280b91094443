//! Each particle's path: its pose at every processed scan, through resampling.
//!
//! The paths form a tree. Node i holds one pose and the node of the same lineage one processed
//! scan earlier, so resampled children share every ancestor with their parent and a step costs
//! one node per particle (28 bytes), whatever the path length. The path of the final best
//! particle is the trajectory GMapping reports: a pose sequence that one map explains, unlike the
//! per-step weighted mean, which can average poses of lineages that later died.
//!
//! A tree made with [`PathTree::recording_means`] also keeps, per node, the mean of the proposal
//! the pose was drawn from (an improved proposal's fitted Gaussian). The drawn pose carries the
//! proposal's spread as step-to-step jitter; the mean is the filter's best guess of where that
//! lineage was at that scan, so the path of means is the smoother estimate of the same lineage.

use crate::pose::Pose;

/// A node index; [`NO_NODE`] marks a path that has not started.
pub type NodeId = u32;

/// The parent of a root node.
pub const NO_NODE: NodeId = NodeId::MAX;

/// Append-only tree of particle poses (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct PathTree {
    poses: Vec<Pose>,
    parents: Vec<NodeId>,
    /// Proposal means, one per node, when recorded (24 more bytes a node).
    means: Option<Vec<Pose>>,
}

impl PathTree {
    /// A tree that also records each node's proposal mean (see the module docs).
    pub fn recording_means() -> Self {
        Self {
            means: Some(Vec::new()),
            ..Self::default()
        }
    }

    /// Whether proposal means are recorded.
    pub fn records_means(&self) -> bool {
        self.means.is_some()
    }

    /// Adds `pose` as the child of `parent` ([`NO_NODE`] for a root) and returns its node.
    ///
    /// # Panics
    /// Never for real runs: 2^32 − 1 nodes would need, e.g., 1,000 particles over 4 million
    /// processed scans; reaching it is a logic error, not bad input.
    pub fn push(&mut self, parent: NodeId, pose: Pose) -> NodeId {
        self.push_with_mean(parent, pose, pose)
    }

    /// Adds `pose`, drawn from a proposal with mean `mean`, as the child of `parent`; `mean` is
    /// dropped unless the tree records means. Panics as [`PathTree::push`].
    pub fn push_with_mean(&mut self, parent: NodeId, pose: Pose, mean: Pose) -> NodeId {
        let id = NodeId::try_from(self.poses.len()).expect("path tree is full");
        assert!(id != NO_NODE, "path tree is full");
        debug_assert!(parent == NO_NODE || parent < id);
        self.poses.push(pose);
        self.parents.push(parent);
        if let Some(means) = &mut self.means {
            means.push(mean);
        }
        id
    }

    /// Appends each particle's current pose (and its proposal mean) to its path: call once per
    /// processed scan, after the proposals and before resampling, so that children inherit the
    /// pose their parent was weighed at.
    pub fn advance<'a>(&mut self, particles: impl Iterator<Item = (&'a mut NodeId, Pose, Pose)>) {
        for (node, pose, mean) in particles {
            *node = self.push_with_mean(*node, pose, mean);
        }
    }

    /// The poses from the root down to `leaf` (empty for [`NO_NODE`]).
    pub fn path(&self, leaf: NodeId) -> Vec<Pose> {
        self.walk(leaf, &self.poses)
    }

    /// The proposal means from the root down to `leaf`, when the tree records them.
    pub fn mean_path(&self, leaf: NodeId) -> Option<Vec<Pose>> {
        self.means.as_ref().map(|m| self.walk(leaf, m))
    }

    /// Weighted means of the ancestors of a weighted particle set, one per lag: element `j` is
    /// the weighted mean (circular heading) of each leaf's pose `j` processed scans before its
    /// own, for `j = 0..=max_lag` and as far back as the paths go. With the current weights
    /// this is the particle approximation of the smoothed mean E[x_{t−j} | z_{1:t}]: lineages
    /// that later died carry no weight. Leaves sharing an ancestor are merged, so a lag where
    /// every path has coalesced costs O(1). `proposal_means` reads the recorded proposal means
    /// instead of the poses (`None` when the tree does not record them).
    ///
    /// `weights` are ≥ 0 and aligned with `leaves`; [`NO_NODE`] leaves and zero weights are
    /// skipped; the result is empty when no leaf has a path and weight.
    pub fn ancestor_means(
        &self,
        leaves: &[NodeId],
        weights: &[f64],
        max_lag: usize,
        proposal_means: bool,
    ) -> Option<Vec<Pose>> {
        let values = if proposal_means {
            self.means.as_deref()?
        } else {
            &self.poses
        };
        let mut level: Vec<(NodeId, f64)> = leaves
            .iter()
            .zip(weights)
            .filter(|&(&n, &w)| n != NO_NODE && w > 0.0)
            .map(|(&n, &w)| (n, w))
            .collect();
        let mut out = Vec::new();
        while !level.is_empty() && out.len() <= max_lag {
            level.sort_unstable_by_key(|&(n, _)| n);
            level.dedup_by(|b, a| {
                let same = a.0 == b.0;
                if same {
                    a.1 += b.1;
                }
                same
            });
            let (mut sw, mut x, mut y, mut s, mut c) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for &(n, w) in &level {
                let p = values[n as usize];
                sw += w;
                x += w * p[0];
                y += w * p[1];
                s += w * p[2].sin();
                c += w * p[2].cos();
            }
            out.push([x / sw, y / sw, s.atan2(c)]);
            level = level
                .into_iter()
                .map(|(n, w)| (self.parents[n as usize], w))
                .filter(|&(n, _)| n != NO_NODE)
                .collect();
        }
        Some(out)
    }

    fn walk(&self, leaf: NodeId, values: &[Pose]) -> Vec<Pose> {
        let mut out = Vec::new();
        let mut node = leaf;
        while node != NO_NODE {
            out.push(values[node as usize]);
            node = self.parents[node as usize];
        }
        out.reverse();
        out
    }

    /// Nodes stored.
    pub fn len(&self) -> usize {
        self.poses.len()
    }

    pub fn is_empty(&self) -> bool {
        self.poses.is_empty()
    }

    /// Bytes held by the nodes.
    pub fn memory_bytes(&self) -> usize {
        self.poses.capacity() * std::mem::size_of::<Pose>()
            + self.parents.capacity() * std::mem::size_of::<NodeId>()
            + self
                .means
                .as_ref()
                .map_or(0, |m| m.capacity() * std::mem::size_of::<Pose>())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn children_share_their_ancestors() {
        let mut t = PathTree::default();
        let root = t.push(NO_NODE, [0.0, 0.0, 0.0]);
        let a = t.push(root, [1.0, 0.0, 0.0]);
        // Two children of `a` (as after resampling duplicated it), then one more step each.
        let b1 = t.push(a, [2.0, 0.0, 0.0]);
        let b2 = t.push(a, [2.0, 1.0, 0.0]);
        let c2 = t.push(b2, [3.0, 1.0, 0.0]);
        assert_eq!(t.path(b1), vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]);
        assert_eq!(
            t.path(c2),
            vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 1.0, 0.0], [3.0, 1.0, 0.0]]
        );
        assert!(t.path(NO_NODE).is_empty());
        assert_eq!(t.len(), 5);
        assert!(!t.records_means());
        assert_eq!(t.mean_path(c2), None);
    }

    #[test]
    fn means_follow_the_same_lineage_as_the_poses() {
        let mut t = PathTree::recording_means();
        let mut nodes = [NO_NODE; 2];
        // Step 1: two particles; step 2: particle 1 is a copy of particle 0 (resampled).
        t.advance(
            nodes
                .iter_mut()
                .enumerate()
                .map(|(i, n)| (n, [i as f64, 0.0, 0.0], [i as f64 + 0.5, 0.0, 0.0])),
        );
        nodes[1] = nodes[0];
        t.advance(
            nodes
                .iter_mut()
                .enumerate()
                .map(|(i, n)| (n, [10.0 + i as f64, 0.0, 0.0], [20.0 + i as f64, 0.0, 0.0])),
        );
        assert_eq!(t.path(nodes[1]), vec![[0.0; 3], [11.0, 0.0, 0.0]]);
        assert_eq!(
            t.mean_path(nodes[1]),
            Some(vec![[0.5, 0.0, 0.0], [21.0, 0.0, 0.0]])
        );
        assert_eq!(t.mean_path(NO_NODE), Some(vec![]));
        // A root pushed without a mean is its own mean.
        let r = t.push(NO_NODE, [7.0, 1.0, 0.0]);
        assert_eq!(t.mean_path(r), Some(vec![[7.0, 1.0, 0.0]]));
    }

    #[test]
    fn ancestor_means_weigh_each_lineage_back_in_time() {
        let mut t = PathTree::recording_means();
        let mut nodes = [NO_NODE; 3];
        // Step 0: three particles at x = 0, 1, 2 (means + 0.5).
        t.advance(
            nodes
                .iter_mut()
                .enumerate()
                .map(|(i, n)| (n, [i as f64, 0.0, 0.0], [i as f64 + 0.5, 0.0, 0.0])),
        );
        // Resampling keeps particle 2 twice and particle 0 once; step 1 moves each by +10.
        nodes = [nodes[0], nodes[2], nodes[2]];
        t.advance(
            nodes
                .iter_mut()
                .enumerate()
                .map(|(i, n)| (n, [10.0 + i as f64, 0.0, 0.0], [10.0 + i as f64, 0.0, 0.0])),
        );
        let w = [0.5, 0.25, 0.25];
        let m = t.ancestor_means(&nodes, &w, 5, false).unwrap();
        assert_eq!(m.len(), 2);
        assert!((m[0][0] - (0.5 * 10.0 + 0.25 * 11.0 + 0.25 * 12.0)).abs() < 1e-12);
        // One step back: particle 0's lineage (x = 0) with 0.5, particle 2's (x = 2) with 0.5;
        // particle 1's lineage died at the resampling and carries nothing.
        assert!((m[1][0] - 1.0).abs() < 1e-12);
        let means = t.ancestor_means(&nodes, &w, 5, true).unwrap();
        assert!((means[1][0] - 1.5).abs() < 1e-12);
        assert_eq!(t.ancestor_means(&nodes, &w, 0, false).unwrap().len(), 1);
        assert!(t
            .ancestor_means(&[NO_NODE], &[1.0], 3, false)
            .unwrap()
            .is_empty());
        assert!(PathTree::default()
            .ancestor_means(&[], &[], 3, true)
            .is_none());
    }
}
