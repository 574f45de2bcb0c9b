//! Criterion benches of grid FastSLAM on the simulated loop corridor (≈ 560 records,
//! ≈ 56 processed scans of 181 beams): a whole run with 30 particles per proposal, on one
//! thread and on all threads. Whole-Intel figures (wall time, real-time factor, peak RSS)
//! come from `cargo run --release --example gridfast_intel`.

use criterion::{criterion_group, criterion_main, Criterion};
use slam_gridfast::{GridFastConfig, GridFastSlam, Proposal};
use slam_models::ScanSlam;

#[path = "../crates/slam-gridfast/tests/support/mod.rs"]
mod support;

fn bench(c: &mut Criterion) {
    let (records, _) = support::simulate(3);
    let mut g = c.benchmark_group("gridfast_loop_30_particles");
    g.sample_size(10);
    for (name, proposal) in [
        ("improved", Proposal::Improved),
        ("scan_matched_odometry", Proposal::ScanMatchedOdometry),
        ("odometry", Proposal::Odometry),
    ] {
        for threads in [1usize, 0] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let label = format!(
                "{name}/{}",
                if threads == 1 {
                    "1_thread"
                } else {
                    "all_threads"
                }
            );
            g.bench_function(label, |b| {
                b.iter(|| {
                    pool.install(|| {
                        let config = GridFastConfig {
                            particles: 30,
                            proposal,
                            ..Default::default()
                        };
                        let mut slam = GridFastSlam::new(config, 1).unwrap();
                        for r in &records {
                            slam.process(r).unwrap();
                        }
                        slam.pose()
                    })
                })
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
