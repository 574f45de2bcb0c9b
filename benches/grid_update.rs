//! Map-update benchmarks: integrating a 360-beam scan into a 5 cm grid, and cloning a grid
//! of 10⁶ cells then writing one scan into the clone (copy-on-write cost).
// criterion_group! generates undocumented public functions.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use slam_grid::{InverseSensorModel, OccupancyGrid, RangeData};
use slam_models::{LaserScan, Pose2};
use std::hint::black_box;

/// A 360° scan with 360 beams of a square room of half-width `h` seen from its centre
/// (ranges 4–5.7 m for h = 4).
fn room_scan(h: f64, n: usize) -> LaserScan {
    let inc = 2.0 * std::f64::consts::PI / n as f64;
    let ranges = (0..n)
        .map(|k| {
            let (s, c) = (k as f64 * inc).sin_cos();
            (h / c.abs().max(1e-12)).min(h / s.abs().max(1e-12))
        })
        .collect();
    LaserScan {
        angle_min: 0.0,
        angle_increment: inc,
        ranges,
        max_range: 30.0,
        sensor_pose: Pose2::IDENTITY,
    }
}

fn integrate(c: &mut Criterion) {
    let scan = room_scan(4.0, 360);
    let prepared = RangeData::new(&scan, &InverseSensorModel::default()).expect("valid scan");
    let mut grid = OccupancyGrid::new(0.05, InverseSensorModel::default());
    let mut g = c.benchmark_group("grid_update");
    g.throughput(Throughput::Elements(1));
    let mut k = 0u64;
    g.bench_function("integrate_360_beams_5cm", |b| {
        b.iter(|| {
            // Small pose changes so that cells do not all saturate.
            k += 1;
            let pose = Pose2::new(0.001 * (k % 50) as f64, 0.0, 0.0005 * (k % 30) as f64);
            grid.try_integrate_prepared(black_box(&pose), black_box(&prepared))
                .expect("valid pose");
        })
    });
    // Clone a 10⁶-cell grid (1000 × 1000 cells at 5 cm, every tile allocated) and write one
    // scan into the clone.
    let mut big = OccupancyGrid::new(0.05, InverseSensorModel::default());
    for y in 0..5 {
        for x in 0..5 {
            let p = Pose2::new(-20.0 + 10.0 * x as f64, -20.0 + 10.0 * y as f64, 0.0);
            big.integrate_scan(&p, &room_scan(4.9, 720));
        }
    }
    let mut probe = big.clone();
    probe.reset_copy_stats();
    probe.integrate_scan(&Pose2::IDENTITY, &scan);
    let st = probe.copy_stats();
    println!(
        "clone of {} tiles ({} cells): writing one 360-beam scan copied {} tiles = {} bytes \
         ({} KiB of {} KiB)",
        big.allocated_tiles(),
        big.allocated_tiles() * slam_grid::TILE_CELLS,
        st.tiles_copied,
        st.bytes_copied,
        st.bytes_copied / 1024,
        big.allocated_tiles() * OccupancyGrid::TILE_BYTES / 1024
    );
    g.bench_function("clone_1e6_cells_and_write_scan", |b| {
        b.iter(|| {
            let mut c = black_box(&big).clone();
            c.try_integrate_prepared(&Pose2::IDENTITY, &prepared)
                .expect("valid pose");
            black_box(c.copy_stats().bytes_copied)
        })
    });
    g.finish();
}

criterion_group!(benches, integrate);
criterion_main!(benches);
