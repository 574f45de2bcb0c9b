//! Criterion benches of the pose-graph optimiser on M3500 (3,500 poses, 5,453 edges;
//! `../shared/datasets/pose-graphs/`): a whole Levenberg-Marquardt optimisation from the
//! file's initial guess (setup included) for each sparse Cholesky choice: faer with AMD
//! ordering and its automatic, simplicial and supernodal kernels, and without a
//! fill-reducing ordering. It is the evidence for the default (docs/results/graph.md).
//! Skipped with a message when the dataset is missing.
// criterion_group! generates undocumented public functions.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion};
use slam_graph::{Factorization, Optimizer, OptimizerConfig, Ordering};
use std::path::PathBuf;

fn m3500() -> Option<PathBuf> {
    let dir = std::env::var_os("SLAM_DATASETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/datasets"));
    let p = dir.join("pose-graphs/input_M3500_g2o.g2o");
    if p.exists() {
        Some(p)
    } else {
        eprintln!("SKIPPED: {} not found", p.display());
        None
    }
}

fn bench(c: &mut Criterion) {
    let Some(path) = m3500() else { return };
    let graph = slam_eval::pose_graph::read_pose_graph(&path).expect("M3500 reads");
    let mut g = c.benchmark_group("graph_m3500_lm");
    g.sample_size(10);
    for (name, ordering, factorization) in [
        ("amd_auto", Ordering::Amd, Factorization::Auto),
        ("amd_simplicial", Ordering::Amd, Factorization::Simplicial),
        ("amd_supernodal", Ordering::Amd, Factorization::Supernodal),
        ("natural_auto", Ordering::Natural, Factorization::Auto),
    ] {
        let config = OptimizerConfig {
            ordering,
            factorization,
            ..OptimizerConfig::default()
        };
        g.bench_function(name, |b| {
            b.iter_batched(
                || graph.clone(),
                |mut gr| {
                    let mut o = Optimizer::new(&gr, config).unwrap();
                    o.optimize(&mut gr).unwrap().final_chi2
                },
                criterion::BatchSize::LargeInput,
            )
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
