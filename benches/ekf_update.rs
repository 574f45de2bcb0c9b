//! `ekf_update`: one EKF update with 10 observations at n = 100 … 2000 landmarks, next to a
//! plain faer copy of the same covariance matrix (the floor for anything that touches all
//! of Σ once), and one prediction at n = 2000.
//!
//! After the criterion groups a summary prints, per n, the median update and copy times
//! (timed again here, interleaved, in the same process), their ratio (target ≤ 3 at
//! n ≥ 1000), the growth exponent of the update between n = 500 and 2000 (≈ 2 for an
//! O(n²) update) and the prediction time at n = 2000.

use criterion::{BenchmarkId, Criterion};
use faer::Mat;
use slam_ekf::{AssociationMode, AssociationOptions, EkfConfig, EkfSlam};
use slam_models::{Control, LandmarkId, LandmarkSlam, OdometryControl, Pose2, RangeBearing};
use std::hint::black_box;
use std::time::{Duration, Instant};

const SIZES: [usize; 5] = [100, 250, 500, 1000, 2000];

/// A filter with `n` landmarks on rings around the robot, mapped in batches of 50 with
/// small motions in between (so Σ is dense), and 10 observations of mapped landmarks.
fn build(n: usize) -> (EkfSlam, Vec<RangeBearing>) {
    let config = EkfConfig {
        association: AssociationOptions {
            mode: AssociationMode::KnownIds,
            known_id_gate_probability: None,
            ..AssociationOptions::default()
        },
        initial_pose_variance: [1e-4, 1e-4, 1e-5],
        ..EkfConfig::default()
    };
    let mut ekf = EkfSlam::new(config, Pose2::IDENTITY, 0).expect("valid config");
    let step = Control::Odometry(OdometryControl {
        rot1: 0.01,
        trans: 0.05,
        rot2: -0.01,
    });
    let mut j = 0;
    while j < n {
        ekf.predict(&step).expect("predict");
        let batch: Vec<RangeBearing> = (j..(j + 50).min(n))
            .map(|k| RangeBearing {
                range: 2.0 + (k % 37) as f64 * 0.2,
                bearing: (k as f64 * 2.399963).sin() * 3.0,
                id: Some(LandmarkId(k as u32)),
            })
            .collect();
        ekf.update(&batch).expect("update");
        j += 50;
    }
    let pose = ekf.pose();
    let lms = ekf.landmarks();
    let obs = (0..10)
        .map(|k| {
            let l = &lms[k * n / 10];
            let q = pose.inverse_transform_point(&l.mean);
            RangeBearing {
                range: q.coords.norm() + 0.01,
                bearing: q.y.atan2(q.x) - 0.002,
                id: Some(l.id),
            }
        })
        .collect();
    (ekf, obs)
}

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

fn benches(c: &mut Criterion) {
    let mut g = c.benchmark_group("ekf_update");
    g.sample_size(10);
    g.warm_up_time(Duration::from_millis(300));
    g.measurement_time(Duration::from_secs(2));
    for &n in &SIZES {
        let (mut ekf, obs) = build(n);
        g.bench_with_input(BenchmarkId::new("update_10_obs", n), &n, |b, _| {
            b.iter(|| black_box(ekf.update(black_box(&obs)).expect("update")))
        });
        let mut dst = Mat::<f64>::zeros(ekf.covariance().nrows(), ekf.covariance().ncols());
        g.bench_with_input(BenchmarkId::new("copy_covariance", n), &n, |b, _| {
            b.iter(|| dst.copy_from(black_box(ekf.covariance())))
        });
        if n == 2000 {
            let u = Control::Odometry(OdometryControl {
                rot1: 0.01,
                trans: 0.1,
                rot2: 0.0,
            });
            g.bench_function(BenchmarkId::new("predict", n), |b| {
                b.iter(|| ekf.predict(black_box(&u)).expect("predict"))
            });
        }
    }
    g.finish();
}

/// Interleaved re-timing for the printed ratios (same process, same matrices).
fn summary() {
    println!("\nekf_update summary (median of interleaved runs, one thread):");
    println!("{:>6} {:>12} {:>12} {:>8}", "n", "update", "copy", "ratio");
    let mut upd = Vec::new();
    for &n in &SIZES {
        let (mut ekf, obs) = build(n);
        let mut dst = Mat::<f64>::zeros(ekf.covariance().nrows(), ekf.covariance().ncols());
        let reps = if n >= 1000 { 15 } else { 41 };
        let (mut tu, mut tc) = (Vec::new(), Vec::new());
        for _ in 0..reps {
            let t = Instant::now();
            black_box(ekf.update(&obs).expect("update"));
            tu.push(t.elapsed());
            let t = Instant::now();
            dst.copy_from(ekf.covariance());
            black_box(&dst);
            tc.push(t.elapsed());
        }
        let (u, c) = (median(tu), median(tc));
        println!(
            "{:>6} {:>10.3}ms {:>10.3}ms {:>8.2}",
            n,
            u.as_secs_f64() * 1e3,
            c.as_secs_f64() * 1e3,
            u.as_secs_f64() / c.as_secs_f64()
        );
        upd.push((n, u.as_secs_f64(), c.as_secs_f64()));
        if n == 2000 {
            let u = Control::Odometry(OdometryControl {
                rot1: 0.01,
                trans: 0.1,
                rot2: 0.0,
            });
            let mut tp = Vec::new();
            for _ in 0..41 {
                let t = Instant::now();
                ekf.predict(&u).expect("predict");
                tp.push(t.elapsed());
            }
            let tp = median(tp).as_secs_f64();
            println!(
                "prediction at n = 2000: {:.4} ms ({:.4} of the update)",
                tp * 1e3,
                tp / upd.last().map(|x| x.1).unwrap_or(1.0)
            );
        }
    }
    let at = |n: usize| upd.iter().find(|x| x.0 == n).copied();
    // Σ at n = 500 (8 MB) may still sit in cache while at 2000 (128 MB) it cannot, so the
    // copy's own exponent is printed beside the update's, and the 1000–2000 pair too.
    for (n0, n1) in [(500, 2000), (1000, 2000)] {
        if let (Some(a), Some(b)) = (at(n0), at(n1)) {
            let r = (n1 as f64 / n0 as f64).ln();
            println!(
                "growth exponent between n = {n0} and {n1}: update {:.2}, copy {:.2}",
                (b.1 / a.1).ln() / r,
                (b.2 / a.2).ln() / r
            );
        }
    }
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    benches(&mut c);
    c.final_summary();
    summary();
}
