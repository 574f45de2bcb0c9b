//! A simulated loop corridor with ground truth, shared by the tests and the benches.
#![allow(dead_code)]

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use slam_models::{LaserScan, Pose2, ScanRecord};

/// Wall segments of a rectangular loop corridor (outer 20 × 12 m, inner block 16 × 8 m,
/// 2 m wide) with boxes and alcoves so that no stretch is featureless.
pub fn world() -> Vec<[f64; 4]> {
    let mut w = Vec::new();
    let mut rect = |x0: f64, y0: f64, x1: f64, y1: f64| {
        w.push([x0, y0, x1, y0]);
        w.push([x1, y0, x1, y1]);
        w.push([x1, y1, x0, y1]);
        w.push([x0, y1, x0, y0]);
    };
    rect(-10.0, -6.0, 10.0, 6.0);
    rect(-8.0, -4.0, 8.0, 4.0);
    // Boxes against the outer wall and the inner block.
    for (x, y) in [
        (-5.0, -5.7),
        (0.5, -5.7),
        (5.5, -5.7),
        (-3.0, 5.7),
        (3.0, 5.7),
    ] {
        rect(x - 0.3, y - 0.3, x + 0.3, y + 0.3);
    }
    for (x, y) in [
        (-9.7, -1.0),
        (9.7, 2.0),
        (-2.0, -4.3),
        (4.0, 4.3),
        (-6.0, 4.3),
    ] {
        rect(x - 0.3, y - 0.3, x + 0.3, y + 0.3);
    }
    w
}

pub fn cast(world: &[[f64; 4]], x: f64, y: f64, a: f64, max: f64) -> f64 {
    let (dx, dy) = (a.cos(), a.sin());
    let mut best = max;
    for s in world {
        let (ex, ey) = (s[2] - s[0], s[3] - s[1]);
        let den = dx * ey - dy * ex;
        if den.abs() < 1e-12 {
            continue;
        }
        let (wx, wy) = (s[0] - x, s[1] - y);
        let t = (wx * ey - wy * ex) / den;
        let u = (wx * dy - wy * dx) / den;
        if t > 0.0 && (0.0..=1.0).contains(&u) && t < best {
            best = t;
        }
    }
    best
}

/// A loop around the corridor (centre line at |x| = 9, |y| = 5), 0.1 m per record, a scan
/// every 3rd record; odometry with a 3 % heading and 2 % distance bias plus noise.
pub fn simulate(seed: u64) -> (Vec<ScanRecord>, Vec<Pose2>) {
    let world = world();
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let corners: [(f64, f64); 6] = [
        (-9.0, -5.0),
        (9.0, -5.0),
        (9.0, 5.0),
        (-9.0, 5.0),
        (-9.0, -5.0),
        (0.0, -5.0),
    ];
    let mut truth = vec![Pose2::new(-9.0, -5.0, 0.0)];
    for w in corners.windows(2) {
        let (a, b) = (w[0], w[1]);
        let heading = (b.1 - a.1).atan2(b.0 - a.0);
        // Turn in place in 0.15 rad steps, then drive.
        loop {
            let cur = *truth.last().unwrap();
            let d = slam_models::normalize_angle(heading - cur.theta);
            if d.abs() < 1e-9 {
                break;
            }
            truth.push(Pose2::new(cur.x, cur.y, cur.theta + d.clamp(-0.15, 0.15)));
        }
        let len = (b.0 - a.0).hypot(b.1 - a.1);
        let n = (len / 0.1).round() as usize;
        for k in 1..=n {
            let f = k as f64 / n as f64;
            truth.push(Pose2::new(
                a.0 + f * (b.0 - a.0),
                a.1 + f * (b.1 - a.1),
                heading,
            ));
        }
    }
    let mut odo = Pose2::IDENTITY;
    let mut records = Vec::with_capacity(truth.len());
    let (n, inc) = (181, std::f64::consts::PI / 180.0);
    for (i, p) in truth.iter().enumerate() {
        if i > 0 {
            let d = truth[i - 1].between(p);
            let noisy = Pose2::new(
                d.x * 1.02 + rng.random_range(-0.005..0.005),
                d.y + rng.random_range(-0.005..0.005),
                d.theta * 1.03 + 0.002 * d.x + rng.random_range(-0.003..0.003),
            );
            odo = odo.compose(&noisy);
        }
        let scan = (i % 3 == 0).then(|| LaserScan {
            angle_min: -std::f64::consts::FRAC_PI_2,
            angle_increment: inc,
            ranges: (0..n)
                .map(|k| {
                    let a = p.theta - std::f64::consts::FRAC_PI_2 + k as f64 * inc;
                    let r = cast(&world, p.x, p.y, a, 30.0);
                    if r >= 30.0 {
                        30.0
                    } else {
                        r + rng.random_range(-0.01..0.01)
                    }
                })
                .collect(),
            max_range: 30.0,
            sensor_pose: Pose2::IDENTITY,
        });
        records.push(ScanRecord {
            t: i as f64 * 0.1,
            odometry: odo,
            scan,
        });
    }
    (records, truth)
}
