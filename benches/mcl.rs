//! Monte Carlo localization speed on Intel: `bench/intel.log` (2,691 s of driving, 910
//! scans, 14,610 records) localized from `--global` on the known-poses map of
//! `radish-corrected/intel-corrected.log.gz`, with the adaptive (KLD) particle count.
//! Prints steps/s, the real-time factor and the particle count's range before the criterion
//! run (whole log, one core: slam-mcl has no threads). Skips when the datasets are missing.
// criterion_group! generates undocumented public functions.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion};
use slam_grid::{KnownPoseConfig, KnownPoseMapping};
use slam_io::{open_dataset, Dataset};
use slam_mcl::{InitialBelief, Mcl, MclConfig, MclMap};
use slam_models::{Pose2, ScanDataset, ScanSlam};
use std::path::Path;
use std::time::Instant;

fn scans(path: &Path) -> Option<ScanDataset> {
    match open_dataset(path, None).ok()? {
        (Dataset::Scan(d), _) => Some(d),
        _ => None,
    }
}

/// One whole run; returns (updates, smallest and largest particle count).
fn localize(map: &MclMap, log: &ScanDataset) -> (usize, usize, usize) {
    let mut mcl = Mcl::new(MclConfig::default(), map.clone(), InitialBelief::Global, 0).unwrap();
    let (mut lo, mut hi, mut n) = (usize::MAX, 0, 0);
    for r in &log.records {
        let info = mcl.process(r).unwrap();
        if info.updated {
            n += 1;
            lo = lo.min(info.particles);
            hi = hi.max(info.particles);
        }
    }
    (n, lo, hi)
}

fn bench(c: &mut Criterion) {
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/datasets");
    let (Some(corrected), Some(log)) = (
        scans(&base.join("radish-corrected/intel-corrected.log.gz")),
        scans(&base.join("bench/intel.log")),
    ) else {
        eprintln!("SKIPPED: Intel datasets not found under {}", base.display());
        return;
    };
    let mut mapper = KnownPoseMapping::new(KnownPoseConfig::default(), Pose2::IDENTITY, 0).unwrap();
    for r in &corrected.records {
        mapper.process(r).unwrap();
    }
    let map = MclMap::new(mapper.map(), &MclConfig::default()).unwrap();
    let start = Instant::now();
    let (updates, lo, hi) = localize(&map, &log);
    let secs = start.elapsed().as_secs_f64();
    let duration = log.records.last().unwrap().t - log.records[0].t;
    println!(
        "mcl intel: {} records ({updates} updates) in {secs:.2} s: {:.0} steps/s, {:.0}x real time, particles {lo}–{hi}",
        log.records.len(),
        log.records.len() as f64 / secs,
        duration / secs
    );
    let mut g = c.benchmark_group("mcl_intel_global");
    g.sample_size(10);
    g.bench_function("whole_log", |b| b.iter(|| localize(&map, &log)));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
