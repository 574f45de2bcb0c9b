//! Scenario generation time: `city` at 2 000 and 50 000 landmarks (the number in view per
//! step is the same, so the time should barely grow), and the `office` laser run.
// criterion_group! generates undocumented public functions.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion};
use slam_sim::scenario::{generate, ScenarioOptions};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("generate");
    g.sample_size(10);
    for n in [2_000usize, 50_000] {
        g.bench_function(format!("city_{n}_landmarks_1500_steps"), |b| {
            b.iter(|| {
                generate(
                    "city",
                    black_box(&ScenarioOptions {
                        seed: 1,
                        landmarks: Some(n),
                        ..Default::default()
                    }),
                )
                .expect("city")
            })
        });
    }
    g.bench_function("office_590_scans_181_beams", |b| {
        b.iter(|| generate("office", black_box(&ScenarioOptions::default())).expect("office"))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
