//! Most-informative-path extraction (planner-spec 3.8), on any tree given as a parent list:
//! node 0 is the root (`None`), every other node's parent has a smaller index, and children are
//! taken in index order (= edge-insertion order for a planner tree).

use crate::error::{config_err, CrlamError, Result};

/// Fraction of the longest path length a candidate path must exceed (in nodes, rounded up).
pub const MIN_LENGTH_FRACTION: f64 = 0.4;
/// Two paths overlap when more than this fraction of the shorter one's positions agree.
pub const OVERLAP_FRACTION: f64 = 0.6;

/// Children of every node in index order, after checking the parent list.
pub fn children_lists(parents: &[Option<usize>]) -> Result<Vec<Vec<usize>>> {
    if parents.is_empty() {
        return Err(config_err("parents", "the tree needs a root"));
    }
    if parents[0].is_some() {
        return Err(config_err(
            "parents",
            "node 0 (the root) must have no parent",
        ));
    }
    let mut children = vec![Vec::new(); parents.len()];
    for (i, p) in parents.iter().enumerate().skip(1) {
        match *p {
            Some(p) if p < i => children[p].push(i),
            _ => {
                return Err(CrlamError::Shape(format!(
                    "node {i} has parent {p:?}; every non-root node needs a parent with a \
                     smaller index"
                )))
            }
        }
    }
    Ok(children)
}

/// The leaves in the reference's depth-first order: at a node, descend into its first child and
/// push the others in order; at a leaf, pop the most recently pushed node.
pub fn dfs_leaves(parents: &[Option<usize>]) -> Result<Vec<usize>> {
    let children = children_lists(parents)?;
    let mut leaves = Vec::new();
    let mut stack: Vec<usize> = Vec::new();
    let mut node = 0;
    loop {
        match children[node].split_first() {
            Some((&first, rest)) => {
                stack.extend_from_slice(rest);
                node = first;
            }
            None => {
                leaves.push(node);
                match stack.pop() {
                    Some(next) => node = next,
                    None => return Ok(leaves),
                }
            }
        }
    }
}

/// The node sequence root → `node`. `parents` must be a valid list (see [`children_lists`]).
pub fn root_path(parents: &[Option<usize>], node: usize) -> Vec<usize> {
    let mut path = vec![node];
    let mut v = node;
    while let Some(p) = parents[v] {
        path.push(p);
        v = p;
    }
    path.reverse();
    path
}

/// The votes of planner-spec 3.8 step 4 over `paths` (root-first node sequences). For each pair
/// i < j with m = min(l_i, l_j) and s = the number of positions t < m where they agree: if
/// s/m > 0.6, the longer gets +1 and the shorter −1 (on equal lengths j gets +1, i −1);
/// otherwise both get +1.
pub fn vote_paths(paths: &[Vec<usize>]) -> Vec<i64> {
    let mut votes = vec![0i64; paths.len()];
    for i in 0..paths.len() {
        for j in i + 1..paths.len() {
            let (a, b) = (&paths[i], &paths[j]);
            let m = a.len().min(b.len());
            let s = a.iter().zip(b).take(m).filter(|(x, y)| x == y).count();
            if m > 0 && s as f64 / m as f64 > OVERLAP_FRACTION {
                let (winner, loser) = if a.len() > b.len() { (i, j) } else { (j, i) };
                votes[winner] += 1;
                votes[loser] -= 1;
            } else {
                votes[i] += 1;
                votes[j] += 1;
            }
        }
    }
    votes
}

/// The candidate paths (steps 1–3): root → leaf for every leaf in [`dfs_leaves`] order, kept when
/// their node count exceeds ⌈0.4 · l_max⌉.
pub fn candidate_paths(parents: &[Option<usize>]) -> Result<Vec<Vec<usize>>> {
    let all: Vec<Vec<usize>> = dfs_leaves(parents)?
        .into_iter()
        .map(|leaf| root_path(parents, leaf))
        .collect();
    let l_max = all.iter().map(Vec::len).max().unwrap_or(0);
    let min_len = (MIN_LENGTH_FRACTION * l_max as f64).ceil() as usize;
    Ok(all.into_iter().filter(|p| p.len() > min_len).collect())
}

/// The main paths (step 5): the candidate paths with the maximal vote, in leaf order. A tree
/// that is only its root (no path exceeds ⌈0.4⌉ = 1 node) gives the single path `[0]`.
pub fn main_paths(parents: &[Option<usize>]) -> Result<Vec<Vec<usize>>> {
    let kept = candidate_paths(parents)?;
    let votes = vote_paths(&kept);
    let Some(&best) = votes.iter().max() else {
        return Ok(vec![vec![0]]);
    };
    Ok(kept
        .into_iter()
        .zip(votes)
        .filter(|&(_, v)| v == best)
        .map(|(p, _)| p)
        .collect())
}

/// Σ ΔI over a root-first path, the root (first node) contributing 0. `gains[v]` is node v's ΔI.
pub fn path_gain(path: &[usize], gains: &[f64]) -> f64 {
    path.iter().skip(1).map(|&v| gains[v]).sum()
}

/// The most informative path (step 6): the path with the largest [`path_gain`], the first one on
/// ties (strict >). Errors on no paths or a node index beyond `gains`.
pub fn max_info_path(paths: &[Vec<usize>], gains: &[f64]) -> Result<Vec<usize>> {
    if let Some(&v) = paths.iter().flatten().find(|&&v| v >= gains.len()) {
        return Err(CrlamError::OutOfBounds(format!(
            "node {v} of {} gains",
            gains.len()
        )));
    }
    let mut best: Option<(&Vec<usize>, f64)> = None;
    for p in paths {
        let g = path_gain(p, gains);
        let better = match best {
            None => true,
            Some((_, bg)) => g > bg,
        };
        if better {
            best = Some((p, g));
        }
    }
    best.map(|(p, _)| p.clone())
        .ok_or_else(|| config_err("paths", "no path to choose from"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dfs_pops_the_most_recent_sibling() {
        // 0 → {1, 2, 3}; 1 → {4, 5}. Descend 0→1→4 (push 2, 3 then 5), pop 5, pop 3, pop 2.
        let parents = [None, Some(0), Some(0), Some(0), Some(1), Some(1)];
        assert_eq!(dfs_leaves(&parents).unwrap(), vec![4, 5, 3, 2]);
        assert_eq!(dfs_leaves(&[None]).unwrap(), vec![0]);
        assert_eq!(main_paths(&[None]).unwrap(), vec![vec![0]]);
        assert!(dfs_leaves(&[None, Some(1)]).is_err());
        assert!(dfs_leaves(&[Some(0)]).is_err());
        assert!(dfs_leaves(&[]).is_err());
    }

    #[test]
    fn max_info_path_prefers_the_first_on_ties() {
        let paths = vec![vec![0, 1], vec![0, 2], vec![0, 3]];
        let gains = [100.0, 1.0, 2.0, 2.0];
        assert_eq!(max_info_path(&paths, &gains).unwrap(), vec![0, 2]);
        assert!(max_info_path(&[], &gains).is_err());
        assert!(max_info_path(&[vec![0, 9]], &gains).is_err());
    }

    /// Hand-made 3-branch tree. Parents (index: parent): 1:0 2:1 3:2 4:3 5:3 6:0 7:6 8:7 9:0 10:2.
    ///
    /// Children: 0 → [1, 6, 9], 2 → [3, 10], 3 → [4, 5], 6 → [7], 7 → [8].
    /// DFS: 0 pushes 6, 9 and descends to 1 → 2 (pushes 10) → 3 (pushes 5) → 4 (leaf); pop 5
    /// (leaf), pop 10 (leaf), pop 9 (leaf), pop 6 → 7 → 8 (leaf). Leaves: 4, 5, 10, 9, 8.
    /// Paths: P4 = 0-1-2-3-4 (l 5), P5 = 0-1-2-3-5 (5), P10 = 0-1-2-10 (4), P9 = 0-9 (2),
    /// P8 = 0-6-7-8 (4). l_max = 5, ⌈0.4·5⌉ = 2: P9 is dropped; kept [P4, P5, P10, P8].
    /// Votes (i, j): (P4, P5) s/m = 4/5 overlap, equal lengths: P5 +1, P4 −1 → [−1, 1, 0, 0];
    /// (P4, P10) 3/4 overlap, P4 longer → [0, 1, −1, 0]; (P4, P8) 1/4 → both +1 → [1, 1, −1, 1];
    /// (P5, P10) 3/4, P5 longer → [1, 2, −2, 1]; (P5, P8) 1/4 → [1, 3, −2, 2];
    /// (P10, P8) 1/4 → [1, 3, −1, 3]. Main paths (vote 3, leaf order): P5, P8.
    #[test]
    fn path_extraction_on_a_three_branch_tree() {
        let parents = [
            None,
            Some(0),
            Some(1),
            Some(2),
            Some(3),
            Some(3),
            Some(0),
            Some(6),
            Some(7),
            Some(0),
            Some(2),
        ];
        assert_eq!(dfs_leaves(&parents).unwrap(), vec![4, 5, 10, 9, 8]);
        let kept = candidate_paths(&parents).unwrap();
        assert_eq!(
            kept,
            vec![
                vec![0, 1, 2, 3, 4],
                vec![0, 1, 2, 3, 5],
                vec![0, 1, 2, 10],
                vec![0, 6, 7, 8]
            ]
        );
        assert_eq!(vote_paths(&kept), vec![1, 3, -1, 3]);
        let main = main_paths(&parents).unwrap();
        assert_eq!(main, vec![vec![0, 1, 2, 3, 5], vec![0, 6, 7, 8]]);
        // Σ ΔI: P5 = 1 + 1 + 1 + 0.5 = 3.5, P8 = 1 + 1.5 + 1 = 3.5: the tie goes to the first (P5).
        // The root's 100 and P4's large gain (P4 is not a main path) do not count.
        let mut gains = [100.0, 1.0, 1.0, 1.0, 10.0, 0.5, 1.0, 1.5, 1.0, 50.0, 7.0];
        assert_eq!(max_info_path(&main, &gains).unwrap(), vec![0, 1, 2, 3, 5]);
        gains[8] = 1.25;
        assert_eq!(max_info_path(&main, &gains).unwrap(), vec![0, 6, 7, 8]);
        // s/m = 3/5 = 0.6 is not an overlap (strict >): both +1.
        assert_eq!(
            vote_paths(&[vec![0, 1, 2, 3, 4], vec![0, 1, 2, 5, 6]]),
            vec![1, 1]
        );
    }
}
