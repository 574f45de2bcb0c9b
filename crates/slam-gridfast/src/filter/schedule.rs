//! Where an update's work runs: the only module that names rayon. One body of the
//! scheduling serves every feature set: with `parallel` (the default) its tasks go to
//! rayon's pool through [`rayon::scope`]; without it, [`inline::scope`] runs each task when
//! it is spawned. Every group's results depend only on its inputs and every particle draws
//! from its own stream, so the output is the same either way, for any number of threads.

use super::stages::Shared;
use super::{numerical, Particle, Pending};
use crate::error::GridFastError;
use crate::proposal::Drawn;
use slam_grid::{GridError, RangeData};
use std::sync::{Mutex, OnceLock};

#[cfg(not(feature = "parallel"))]
use inline::scope;
#[cfg(feature = "parallel")]
use rayon::scope;

/// rayon's `scope` without a thread pool: a spawned task runs at once, on this thread.
#[cfg(not(feature = "parallel"))]
mod inline {
    use std::marker::PhantomData;

    /// A scope whose tasks run when they are spawned.
    pub(super) struct Scope<'s>(PhantomData<&'s ()>);

    impl<'s> Scope<'s> {
        /// Runs `task` now (rayon's `Scope::spawn` queues it).
        pub(super) fn spawn<F: FnOnce(&Scope<'s>) + Send + 's>(&self, task: F) {
            task(self)
        }
    }

    /// Runs `op` with a scope (rayon's `scope`).
    pub(super) fn scope<'s, R>(op: impl FnOnce(&Scope<'s>) -> R) -> R {
        op(&Scope(PhantomData))
    }
}

/// Whether `scan` can be integrated into every group leader's map at its pose, checked on
/// the pool: the first refusal (slam-grid refuses a scan kilometres off the map).
pub(super) fn check_integrable(
    groups: &[(Particle, usize)],
    scan: &RangeData,
) -> Result<(), GridError> {
    #[cfg(feature = "parallel")]
    use rayon::prelude::*;
    #[cfg(feature = "parallel")]
    let leaders = groups.par_iter();
    #[cfg(not(feature = "parallel"))]
    let mut leaders = groups.iter();
    leaders.try_for_each(|(p, _)| p.map.check_integrable(&p.pose, scan))
}

/// One update's work per group of identical particles (`groups`, (first index, count) in
/// order: the filter's `identical`): the group's first particle integrates the pending
/// scan and the copies, which hold the empty map meanwhile, take copies of its map; then
/// `finish` draws the group's particles from `best_work`'s result, which needs the best
/// particle's map with the pending scan. The best particle's group runs first and its
/// `best_work` beside the other groups' integrations, and each other group is drawn as
/// soon as both its map and that result are ready: no step waits for all the maps. `dead`
/// (the particles the last resampling left out) is dropped beside them.
///
/// Returns `best_work`'s result and the draws in particle order, or the integration's
/// error (the best group's first, then the first group's in order), naming the pending
/// scan.
pub(super) fn step_groups<B, F>(
    particles: &mut [Particle],
    best: usize,
    pending: Option<Pending>,
    groups: &[(usize, usize)],
    dead: Vec<Particle>,
    best_work: B,
    finish: F,
) -> Result<(Shared, Vec<Drawn>), GridFastError>
where
    B: FnOnce(&Particle) -> Shared + Send,
    F: Fn(&[Particle], usize, &Shared) -> Vec<Drawn> + Sync,
{
    let k = pending.as_ref().map_or(0, |p| p.k);
    let scan = pending.map(|p| p.scan);
    let integrate = |group: &mut [Particle]| -> Result<(), GridError> {
        let (Some(scan), Some((first, copies))) = (&scan, group.split_first_mut()) else {
            return Ok(());
        };
        first.map.try_integrate_prepared(&first.pose, scan)?;
        for c in copies {
            c.map = first.map.clone();
        }
        Ok(())
    };
    let internal = |reason: &str| GridFastError::Numerical {
        scan: k,
        reason: reason.to_string(),
    };
    let (slices, best_group) = split_groups(particles, groups, best);
    let bg = best_group.ok_or_else(|| internal("the best particle leads no group"))?;
    let n = slices.len();
    let total = groups.iter().map(|&(_, n)| n).sum();
    let (shared, out, mut errors) = run_groups(slices, bg, dead, &integrate, best_work, &finish);
    if let Some(e) = errors[bg].take() {
        return Err(numerical(k, e));
    }
    if let Some(e) = errors.into_iter().flatten().next() {
        return Err(numerical(k, e));
    }
    let shared = shared.ok_or_else(|| internal("no match on the best particle's map"))?;
    let mut drawn = Vec::with_capacity(total);
    for g in out.into_iter().take(n) {
        drawn.extend(g.ok_or_else(|| internal("a group was not drawn"))?);
    }
    Ok((shared, drawn))
}

/// The groups' slices of `particles` in order, with their first index, and which one the
/// particle `best` leads.
fn split_groups<'p>(
    particles: &'p mut [Particle],
    groups: &[(usize, usize)],
    best: usize,
) -> (Vec<(usize, &'p mut [Particle])>, Option<usize>) {
    let mut slices: Vec<(usize, &mut [Particle])> = Vec::with_capacity(groups.len());
    let mut best_group = None;
    let mut rest: &mut [Particle] = particles;
    let mut offset = 0;
    for &(start, n) in groups {
        let (_, tail) = std::mem::take(&mut rest).split_at_mut(start - offset);
        let (group, tail) = tail.split_at_mut(n);
        if start == best {
            best_group = Some(slices.len());
        }
        slices.push((start, group));
        rest = tail;
        offset = start + n;
    }
    (slices, best_group)
}

/// Per group: its draws, or its integration's error.
type GroupResults = (
    Option<Shared>,
    Vec<Option<Vec<Drawn>>>,
    Vec<Option<GridError>>,
);

/// [`step_groups`]'s tasks: the other groups' tasks are spawned, then the best group's
/// integration and `best_work` run here; a group whose map is ready before that result
/// waits in a list, which the best group's task then spawns.
fn run_groups<B, F, I>(
    slices: Vec<(usize, &mut [Particle])>,
    bg: usize,
    dead: Vec<Particle>,
    integrate: &I,
    best_work: B,
    finish: &F,
) -> GroupResults
where
    B: FnOnce(&Particle) -> Shared + Send,
    F: Fn(&[Particle], usize, &Shared) -> Vec<Drawn> + Sync,
    I: Fn(&mut [Particle]) -> Result<(), GridError> + Sync,
{
    let n = slices.len();
    let out: Vec<OnceLock<Vec<Drawn>>> = (0..n).map(|_| OnceLock::new()).collect();
    let errors: Vec<OnceLock<GridError>> = (0..n).map(|_| OnceLock::new()).collect();
    let shared: OnceLock<Shared> = OnceLock::new();
    // Whether `shared` is set, and the groups whose maps were ready before it.
    type Waiting<'a> = (bool, Vec<(usize, usize, &'a [Particle])>);
    let waiting: Mutex<Waiting<'_>> = Mutex::new((false, Vec::new()));
    let lock = || waiting.lock().unwrap_or_else(|e| e.into_inner());
    let draw = |g: usize, start: usize, group: &[Particle], s: &Shared| {
        let _ = out[g].set(finish(group, start, s));
    };
    scope(|scope| {
        let mut best_slice = None;
        for (g, (start, group)) in slices.into_iter().enumerate() {
            if g == bg {
                best_slice = Some((start, group));
                continue;
            }
            let (draw, errors, shared, lock) = (&draw, &errors, &shared, &lock);
            scope.spawn(move |_| {
                if let Err(e) = integrate(group) {
                    let _ = errors[g].set(e);
                    return;
                }
                let group: &[Particle] = group;
                let ready = {
                    let mut w = lock();
                    if !w.0 {
                        w.1.push((g, start, group));
                    }
                    w.0
                };
                if let (true, Some(s)) = (ready, shared.get()) {
                    draw(g, start, group, s);
                }
            });
        }
        // Taken first from this thread's queue (last in, first out), once the best group's
        // work below is done: the dead maps go before the other groups write new tiles.
        scope.spawn(move |_| drop(dead));
        let Some((start, group)) = best_slice else {
            return;
        };
        if let Err(e) = integrate(group) {
            let _ = errors[bg].set(e);
            return;
        }
        let group: &[Particle] = group;
        let Some(first) = group.first() else {
            return;
        };
        let s = shared.get_or_init(|| best_work(first));
        let woken = {
            let mut w = lock();
            w.0 = true;
            std::mem::take(&mut w.1)
        };
        for (g, start, group) in woken {
            let draw = &draw;
            scope.spawn(move |_| draw(g, start, group, s));
        }
        draw(bg, start, group, s);
    });
    (
        shared.into_inner(),
        out.into_iter().map(OnceLock::into_inner).collect(),
        errors.into_iter().map(OnceLock::into_inner).collect(),
    )
}
