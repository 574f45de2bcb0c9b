//! Ray-casting throughput on a 200-segment world (target: ≥ 1 M rays/s on one core).
//!
//! Criterion reports the throughput as `elem/s` (one element = one ray); the bench also
//! prints `rays/s` directly from a plain timed loop before the criterion runs.
// criterion_group! generates undocumented public functions.
#![allow(missing_docs)]

use criterion::{criterion_group, Criterion, Throughput};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use slam_models::{Point2, Pose2};
use slam_sim::laser::{LaserScanner, Segment, World};
use std::hint::black_box;
use std::time::Instant;

/// 50 random boxes (4 walls each) in a 60 m × 60 m square: 200 segments.
fn boxes_world() -> World {
    let mut rng = Pcg64Mcg::seed_from_u64(11);
    let mut segs = Vec::new();
    for _ in 0..50 {
        let (x, y) = (rng.random_range(-30.0..28.0), rng.random_range(-30.0..28.0));
        let (w, h) = (rng.random_range(0.3..2.0), rng.random_range(0.3..2.0));
        segs.push(Segment::new(x, y, x + w, y));
        segs.push(Segment::new(x + w, y, x + w, y + h));
        segs.push(Segment::new(x + w, y + h, x, y + h));
        segs.push(Segment::new(x, y + h, x, y));
    }
    World::new(segs).expect("valid world")
}

/// Random ray origins and angles.
fn rays(n: usize) -> Vec<(Point2, f64)> {
    let mut rng = Pcg64Mcg::seed_from_u64(12);
    (0..n)
        .map(|_| {
            (
                Point2::new(rng.random_range(-30.0..30.0), rng.random_range(-30.0..30.0)),
                rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
            )
        })
        .collect()
}

fn print_rays_per_second() {
    let w = boxes_world();
    let rs = rays(100_000);
    for max_range in [10.0, 30.0] {
        let t = Instant::now();
        let mut hits = 0usize;
        let mut reps = 0;
        while t.elapsed().as_secs_f64() < 1.0 {
            for (p, a) in &rs {
                hits += w.cast(p, *a, max_range).is_some() as usize;
            }
            reps += 1;
        }
        let rate = (reps * rs.len()) as f64 / t.elapsed().as_secs_f64();
        println!(
            "raycast: {} segments, max range {max_range} m: {:.2} M rays/s (one core; {:.0} % hit)",
            w.segments().len(),
            rate / 1e6,
            100.0 * hits as f64 / (reps * rs.len()) as f64
        );
    }
}

fn bench(c: &mut Criterion) {
    print_rays_per_second();
    let w = boxes_world();
    let rs = rays(10_000);
    let mut g = c.benchmark_group("raycast");
    g.throughput(Throughput::Elements(rs.len() as u64));
    g.bench_function("grid_200_segments_30m", |b| {
        b.iter(|| {
            let mut s = 0.0;
            for (p, a) in &rs {
                s += w.cast(black_box(p), *a, 30.0).unwrap_or(0.0);
            }
            s
        })
    });
    g.throughput(Throughput::Elements(1000));
    g.bench_function("brute_force_200_segments_30m", |b| {
        b.iter(|| {
            let mut s = 0.0;
            for (p, a) in &rs[..1000] {
                s += w.cast_brute_force(black_box(p), *a, 30.0).unwrap_or(0.0);
            }
            s
        })
    });
    g.finish();
    let mut g = c.benchmark_group("scan");
    let sc = LaserScanner::default();
    g.throughput(Throughput::Elements(sc.beams as u64));
    g.bench_function("181_beams", |b| {
        b.iter(|| sc.true_ranges(&w, black_box(&Pose2::new(0.5, 0.5, 0.3))))
    });
    g.finish();
}

criterion_group!(benches, bench);

fn main() {
    benches();
    Criterion::default().configure_from_args().final_summary();
}
