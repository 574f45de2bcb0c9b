//! A persistent map from `u32` keys to values: a balanced 16-ary radix tree whose nodes are
//! shared between copies through [`Arc`].
//!
//! This is the landmark store of FastSLAM (Montemerlo et al., AAAI 2002, §4 "Efficient
//! implementation"): every particle owns a map, resampling duplicates particles, and a
//! duplicate must not copy N landmarks. Here
//!
//! * [`Clone`] copies one pointer (the root) and bumps one reference count: O(1);
//! * a write ([`PersistentMap::insert`], [`PersistentMap::get_mut`],
//!   [`PersistentMap::remove`]) copies only the nodes on the path from the root to the
//!   changed leaf that are still shared with another copy ([`Arc::make_mut`]), and writes in
//!   place where this copy is the sole owner: O(log₁₆ K) nodes for the largest key K;
//! * a read walks the same path without copying: O(log₁₆ K).
//!
//! All leaves sit at the same depth, so the tree is balanced by construction; when keys are
//! handed out densely (0, 1, 2, …, as FastSLAM does for new landmarks) the depth is
//! ⌈log₁₆ N⌉ for N landmarks: 3 levels for 500–4,096 landmarks, 4 up to 65,536.
//! The root grows by one level when a key beyond the current capacity arrives.
//!
//! Values live in their own `Arc` (one allocation per value), so copying an inner node on a
//! write path costs 16 pointer copies whatever the size of `T`.

use std::sync::Arc;

/// log₂ of the branching factor.
const BITS: u32 = 4;
/// Branching factor: children per inner node.
const FANOUT: usize = 1 << BITS;
/// Mask selecting one level's digit of a key.
const MASK: u64 = (FANOUT as u64) - 1;
/// Depth at which every `u32` key fits (16⁸ = 2³²).
const MAX_DEPTH: u32 = 32 / BITS;

/// A child slot: an inner node one level down, or a value at the bottom level.
enum Link<T> {
    Node(Arc<Inner<T>>),
    Value(Arc<T>),
}

impl<T> Clone for Link<T> {
    fn clone(&self) -> Self {
        match self {
            Link::Node(n) => Link::Node(Arc::clone(n)),
            Link::Value(v) => Link::Value(Arc::clone(v)),
        }
    }
}

/// An inner node: `FANOUT` optional children and how many are present.
struct Inner<T> {
    kids: [Option<Link<T>>; FANOUT],
    count: u8,
}

impl<T> Clone for Inner<T> {
    /// Shallow: clones the 16 child pointers, never a value.
    fn clone(&self) -> Self {
        Self {
            kids: self.kids.clone(),
            count: self.count,
        }
    }
}

impl<T> Inner<T> {
    fn empty() -> Self {
        Self {
            kids: Default::default(),
            count: 0,
        }
    }
}

/// A persistent (copy-on-write, structurally shared) map `u32 → T`, iterated in key order.
///
/// ```
/// use slam_fastslam::tree::PersistentMap;
/// let mut a = PersistentMap::new();
/// a.insert(3, "three");
/// let mut b = a.clone();          // O(1): shares every node with `a`
/// b.insert(3, "drei");            // copies only b's path to key 3
/// assert_eq!(a.get(3), Some(&"three"));
/// assert_eq!(b.get(3), Some(&"drei"));
/// ```
pub struct PersistentMap<T> {
    root: Option<Arc<Inner<T>>>,
    /// Levels of inner nodes; keys below 16^depth fit.
    depth: u32,
    len: usize,
}

impl<T> Clone for PersistentMap<T> {
    /// O(1): the copy shares every node.
    fn clone(&self) -> Self {
        Self {
            root: self.root.clone(),
            depth: self.depth,
            len: self.len,
        }
    }
}

impl<T> Default for PersistentMap<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: std::fmt::Debug> std::fmt::Debug for PersistentMap<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_map().entries(self.iter()).finish()
    }
}

/// Index of `key`'s child at inner level `level` (0 = root) of a tree `depth` levels deep.
#[inline]
fn digit(key: u32, level: u32, depth: u32) -> usize {
    ((key as u64 >> (BITS * (depth - 1 - level))) & MASK) as usize
}

/// Smallest depth whose capacity 16^depth exceeds `key`.
#[inline]
fn depth_for(key: u32) -> u32 {
    let mut d = 1;
    while d < MAX_DEPTH && (key as u64) >> (BITS * d) != 0 {
        d += 1;
    }
    d
}

impl<T> PersistentMap<T> {
    /// An empty map.
    pub fn new() -> Self {
        Self {
            root: None,
            depth: 0,
            len: 0,
        }
    }

    /// Number of entries.
    #[inline]
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when the map holds no entry.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Levels of inner nodes between the root and the values (0 for an empty map).
    #[inline]
    pub fn depth(&self) -> u32 {
        self.depth
    }

    /// The value under `key`, without copying anything: O(depth).
    pub fn get(&self, key: u32) -> Option<&T> {
        let mut node: &Inner<T> = self.root.as_deref()?;
        if self.depth < MAX_DEPTH && (key as u64) >> (BITS * self.depth) != 0 {
            return None;
        }
        for level in 0..self.depth {
            match node.kids[digit(key, level, self.depth)].as_ref()? {
                Link::Node(n) => node = n,
                Link::Value(v) => return Some(v),
            }
        }
        None
    }

    /// True when `key` is present.
    #[inline]
    pub fn contains_key(&self, key: u32) -> bool {
        self.get(key).is_some()
    }

    /// Adds levels above the root until `key` fits.
    fn grow_to(&mut self, key: u32) {
        let need = depth_for(key);
        if self.root.is_none() {
            self.root = Some(Arc::new(Inner::empty()));
            self.depth = need;
            return;
        }
        while self.depth < need {
            let mut top = Inner::empty();
            top.kids[0] = self.root.take().map(Link::Node);
            top.count = 1;
            self.root = Some(Arc::new(top));
            self.depth += 1;
        }
    }

    /// Inserts or replaces the value under `key`, returning the previous value's shared
    /// handle. Copies the shared part of the path to `key`, nothing else.
    pub fn insert(&mut self, key: u32, value: T) -> Option<Arc<T>> {
        self.grow_to(key);
        let depth = self.depth;
        let mut node = Arc::make_mut(self.root.as_mut()?);
        for level in 0..depth {
            let i = digit(key, level, depth);
            if level + 1 == depth {
                let old = node.kids[i].replace(Link::Value(Arc::new(value)));
                return match old {
                    Some(Link::Value(v)) => Some(v),
                    _ => {
                        node.count += 1;
                        self.len += 1;
                        None
                    }
                };
            }
            if node.kids[i].is_none() {
                node.kids[i] = Some(Link::Node(Arc::new(Inner::empty())));
                node.count += 1;
            }
            node = match node.kids[i].as_mut() {
                Some(Link::Node(n)) => Arc::make_mut(n),
                // Only the bottom level holds values, handled above.
                _ => return None,
            };
        }
        None
    }

    /// Removes `key`, returning its value's shared handle; empty nodes on the path are
    /// pruned. Copies the shared part of the path only when `key` is present.
    pub fn remove(&mut self, key: u32) -> Option<Arc<T>> {
        if !self.contains_key(key) {
            return None;
        }
        let depth = self.depth;
        let root = self.root.as_mut()?;
        let (old, now_empty) = remove_rec(root, key, 0, depth);
        if old.is_some() {
            self.len -= 1;
        }
        if now_empty {
            self.root = None;
            self.depth = 0;
        }
        old
    }

    /// Iterates `(key, &value)` in ascending key order.
    pub fn iter(&self) -> Iter<'_, T> {
        let mut stack = Vec::with_capacity(self.depth as usize + 1);
        if let Some(r) = self.root.as_deref() {
            stack.push((r, 0usize, 0u32, 0u32));
        }
        Iter {
            stack,
            depth: self.depth,
        }
    }

    /// Number of nodes (inner nodes and values) reachable from `self` that are not shared
    /// with `other`, i.e. what a write to `self` has copied since the two were equal.
    /// O(size of the difference · 16) — a diagnostic for tests and benches.
    pub fn unshared_nodes(&self, other: &Self) -> usize {
        match (&self.root, &other.root) {
            (Some(a), Some(b)) if self.depth == other.depth => unshared_rec(a, Some(b)),
            (Some(a), _) => unshared_rec(a, None),
            (None, _) => 0,
        }
    }

    /// True when both maps share the very same root node (as right after a clone).
    pub fn ptr_eq(&self, other: &Self) -> bool {
        match (&self.root, &other.root) {
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            (None, None) => true,
            _ => false,
        }
    }
}

impl<T: Clone> PersistentMap<T> {
    /// A mutable reference to the value under `key`, or `None` when absent (then nothing is
    /// copied). Copies the shared part of the path and the value itself if shared.
    pub fn get_mut(&mut self, key: u32) -> Option<&mut T> {
        if !self.contains_key(key) {
            return None;
        }
        let depth = self.depth;
        let mut node = Arc::make_mut(self.root.as_mut()?);
        for level in 0..depth {
            let i = digit(key, level, depth);
            match node.kids[i].as_mut()? {
                Link::Node(n) => node = Arc::make_mut(n),
                Link::Value(v) => return Some(Arc::make_mut(v)),
            }
        }
        None
    }
}

fn remove_rec<T>(
    node: &mut Arc<Inner<T>>,
    key: u32,
    level: u32,
    depth: u32,
) -> (Option<Arc<T>>, bool) {
    let i = digit(key, level, depth);
    let n = Arc::make_mut(node);
    let old = match n.kids[i].as_mut() {
        None => return (None, false),
        Some(Link::Value(_)) => match n.kids[i].take() {
            Some(Link::Value(v)) => Some(v),
            _ => None,
        },
        Some(Link::Node(child)) => {
            let (old, child_empty) = remove_rec(child, key, level + 1, depth);
            if child_empty {
                n.kids[i] = None;
            }
            if n.kids[i].is_some() {
                return (old, false);
            }
            old
        }
    };
    n.count -= 1;
    (old, n.count == 0)
}

fn unshared_rec<T>(a: &Arc<Inner<T>>, b: Option<&Arc<Inner<T>>>) -> usize {
    if let Some(b) = b {
        if Arc::ptr_eq(a, b) {
            return 0;
        }
    }
    let mut n = 1;
    for (k, kid) in a.kids.iter().enumerate() {
        let other = b.and_then(|b| b.kids[k].as_ref());
        match (kid, other) {
            (Some(Link::Node(x)), Some(Link::Node(y))) => n += unshared_rec(x, Some(y)),
            (Some(Link::Node(x)), _) => n += unshared_rec(x, None),
            (Some(Link::Value(x)), Some(Link::Value(y))) if Arc::ptr_eq(x, y) => {}
            (Some(Link::Value(_)), _) => n += 1,
            (None, _) => {}
        }
    }
    n
}

/// In-order iterator over a [`PersistentMap`].
pub struct Iter<'a, T> {
    /// (node, next child index, key prefix of the node, level of the node).
    stack: Vec<(&'a Inner<T>, usize, u32, u32)>,
    depth: u32,
}

impl<'a, T> Iterator for Iter<'a, T> {
    type Item = (u32, &'a T);

    fn next(&mut self) -> Option<Self::Item> {
        while let Some(top) = self.stack.last_mut() {
            let (node, next, prefix, level) = (top.0, top.1, top.2, top.3);
            if next >= FANOUT {
                self.stack.pop();
                continue;
            }
            top.1 += 1;
            // The key bits below this level are filled in one digit per level.
            let key = ((prefix as u64) << BITS | next as u64) as u32;
            match node.kids[next].as_ref() {
                None => {}
                Some(Link::Value(v)) => return Some((key, v)),
                Some(Link::Node(n)) if level + 1 < self.depth => {
                    self.stack.push((n, 0, key, level + 1));
                }
                Some(Link::Node(_)) => {}
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::collections::BTreeMap;

    #[derive(Debug, Clone)]
    enum Op {
        Insert(u32, i64),
        Remove(u32),
        Bump(u32),
    }

    fn op() -> impl Strategy<Value = Op> {
        // Mostly small keys (dense, as FastSLAM hands them out) and some huge ones.
        let key = prop_oneof![0u32..300, any::<u32>()];
        prop_oneof![
            (key.clone(), any::<i64>()).prop_map(|(k, v)| Op::Insert(k, v)),
            key.clone().prop_map(Op::Remove),
            key.prop_map(Op::Bump),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        /// The map behaves exactly like a BTreeMap under any sequence of operations.
        #[test]
        fn agrees_with_btreemap(ops in prop::collection::vec(op(), 0..200)) {
            let mut m = PersistentMap::new();
            let mut r = BTreeMap::new();
            for o in ops {
                match o {
                    Op::Insert(k, v) => {
                        prop_assert_eq!(m.insert(k, v).map(|a| *a), r.insert(k, v));
                    }
                    Op::Remove(k) => prop_assert_eq!(m.remove(k).map(|a| *a), r.remove(&k)),
                    Op::Bump(k) => {
                        let a = m.get_mut(k).map(|v| { *v = v.wrapping_add(1); *v });
                        let b = r.get_mut(&k).map(|v| { *v = v.wrapping_add(1); *v });
                        prop_assert_eq!(a, b);
                    }
                }
                prop_assert_eq!(m.len(), r.len());
            }
            let got: Vec<(u32, i64)> = m.iter().map(|(k, v)| (k, *v)).collect();
            let want: Vec<(u32, i64)> = r.iter().map(|(k, v)| (*k, *v)).collect();
            prop_assert_eq!(got, want);
            for k in 0..300 {
                prop_assert_eq!(m.get(k), r.get(&k));
            }
        }

        /// Copies never alias: writes to one copy are invisible in every other, in both
        /// directions, whatever was shared.
        #[test]
        fn copies_are_independent(ops_a in prop::collection::vec(op(), 0..60),
                                  ops_b in prop::collection::vec(op(), 0..60)) {
            let mut base = PersistentMap::new();
            for k in 0..100u32 { base.insert(k * 3, k as i64); }
            let snapshot: Vec<(u32, i64)> = base.iter().map(|(k, v)| (k, *v)).collect();
            let mut a = base.clone();
            let mut b = base.clone();
            let (mut ra, mut rb): (BTreeMap<u32, i64>, BTreeMap<u32, i64>) =
                (snapshot.iter().copied().collect(), snapshot.iter().copied().collect());
            for (m, r, ops) in [(&mut a, &mut ra, &ops_a), (&mut b, &mut rb, &ops_b)] {
                for o in ops {
                    match *o {
                        Op::Insert(k, v) => { m.insert(k, v); r.insert(k, v); }
                        Op::Remove(k) => { m.remove(k); r.remove(&k); }
                        Op::Bump(k) => {
                            if let Some(v) = m.get_mut(k) { *v += 1; }
                            if let Some(v) = r.get_mut(&k) { *v += 1; }
                        }
                    }
                }
            }
            let base_now: Vec<(u32, i64)> = base.iter().map(|(k, v)| (k, *v)).collect();
            prop_assert_eq!(base_now, snapshot);
            prop_assert_eq!(a.iter().map(|(k, v)| (k, *v)).collect::<Vec<_>>(),
                            ra.into_iter().collect::<Vec<_>>());
            prop_assert_eq!(b.iter().map(|(k, v)| (k, *v)).collect::<Vec<_>>(),
                            rb.into_iter().collect::<Vec<_>>());
        }
    }

    #[test]
    fn clone_is_a_pointer_and_writes_copy_one_path() {
        let n = 50_000u32;
        let mut a = PersistentMap::new();
        for k in 0..n {
            a.insert(k, [k as f64; 6]);
        }
        assert_eq!(a.depth(), 4); // 16⁴ = 65,536 ≥ 50,000
        let mut b = a.clone();
        assert!(a.ptr_eq(&b));
        assert_eq!(b.unshared_nodes(&a), 0);
        b.get_mut(12_345).unwrap()[0] = -1.0;
        // Exactly the path: 4 inner nodes and the one value were copied.
        assert_eq!(b.unshared_nodes(&a), 5);
        assert_eq!(a.get(12_345).unwrap()[0], 12_345.0);
        // A second write to the same key is in place: b owns that path now.
        b.get_mut(12_345).unwrap()[1] = -2.0;
        assert_eq!(b.unshared_nodes(&a), 5);
        // A write to a neighbour under the same bottom node copies only its value.
        b.get_mut(12_346).unwrap()[0] = -1.0;
        assert_eq!(b.unshared_nodes(&a), 6);
        // A miss copies nothing.
        let c = a.clone();
        let mut d = a.clone();
        assert!(d.get_mut(n + 10).is_none());
        assert!(d.ptr_eq(&c));
    }

    #[test]
    fn grows_and_prunes() {
        let mut m = PersistentMap::new();
        m.insert(5, 'a');
        assert_eq!(m.depth(), 1);
        m.insert(u32::MAX, 'z');
        assert_eq!(m.depth(), 8);
        assert_eq!(m.get(5), Some(&'a'));
        assert_eq!(m.get(u32::MAX), Some(&'z'));
        assert_eq!(m.get(u32::MAX - 1), None);
        assert_eq!(
            m.iter().map(|(k, _)| k).collect::<Vec<_>>(),
            vec![5, u32::MAX]
        );
        assert_eq!(*m.remove(5).unwrap(), 'a');
        assert!(m.remove(5).is_none());
        assert_eq!(*m.remove(u32::MAX).unwrap(), 'z');
        assert!(m.is_empty());
        assert_eq!(m.depth(), 0);
        m.insert(17, 'q');
        assert_eq!(m.depth(), 2);
        assert_eq!(m.get(17), Some(&'q'));
    }
}
