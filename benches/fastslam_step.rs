//! FastSLAM step cost against map size, and particle throughput.
//!
//! 1. `city` scenario (slam-sim), 100 particles, FastSLAM 2.0, ids known, every particle's
//!    map pre-filled with all N true landmarks (`set_prior_map`, so the map really holds N
//!    landmarks while the robot sees about the same number per scan at every N), for
//!    N = 500, 5,000 and 50,000: time per step (predict + update) and bytes allocated per
//!    step (a counting global allocator). A copy-the-map design would scale with N; the
//!    shared trees scale with log N. Prints t(50,000)/t(500) (target ≤ 2).
//! 2. 1,000 particles on `loop`: steps per second on one thread and on all threads.
//! 3. Memory as the run grows: FastSLAM 2.0, 100 particles, `loop` for 100,000 steps
//!    (≈ 330 laps past the same 50 landmarks, so the maps stop growing after the first lap).
//!    At 1,000, 10,000 and 100,000 steps: bytes allocated per step since the previous
//!    checkpoint (flat: O(1) work per particle per step), the live heap the filter holds and
//!    its growth per step (one trunk node of the shared path tree, not one pose per
//!    particle: copying every particle's path would hold M · t poses), and the tree's
//!    distinct nodes. Printed only; `FASTSLAM_MEMORY_STEPS=N` shortens it.
//!
//! ```text
//! cargo xtask bench fastslam
//! ```
// criterion_group! generates undocumented public functions.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion};
use slam_fastslam::{FastSlam, FastSlamConfig, Variant};
use slam_models::{LandmarkEstimate, LandmarkSlam, Matrix2};
use slam_sim::scenario::{generate, ScenarioOptions};
use slam_sim::{LandmarkSimRun, SimOutput};
use std::alloc::{GlobalAlloc, Layout, System};
use std::hint::black_box;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// The system allocator, counting the bytes it hands out and (for the live heap) takes
/// back. A `realloc` counts as the growth only, as before the free counter existed; its
/// shrinking counts as freed.
struct Counting;

static ALLOCATED: AtomicU64 = AtomicU64::new(0);
static FREED: AtomicU64 = AtomicU64::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        ALLOCATED.fetch_add(l.size() as u64, Ordering::Relaxed);
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        FREED.fetch_add(l.size() as u64, Ordering::Relaxed);
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
        ALLOCATED.fetch_add(new.saturating_sub(l.size()) as u64, Ordering::Relaxed);
        FREED.fetch_add(l.size().saturating_sub(new) as u64, Ordering::Relaxed);
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.realloc(p, l, new) }
    }
}

/// Bytes allocated and not yet freed.
fn live() -> u64 {
    ALLOCATED.load(Ordering::Relaxed) - FREED.load(Ordering::Relaxed)
}

#[global_allocator]
static GLOBAL: Counting = Counting;

const CITY_STEPS: usize = 400;
const WARMUP: usize = 20;

fn scenario(name: &str, landmarks: Option<usize>, steps: usize) -> LandmarkSimRun {
    match generate(
        name,
        &ScenarioOptions {
            seed: 1,
            steps: Some(steps),
            landmarks,
            ..Default::default()
        },
    ) {
        Ok(SimOutput::Landmark(r)) => r,
        _ => panic!("{name} is a landmark scenario"),
    }
}

/// A filter over `run` with `particles` particles (and, for the city, the prior map),
/// advanced by `WARMUP` steps.
fn filter(run: &LandmarkSimRun, particles: usize, prior: bool) -> FastSlam {
    let cfg = FastSlamConfig {
        variant: Variant::FastSlam2,
        particles,
        motion: run.motion,
        sensor: run.sensor,
        ..Default::default()
    };
    let mut f = FastSlam::new(cfg, run.dataset.initial_pose, 9).expect("valid config");
    if prior {
        let lms: Vec<LandmarkEstimate> = run
            .dataset
            .landmarks
            .as_ref()
            .expect("city has true landmarks")
            .iter()
            .map(|&(id, mean)| LandmarkEstimate {
                id,
                mean,
                covariance: Matrix2::identity() * 0.01,
            })
            .collect();
        f.set_prior_map(&lms).expect("finite prior");
    }
    for s in &run.dataset.steps[..WARMUP] {
        f.predict(&s.control).expect("finite");
        f.update(&s.observations).expect("finite");
    }
    f
}

/// Runs `iters` steps, cycling through the run's steps after the warm-up (a fresh filter
/// each time the data runs out, built outside the timed region). Returns the time spent
/// in steps and the bytes allocated by them.
fn timed_steps(run: &LandmarkSimRun, particles: usize, prior: bool, iters: u64) -> (Duration, u64) {
    let mut f = filter(run, particles, prior);
    let mut k = WARMUP;
    let mut t = Duration::ZERO;
    let mut bytes = 0;
    for _ in 0..iters {
        if k == run.dataset.steps.len() {
            f = filter(run, particles, prior);
            k = WARMUP;
        }
        let s = &run.dataset.steps[k];
        let a0 = ALLOCATED.load(Ordering::Relaxed);
        let t0 = Instant::now();
        f.predict(&s.control).expect("finite");
        black_box(f.update(&s.observations).expect("finite"));
        t += t0.elapsed();
        bytes += ALLOCATED.load(Ordering::Relaxed) - a0;
        k += 1;
    }
    (t, bytes)
}

fn city(c: &mut Criterion) {
    let sizes = [500usize, 5_000, 50_000];
    let runs: Vec<LandmarkSimRun> = sizes
        .iter()
        .map(|&n| scenario("city", Some(n), CITY_STEPS))
        .collect();
    // Direct measurement for the summary line: every step of the run once.
    let mut per_step = Vec::new();
    for (n, r) in sizes.iter().zip(&runs) {
        let steps = (CITY_STEPS - WARMUP) as u64;
        let obs: usize = r.dataset.steps[WARMUP..]
            .iter()
            .map(|s| s.observations.len())
            .sum();
        let (t, bytes) = timed_steps(r, 100, true, steps);
        let us = t.as_secs_f64() * 1e6 / steps as f64;
        println!(
            "city N = {n:>6}: {us:8.1} µs/step, {:8.0} bytes allocated/step, {:.1} observations/step",
            bytes as f64 / steps as f64,
            obs as f64 / steps as f64
        );
        per_step.push(us);
    }
    println!(
        "t(50,000)/t(500) = {:.2} (target ≤ 2; a copy-the-map design ≈ 100)",
        per_step[2] / per_step[0]
    );
    let mut g = c.benchmark_group("city_100_particles");
    g.sample_size(10).measurement_time(Duration::from_secs(5));
    for (n, r) in sizes.iter().zip(&runs) {
        g.bench_function(format!("N={n}"), |b| {
            b.iter_custom(|iters| timed_steps(r, 100, true, iters).0)
        });
    }
    g.finish();
}

fn loop_1000(c: &mut Criterion) {
    let r = scenario("loop", None, 333);
    let all = rayon::current_num_threads();
    for threads in [1, all] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        let steps = 100u64;
        let (t, _) = pool.install(|| timed_steps(&r, 1000, false, steps));
        println!(
            "loop, 1,000 particles, {threads} thread(s): {:.1} steps/s",
            steps as f64 / t.as_secs_f64()
        );
        let mut g = c.benchmark_group("loop_1000_particles");
        g.sample_size(10).measurement_time(Duration::from_secs(5));
        g.bench_function(format!("threads={threads}"), |b| {
            b.iter_custom(|iters| pool.install(|| timed_steps(&r, 1000, false, iters).0))
        });
        g.finish();
    }
}

fn memory_per_step(_: &mut Criterion) {
    let steps: usize = std::env::var("FASTSLAM_MEMORY_STEPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(100_000);
    let particles = 100;
    let run = scenario("loop", None, steps);
    let cfg = FastSlamConfig {
        variant: Variant::FastSlam2,
        particles,
        motion: run.motion,
        sensor: run.sensor,
        ..Default::default()
    };
    let live0 = live();
    let mut f = FastSlam::new(cfg, run.dataset.initial_pose, 0).expect("valid config");
    println!("memory: FastSLAM 2.0, {particles} particles, loop, {steps} steps");
    println!(
        "{:>8} {:>14} {:>12} {:>14} {:>11} {:>16}",
        "steps", "alloc B/step", "live MB", "live B/step", "tree nodes", "copied paths MB"
    );
    let checkpoints = [1_000, 10_000, 100_000];
    let (mut prev_step, mut prev_alloc, mut prev_live) =
        (0usize, ALLOCATED.load(Ordering::Relaxed), live());
    for (k, s) in run.dataset.steps.iter().enumerate() {
        f.predict(&s.control).expect("finite");
        f.update(&s.observations).expect("finite");
        let done = k + 1;
        if checkpoints.contains(&done) {
            let (alloc, held) = (ALLOCATED.load(Ordering::Relaxed), live());
            let n = (done - prev_step) as f64;
            // Counted after the snapshot: flattening the tree allocates.
            let nodes = f.particle_paths().map_or(0, |p| p.nodes.len());
            println!(
                "{done:>8} {:>14.0} {:>12.2} {:>14.1} {:>11} {:>16.1}",
                (alloc - prev_alloc) as f64 / n,
                (held - live0) as f64 / 1e6,
                (held as f64 - prev_live as f64) / n,
                nodes,
                (particles * (done + 1) * 24) as f64 / 1e6
            );
            (prev_step, prev_alloc, prev_live) = (done, ALLOCATED.load(Ordering::Relaxed), live());
        }
    }
}

criterion_group!(benches, city, loop_1000, memory_per_step);
criterion_main!(benches);
