//! Particle trajectories as one shared tree of poses.
//!
//! Each particle points at the node of its latest corrected pose; a node points at its
//! parent. After resampling, copies of a particle share its node, so common ancestry is
//! stored once; a branch whose last particle died is freed as soon as nothing points at
//! it (reference counting). Memory is therefore O(M · depth since the last coalescence)
//! rather than O(M · T).

use slam_models::Pose2;
use std::sync::Arc;

/// One corrected pose in the tree: the pose a particle had at processed scan `scan`.
#[derive(Debug)]
pub(crate) struct Node {
    pub pose: Pose2,
    pub scan: usize,
    pub parent: Option<Arc<Node>>,
}

impl Node {
    /// A new leaf below `parent`.
    pub fn child(parent: Option<Arc<Node>>, pose: Pose2, scan: usize) -> Arc<Node> {
        Arc::new(Node { pose, scan, parent })
    }

    /// The poses from the root to this node, in scan order.
    pub fn path(self: &Arc<Node>) -> Vec<Pose2> {
        let mut out = Vec::with_capacity(self.scan + 1);
        let mut cur = Some(self);
        while let Some(n) = cur {
            out.push(n.pose);
            cur = n.parent.as_ref();
        }
        out.reverse();
        out
    }
}

impl Drop for Node {
    /// Frees a dead chain iteratively: the default recursive drop of a long `Arc` chain
    /// would overflow the stack after a few hundred thousand nodes.
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shared_ancestors_and_freed_branches() {
        let root = Node::child(None, Pose2::new(0.0, 0.0, 0.0), 0);
        let a = Node::child(Some(root.clone()), Pose2::new(1.0, 0.0, 0.0), 1);
        let b = Node::child(Some(root.clone()), Pose2::new(0.0, 1.0, 0.0), 1);
        assert_eq!(Arc::strong_count(&root), 3);
        assert_eq!(a.path().len(), 2);
        assert_eq!(b.path()[1], Pose2::new(0.0, 1.0, 0.0));
        let weak_b = Arc::downgrade(&b);
        drop(b);
        assert!(weak_b.upgrade().is_none());
        assert_eq!(Arc::strong_count(&root), 2);
    }

    #[test]
    fn a_long_chain_drops_without_overflowing_the_stack() {
        let mut n = Node::child(None, Pose2::IDENTITY, 0);
        for k in 1..1_000_000 {
            n = Node::child(Some(n), Pose2::IDENTITY, k);
        }
        assert_eq!(n.path().len(), 1_000_000);
        drop(n);
    }
}
