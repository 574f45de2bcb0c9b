//! `par_iter` / `par_iter_mut` with or without the `parallel` feature.
//!
//! With `parallel` (the default) these are rayon's; without it, the same method names on
//! slices return std's sequential iterators, so the per-particle code is written once and
//! every particle draws from its own stream either way (same seed, same bytes).

#[cfg(feature = "parallel")]
pub(crate) use rayon::prelude::*;

/// Sequential stand-ins for rayon's `par_iter` and `par_iter_mut` (a crate may use only one).
#[cfg(not(feature = "parallel"))]
#[allow(dead_code)]
pub(crate) trait SequentialIter<T> {
    /// `iter()`, under rayon's name.
    fn par_iter(&self) -> std::slice::Iter<'_, T>;
    /// `iter_mut()`, under rayon's name.
    fn par_iter_mut(&mut self) -> std::slice::IterMut<'_, T>;
}

#[cfg(not(feature = "parallel"))]
impl<T> SequentialIter<T> for [T] {
    fn par_iter(&self) -> std::slice::Iter<'_, T> {
        self.iter()
    }
    fn par_iter_mut(&mut self) -> std::slice::IterMut<'_, T> {
        self.iter_mut()
    }
}
