//! Criterion benches of grid FastSLAM on slam-sim's `office` (one lap: ≈ 295 scans of 181
//! beams, ≈ 70 processed): a whole run with 30 particles per proposal (slam-eval's
//! `run_scans`, unscored), on one thread and on all threads. Whole-Intel figures (wall time, real-time factor, peak RSS)
//! come from `cargo run --release --example gridfast_intel`.
// criterion_group! generates undocumented public functions.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion};
use slam_gridfast::{GridFastConfig, GridFastSlam, Proposal, ProposalConfig};
use slam_sim::scenario::{generate, ScenarioOptions};
use slam_sim::SimOutput;

fn bench(c: &mut Criterion) {
    let opts = ScenarioOptions {
        seed: 3,
        laps: Some(1.0),
        ..Default::default()
    };
    let Ok(SimOutput::Laser(run)) = generate("office", &opts) else {
        panic!("office scenario did not generate a laser run");
    };
    // Without its ground truth: the bench times the run, not the scoring.
    let data = slam_models::ScanDataset {
        ground_truth: None,
        ..run.dataset
    };
    let mut g = c.benchmark_group("gridfast_office_30_particles");
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
                            proposal: ProposalConfig {
                                kind: proposal,
                                ..Default::default()
                            },
                            ..Default::default()
                        };
                        let mut slam =
                            GridFastSlam::new(config, slam::models::Pose2::IDENTITY, 1).unwrap();
                        slam_eval::run_scans(&mut slam, &data, &Default::default())
                            .unwrap()
                            .trajectory
                    })
                })
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
