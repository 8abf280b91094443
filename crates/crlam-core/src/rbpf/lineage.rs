//! Each particle's path: its pose at every processed scan, through resampling.
//!
//! The paths form a tree. Node i holds one pose and the node of the same lineage one processed
//! scan earlier, so resampled children share every ancestor with their parent and a step costs
//! one node per particle (28 bytes), whatever the path length. The path of the final best
//! particle is the trajectory GMapping reports: a pose sequence that one map explains, unlike the
//! per-step weighted mean, which can average poses of lineages that later died.

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
}

impl PathTree {
    /// Adds `pose` as the child of `parent` ([`NO_NODE`] for a root) and returns its node.
    ///
    /// # Panics
    /// Never for real runs: 2^32 − 1 nodes would need, e.g., 1,000 particles over 4 million
    /// processed scans; reaching it is a logic error, not bad input.
    pub fn push(&mut self, parent: NodeId, pose: Pose) -> NodeId {
        let id = NodeId::try_from(self.poses.len()).expect("path tree is full");
        assert!(id != NO_NODE, "path tree is full");
        debug_assert!(parent == NO_NODE || parent < id);
        self.poses.push(pose);
        self.parents.push(parent);
        id
    }

    /// Appends each particle's current pose to its path: call once per processed scan, after the
    /// proposals and before resampling, so that children inherit the pose their parent was
    /// weighed at.
    pub fn advance<'a>(&mut self, particles: impl Iterator<Item = (&'a mut NodeId, Pose)>) {
        for (node, pose) in particles {
            *node = self.push(*node, pose);
        }
    }

    /// The poses from the root down to `leaf` (empty for [`NO_NODE`]).
    pub fn path(&self, leaf: NodeId) -> Vec<Pose> {
        let mut out = Vec::new();
        let mut node = leaf;
        while node != NO_NODE {
            out.push(self.poses[node as usize]);
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
    }
}
