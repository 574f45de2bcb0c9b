//! Particle paths as one shared tree of poses (the path posterior of a particle filter).
//!
//! A particle filter over paths (FastSLAM, grid FastSLAM: Probabilistic Robotics §13.3,
//! "each particle is a hypothesis of the whole path x_{0:t}") must keep every particle's
//! path without copying it. Each particle holds an [`Arc`] to the [`PathNode`] of its latest
//! pose; a node points at its parent. Extending a path is one allocation (O(1) per particle
//! per step); resampling copies a pointer, so copies of a particle share their ancestry; a
//! branch whose last particle died is freed as soon as nothing points at it (reference
//! counting, with an iterative [`Drop`] so that freeing a long dead chain cannot overflow
//! the stack). Live memory is O(M + shared history): the common trunk once, plus the
//! branches since the particles' last common ancestor.
//!
//! [`ParticlePaths`] is the same tree flattened into plain data (nodes in an array, parents
//! as indices) for pictures and files.

use crate::Pose2;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::sync::Arc;

/// One pose in the tree: the pose a particle had at step `index` (the meaning of a step is
/// the filter's: an update call for FastSLAM, a processed scan for grid FastSLAM).
pub struct PathNode {
    pose: Pose2,
    index: usize,
    parent: Option<Arc<PathNode>>,
}

impl PathNode {
    /// A new leaf below `parent` (`None` for a root).
    pub fn child(parent: Option<Arc<PathNode>>, pose: Pose2, index: usize) -> Arc<PathNode> {
        Arc::new(PathNode {
            pose,
            index,
            parent,
        })
    }

    /// The pose at this node.
    pub fn pose(&self) -> Pose2 {
        self.pose
    }

    /// The step index given at creation.
    pub fn index(&self) -> usize {
        self.index
    }

    /// The parent node (`None` at a root).
    pub fn parent(&self) -> Option<&Arc<PathNode>> {
        self.parent.as_ref()
    }

    /// The poses from the root to this node, root first. O(depth), iterative.
    pub fn path(self: &Arc<PathNode>) -> Vec<Pose2> {
        let mut out = Vec::with_capacity(self.index + 1);
        let mut cur = Some(self);
        while let Some(n) = cur {
            out.push(n.pose);
            cur = n.parent.as_ref();
        }
        out.reverse();
        out
    }
}

impl std::fmt::Debug for PathNode {
    /// The node and its parent's step, not the whole chain: a derived `Debug` would print
    /// (and recurse through) every ancestor.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PathNode")
            .field("pose", &self.pose)
            .field("index", &self.index)
            .field("parent_index", &self.parent.as_ref().map(|p| p.index))
            .finish()
    }
}

impl Drop for PathNode {
    /// Frees a dead chain iteratively: the default recursive drop of a long `Arc` chain
    /// would overflow the stack after a few hundred thousand nodes. Stops at the first
    /// ancestor still shared with a living path.
    fn drop(&mut self) {
        let mut next = self.parent.take();
        while let Some(arc) = next {
            match Arc::try_unwrap(arc) {
                Ok(mut node) => next = node.parent.take(),
                Err(_) => break,
            }
        }
    }
}

/// One node of a flattened [`ParticlePaths`] tree.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PathTreeNode {
    /// The pose (world frame, metres, radians).
    pub pose: Pose2,
    /// The step index (as [`PathNode::index`]).
    pub step: usize,
    /// Index of the parent in [`ParticlePaths::nodes`]; `None` at the root. Always smaller
    /// than this node's own index.
    pub parent: Option<usize>,
}

/// Every particle's path as plain data: the distinct nodes of the shared tree, each stored
/// once, parents before children. A particle's path is the chain from its leaf up to the
/// root; drawing every node's edge to its parent draws every particle's path, with the
/// shared history drawn once. Size O(distinct nodes), not O(particles × steps).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ParticlePaths {
    /// The distinct nodes, sorted by step (so a parent comes before its children).
    pub nodes: Vec<PathTreeNode>,
    /// For each particle, in particle order, the index in `nodes` of its latest pose.
    pub leaves: Vec<usize>,
    /// For each particle, its normalised weight in [0, 1].
    pub weights: Vec<f64>,
    /// The particle whose path is the filter's estimate (the highest weight).
    pub best: usize,
}

impl ParticlePaths {
    /// Flattens the trees below `leaves` (one leaf per particle; leaves may share nodes).
    /// `weights` and `best` are stored as given. O(distinct nodes · log).
    pub fn from_leaves(leaves: &[&Arc<PathNode>], weights: Vec<f64>, best: usize) -> Self {
        // Pass 1: every distinct node once, climbing from each leaf until a node already
        // seen (the rest of that chain is then known).
        let mut seen: HashMap<*const PathNode, usize> = HashMap::new();
        let mut order: Vec<&PathNode> = Vec::new();
        for leaf in leaves {
            let mut cur: Option<&PathNode> = Some(&***leaf);
            while let Some(n) = cur {
                let key = n as *const PathNode;
                if seen.contains_key(&key) {
                    break;
                }
                seen.insert(key, order.len());
                order.push(n);
                cur = n.parent.as_deref();
            }
        }
        // Pass 2: sort by step (ties in discovery order) and link parents by index.
        let mut rank: Vec<usize> = (0..order.len()).collect();
        rank.sort_by_key(|&i| (order[i].index, i));
        let mut position = vec![0; order.len()];
        for (pos, &i) in rank.iter().enumerate() {
            position[i] = pos;
        }
        let nodes = rank
            .iter()
            .map(|&i| {
                let n = order[i];
                PathTreeNode {
                    pose: n.pose,
                    step: n.index,
                    parent: n
                        .parent
                        .as_deref()
                        .map(|p| position[seen[&(p as *const PathNode)]]),
                }
            })
            .collect();
        let leaves = leaves
            .iter()
            .map(|l| position[seen[&Arc::as_ptr(l)]])
            .collect();
        Self {
            nodes,
            leaves,
            weights,
            best,
        }
    }

    /// The path ending at node `leaf`, root first; empty when `leaf` is out of range.
    pub fn path_to(&self, leaf: usize) -> Vec<Pose2> {
        let mut out = Vec::new();
        let mut cur = (leaf < self.nodes.len()).then_some(leaf);
        while let Some(i) = cur {
            out.push(self.nodes[i].pose);
            // Parents have smaller indices (construction), so this terminates.
            cur = self.nodes[i].parent.filter(|&p| p < i);
        }
        out.reverse();
        out
    }

    /// Particle `k`'s path, root first; empty when `k` is out of range.
    pub fn path_of(&self, k: usize) -> Vec<Pose2> {
        self.leaves
            .get(k)
            .map_or_else(Vec::new, |&leaf| self.path_to(leaf))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shared_ancestors_and_freed_branches() {
        let root = PathNode::child(None, Pose2::new(0.0, 0.0, 0.0), 0);
        let a = PathNode::child(Some(root.clone()), Pose2::new(1.0, 0.0, 0.0), 1);
        let b = PathNode::child(Some(root.clone()), Pose2::new(0.0, 1.0, 0.0), 1);
        assert_eq!(Arc::strong_count(&root), 3);
        assert_eq!(a.path().len(), 2);
        assert_eq!(b.path()[1], Pose2::new(0.0, 1.0, 0.0));
        let weak_b = Arc::downgrade(&b);
        drop(b);
        assert!(weak_b.upgrade().is_none());
        assert_eq!(Arc::strong_count(&root), 2);
    }

    /// Dropping the last leaf of a dead branch frees the whole branch up to the first
    /// shared ancestor, and nothing above it.
    #[test]
    fn a_dead_branch_is_freed_up_to_the_fork() {
        let root = PathNode::child(None, Pose2::IDENTITY, 0);
        let fork = PathNode::child(Some(root.clone()), Pose2::new(1.0, 0.0, 0.0), 1);
        let keep = PathNode::child(Some(fork.clone()), Pose2::new(2.0, 0.0, 0.0), 2);
        let mut dead = PathNode::child(Some(fork.clone()), Pose2::new(2.0, 1.0, 0.0), 2);
        let mut weak = vec![Arc::downgrade(&dead)];
        for k in 3..50 {
            dead = PathNode::child(Some(dead), Pose2::new(k as f64, 1.0, 0.0), k);
            weak.push(Arc::downgrade(&dead));
        }
        drop((root, fork));
        drop(dead);
        assert!(weak.iter().all(|w| w.upgrade().is_none()));
        assert_eq!(keep.path().len(), 3);
        assert_eq!(Arc::strong_count(keep.parent().unwrap()), 1);
    }

    #[test]
    fn a_long_chain_drops_without_overflowing_the_stack() {
        let mut n = PathNode::child(None, Pose2::IDENTITY, 0);
        for k in 1..1_000_000 {
            n = PathNode::child(Some(n), Pose2::IDENTITY, k);
        }
        assert_eq!(n.path().len(), 1_000_000);
        drop(n);
    }

    /// Flattening keeps each shared node once, puts parents first, and every particle's
    /// path read back from the flat form equals the one read from its node.
    #[test]
    fn flattened_paths_equal_the_node_paths() {
        let p = |x: f64, y: f64| Pose2::new(x, y, 0.0);
        let root = PathNode::child(None, p(0.0, 0.0), 0);
        let a1 = PathNode::child(Some(root.clone()), p(1.0, 0.0), 1);
        let b1 = PathNode::child(Some(root.clone()), p(1.0, 1.0), 1);
        let a2 = PathNode::child(Some(a1.clone()), p(2.0, 0.0), 2);
        let a2b = PathNode::child(Some(a1.clone()), p(2.0, -1.0), 2);
        let b2 = PathNode::child(Some(b1.clone()), p(2.0, 1.0), 2);
        // Four particles, two of them copies of one (after resampling).
        let leaves = [&b2, &a2, &a2b, &a2];
        let flat = ParticlePaths::from_leaves(&leaves, vec![0.1, 0.4, 0.1, 0.4], 1);
        assert_eq!(flat.nodes.len(), 6);
        for (i, n) in flat.nodes.iter().enumerate() {
            assert!(n.parent.is_none_or(|q| q < i));
            assert_eq!(n.parent.is_none(), n.step == 0);
        }
        for (k, leaf) in leaves.iter().enumerate() {
            assert_eq!(flat.path_of(k), leaf.path());
        }
        assert_eq!(flat.leaves[1], flat.leaves[3]);
        assert!(flat.path_of(4).is_empty());
    }
}
