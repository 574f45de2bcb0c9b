//! Unit tests of the laser front end (the simulated and Intel runs are in the workspace's
//! `tests/graph_laser.rs`).

use super::loops::loop_pyramid;
use super::*;
use slam_grid::BranchBoundMatcher;

/// Appends record and keyframe `k` (time k s, `scan`) at `pose` as its odometry, local and
/// global pose, 0.5 m of path per keyframe: the hand-built graphs of the tests below.
fn push_keyframe(f: &mut LaserGraphSlam, k: usize, pose: Pose2, scan: &LaserScan) {
    f.times.push(k as f64);
    f.odometry.push(pose);
    f.last_keyframe_at.push(Some(k));
    f.keyframes.push(Keyframe {
        record: k,
        scan: scan.clone(),
        local: pose,
        global: pose,
        path: 0.5 * k as f64,
    });
}

fn record(t: f64, odometry: Pose2) -> ScanRecord {
    ScanRecord {
        t,
        odometry,
        scan: None,
    }
}

/// Without scans, the smoothed trajectory is the odometry itself (every odometry edge is
/// satisfied exactly, the first pose held).
#[test]
fn odometry_only_gives_the_odometry() {
    let mut f = LaserGraphSlam::new(LaserGraphConfig::default(), Pose2::IDENTITY, 0).unwrap();
    let mut o = Pose2::new(1.0, -2.0, 0.3);
    let mut expected = Vec::new();
    for i in 0..50 {
        f.process(&record(i as f64 * 0.1, o)).unwrap();
        expected.push(o);
        o = o.compose(&Pose2::new(0.05, 0.0, 0.02));
    }
    let tr = f.trajectory();
    assert_eq!(tr.len(), 50);
    for (a, b) in tr.iter().zip(&expected) {
        assert!(a.pose.approx_eq(b, 1e-9), "{:?} vs {b:?}", a.pose);
    }
}

/// A scan with a NaN range is an error and leaves the front end as it was; an odometry jump
/// beyond the limit is an error naming the bound.
#[test]
fn bad_records_are_errors_that_change_nothing() {
    let mut f = LaserGraphSlam::new(LaserGraphConfig::default(), Pose2::IDENTITY, 0).unwrap();
    f.process(&record(0.0, Pose2::IDENTITY)).unwrap();
    let bad = ScanRecord {
        t: 0.1,
        odometry: Pose2::new(0.1, 0.0, 0.0),
        scan: Some(slam_models::LaserScan {
            angle_min: -1.0,
            angle_increment: 0.1,
            ranges: vec![f64::NAN; 21],
            max_range: 20.0,
            sensor_pose: Pose2::IDENTITY,
        }),
    };
    assert!(f.process(&bad).is_err());
    assert_eq!(f.trajectory().len(), 1);
    let e = f.step(&record(0.2, Pose2::new(1e4, 0.0, 0.0))).unwrap_err();
    assert!(e.to_string().contains("5 m"), "{e}");
    assert_eq!(f.trajectory().len(), 1);
}

/// A scan from (`x0`, `y0`) inside the box 0 ≤ x ≤ 6, 0 ≤ y ≤ 4 with a 1 m square pillar
/// at (4 … 5, 1 … 2), 361 beams over 360°, 20 m max range (rays cast exactly).
fn room_scan(x0: f64, y0: f64) -> slam_models::LaserScan {
    let n = 361;
    let angle_min = -std::f64::consts::PI;
    let inc = 2.0 * std::f64::consts::PI / (n - 1) as f64;
    let segments = [
        ((0.0, 0.0), (6.0, 0.0)),
        ((6.0, 0.0), (6.0, 4.0)),
        ((6.0, 4.0), (0.0, 4.0)),
        ((0.0, 4.0), (0.0, 0.0)),
        ((4.0, 1.0), (5.0, 1.0)),
        ((5.0, 1.0), (5.0, 2.0)),
        ((5.0, 2.0), (4.0, 2.0)),
        ((4.0, 2.0), (4.0, 1.0)),
    ];
    let ranges = (0..n)
        .map(|i| {
            let a = angle_min + i as f64 * inc;
            let (dx, dy) = (a.cos(), a.sin());
            let mut best = 20.0f64;
            for ((ax, ay), (bx, by)) in segments {
                // Solve (x0, y0) + t·d = a + u·(b − a), t > 0, 0 ≤ u ≤ 1.
                let (ex, ey) = (bx - ax, by - ay);
                let det = dx * (-ey) - dy * (-ex);
                if det.abs() < 1e-12 {
                    continue;
                }
                let (rx, ry) = (ax - x0, ay - y0);
                let t = (rx * (-ey) - ry * (-ex)) / det;
                let u = (dx * ry - dy * rx) / det;
                if t > 1e-9 && (0.0..=1.0).contains(&u) {
                    best = best.min(t);
                }
            }
            best
        })
        .collect();
    slam_models::LaserScan {
        angle_min,
        angle_increment: inc,
        ranges,
        max_range: 20.0,
        sensor_pose: Pose2::IDENTITY,
    }
}

/// The loop-closure pyramid over the obstacles' reach finds exactly what the pyramid over
/// every covered cell finds (pose, score and covariance), from initial guesses up to 0.4 m
/// and 0.2 rad off, and it is smaller.
#[test]
fn obstacle_bounded_pyramid_searches_like_the_full_one() {
    let config = LaserGraphConfig::default();
    let mut grid = OccupancyGrid::try_new(config.resolution, config.sensor_model)
        .unwrap()
        .with_likelihood(config.likelihood)
        .unwrap();
    for (x, y) in [(1.0, 1.0), (2.0, 3.0), (3.0, 2.0)] {
        grid.try_integrate_scan(&Pose2::new(x, y, 0.0), &room_scan(x, y))
            .unwrap();
    }
    let full = MaxPyramid::covering(&grid, config.loop_depth)
        .unwrap()
        .unwrap();
    let bounded = loop_pyramid(&grid, config.loop_depth).unwrap().unwrap();
    assert!(bounded.memory_bytes() < full.memory_bytes());
    let scan = RangeData::new(&room_scan(2.5, 1.5), grid.sensor_model()).unwrap();
    let matcher = BranchBoundMatcher {
        linear_window: 0.5,
        angular_window: 0.3,
        angular_step: 0.0,
        depth: config.loop_depth,
        min_score: 0.3,
        min_points: 10,
    };
    for (dx, dy, dth) in [(0.0, 0.0, 0.0), (0.3, -0.2, 0.1), (-0.4, 0.1, -0.2)] {
        let initial = Pose2::new(2.5 + dx, 1.5 + dy, dth);
        let a = matcher.match_in(&full, &scan, &initial).unwrap().unwrap();
        let b = matcher
            .match_in(&bounded, &scan, &initial)
            .unwrap()
            .unwrap();
        assert_eq!(a, b);
        assert!(a.pose.distance(&Pose2::new(2.5, 1.5, 0.0)) < 0.1, "{a:?}");
    }
}

/// A front end whose keyframes and records are a noisy-odometry drive twice around a 6 m
/// square (0.5 m steps, 96 records, every record a keyframe whose local pose is the
/// odometry), with the odometry edges and, from the second lap to the first, true loop
/// closures (the true relative pose, σ = 2 cm / 0.005 rad); optionally one false closure
/// joining records 12 and 36 (opposite corners, 8.5 m apart) as if they were one place.
/// Returns the smoothed trajectory and the odometry chain's covariance between the false
/// closure's ends (the uncertainty of the edges it contradicts).
fn square_with_closures(config: LaserGraphConfig, false_closure: bool) -> (Vec<Pose2>, Matrix3) {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
    let noise = Normal::new(0.0, 1.0).unwrap();
    let mut f = LaserGraphSlam::new(config, Pose2::IDENTITY, 0).unwrap();
    let scan = room_scan(2.5, 1.5);
    let n = 96;
    let truth: Vec<Pose2> = {
        let mut p = Pose2::IDENTITY;
        (0..n)
            .map(|k| {
                let here = p;
                let turn = if k % 12 == 11 {
                    std::f64::consts::FRAC_PI_2
                } else {
                    0.0
                };
                p = p.compose(&Pose2::new(0.5, 0.0, turn));
                here
            })
            .collect()
    };
    let mut o = Pose2::IDENTITY;
    for k in 0..n {
        if k > 0 {
            let d = truth[k - 1].between(&truth[k]);
            let e = Pose2::new(
                d.x + 0.02 * noise.sample(&mut rng),
                d.y + 0.02 * noise.sample(&mut rng),
                d.theta + 0.01 + 0.01 * noise.sample(&mut rng),
            );
            o = o.compose(&e);
        }
        push_keyframe(&mut f, k, o, &scan);
        if k > 0 {
            let z = f.odometry[k - 1].between(&o);
            let information = invert(&f.odometry_chain_covariance(k - 1, k));
            f.constraints.push(Constraint {
                from: k - 1,
                to: k,
                z,
                information,
                loop_closure: false,
            });
        }
    }
    let closure_info = invert(&Matrix3::from_diagonal(&slam_models::Vector3::new(
        4e-4, 4e-4, 2.5e-5,
    )));
    for k in [0, 3, 6, 9, 20, 30, 40] {
        let z = truth[k].between(&truth[k + 48]);
        f.constraints.push(Constraint {
            from: k,
            to: k + 48,
            z: Pose2::new(
                z.x + 0.02 * noise.sample(&mut rng),
                z.y + 0.02 * noise.sample(&mut rng),
                z.theta + 0.005 * noise.sample(&mut rng),
            ),
            information: closure_info,
            loop_closure: true,
        });
    }
    if false_closure {
        f.constraints.push(Constraint {
            from: 12,
            to: 36,
            z: Pose2::IDENTITY,
            information: closure_info,
            loop_closure: true,
        });
    }
    f.optimize_keyframes().unwrap();
    let contradicted = f.odometry_chain_covariance(12, 36);
    (f.smoothed_poses(), contradicted)
}

/// A wrong closure cannot move the estimate by more than the uncertainty of the edges it
/// contradicts: with the default treatment (DCS on the keyframe graph's closures, then
/// χ²-gated out of the trajectory graph) a false closure between opposite corners of the
/// square moves no smoothed pose by more than the 1σ position uncertainty of the odometry
/// chain between its ends; without a closure kernel the same closure moves the estimate by
/// more than that (the test has teeth).
#[test]
fn an_injected_false_closure_moves_the_estimate_less_than_the_contradicted_uncertainty() {
    let sigma = |cov: &Matrix3| {
        let (a, b, d) = (cov[(0, 0)], cov[(0, 1)], cov[(1, 1)]);
        (0.5 * (a + d) + (0.25 * (a - d) * (a - d) + b * b).sqrt()).sqrt()
    };
    let moved = |x: &[Pose2], y: &[Pose2]| {
        x.iter()
            .zip(y)
            .map(|(a, b)| a.distance(b))
            .fold(0.0, f64::max)
    };
    let (clean, cov) = square_with_closures(LaserGraphConfig::default(), false);
    let (dirty, _) = square_with_closures(LaserGraphConfig::default(), true);
    let bound = sigma(&cov);
    let shift = moved(&clean, &dirty);
    eprintln!("false closure: moved {shift:.4} m, contradicted chain 1σ {bound:.3} m");
    assert!(bound > 0.1, "the chain's σ {bound} m");
    assert!(shift < bound, "moved {shift} m, bound {bound} m");
    let mut plain = LaserGraphConfig::default();
    plain.optimizer.closure_kernel = crate::kernel::RobustKernel::None;
    plain.smoother_max_closure_chi2 = f64::MAX;
    let (clean, _) = square_with_closures(plain.clone(), false);
    let (dirty, _) = square_with_closures(plain, true);
    let shift = moved(&clean, &dirty);
    eprintln!("without the kernel: moved {shift:.4} m");
    assert!(shift > bound, "moved {shift} m, bound {bound} m");
}

/// The room scan of a robot at (`x0`, `y0`) facing `theta`: [`room_scan`]'s world-frame
/// beams, their angles taken relative to the heading.
fn room_scan_facing(x0: f64, y0: f64, theta: f64) -> slam_models::LaserScan {
    let mut s = room_scan(x0, y0);
    s.angle_min -= theta;
    s
}

/// A turn in place that the odometry measured 1.2 rad too far (far more than the local
/// window's ±0.3 rad, as `perturb-odometry` gives turns in place on fhw and Intel): with
/// the recovery's search over every heading the second keyframe is found at its true
/// heading (the scan's truth, not the front end's output); with the recovery off it is
/// not, so the test fails without it.
#[test]
fn a_turn_the_odometry_got_wrong_is_recovered() {
    let run = |enabled: bool| {
        let mut config = LaserGraphConfig::default();
        config.local_recovery.enabled = enabled;
        let mut f = LaserGraphSlam::new(config, Pose2::IDENTITY, 0).unwrap();
        let (x, y) = (2.5, 1.5);
        // (true heading, odometry heading) of three records turning in place.
        for (i, (truth, odometry)) in [(0.0, 0.0), (0.5, 1.7), (0.9, 2.1)].iter().enumerate() {
            let r = ScanRecord {
                t: i as f64,
                odometry: Pose2::new(x, y, *odometry),
                scan: Some(room_scan_facing(x, y, *truth)),
            };
            f.process(&r).unwrap();
        }
        let tr = f.trajectory();
        let errors: Vec<f64> = [0.5, 0.9]
            .iter()
            .zip(&tr[1..])
            .map(|(truth, p)| slam_models::normalize_angle(p.pose.theta - truth).abs())
            .collect();
        (errors, f.stats().local_match_recovered)
    };
    let (errors, recovered) = run(true);
    assert!(recovered >= 1, "{recovered}");
    for e in &errors {
        assert!(*e < 0.02, "{errors:?}");
    }
    let (errors, recovered) = run(false);
    assert_eq!(recovered, 0);
    assert!(errors[0] > 0.2, "{errors:?}");
}

/// The loop search's sampler is Cartographer's fixed-ratio sampler: after n pulses
/// ⌈ratio·n⌉ were sampled (ratios exact in binary, so the bound is exact), the first
/// always, every one at ratio 1 (the search before sampling existed), and never two in a
/// row at ratio ½.
#[test]
fn loop_sampler_takes_a_fixed_ratio() {
    for ratio in [1.0, 0.5, 0.25, 0.125] {
        let mut s = loops::Sampler::default();
        let mut taken = 0u32;
        let mut previous = false;
        for n in 1..=200u32 {
            let t = s.pulse(ratio);
            if n == 1 {
                assert!(t, "ratio {ratio}: the first pulse");
            }
            if ratio == 0.5 {
                assert!(!(t && previous), "two in a row at pulse {n}");
            }
            previous = t;
            taken += u32::from(t);
            assert_eq!(
                taken,
                (ratio * n as f64).ceil() as u32,
                "ratio {ratio}, n {n}"
            );
        }
    }
}

/// A straight chain of 40 keyframes 0.5 m apart (stiff scan-matching edges, σ = 1 cm and
/// 1 mrad, exact) and `n` loop closures from keyframes 0–9 (one submap) to keyframes 30–39,
/// every one of them 0.1 m off across the chain (a shared error, as the closures into one
/// submap share the submap's): the mean lateral offset of keyframes 30–39 after the
/// keyframe graph's optimisation (no robust kernel).
fn offset_from_shared_closures(n: usize, share: bool) -> f64 {
    let config = LaserGraphConfig {
        closures_share_submap: share,
        optimizer: crate::optimizer::OptimizerConfig {
            closure_kernel: crate::kernel::RobustKernel::None,
            ..LaserGraphConfig::default().optimizer
        },
        ..LaserGraphConfig::default()
    };
    let mut f = LaserGraphSlam::new(config, Pose2::IDENTITY, 0).unwrap();
    let diag = |a: f64, b: f64, c: f64| {
        Matrix3::from_diagonal(&slam_models::Vector3::new(1.0 / a, 1.0 / b, 1.0 / c))
    };
    let scan = room_scan(2.5, 1.5);
    for k in 0..40 {
        let p = Pose2::new(0.5 * k as f64, 0.0, 0.0);
        push_keyframe(&mut f, k, p, &scan);
        if k > 0 {
            f.constraints.push(Constraint {
                from: k - 1,
                to: k,
                z: Pose2::new(0.5, 0.0, 0.0),
                information: diag(1e-4, 1e-4, 1e-6),
                loop_closure: false,
            });
        }
    }
    f.submaps.push(Submap {
        grid: None,
        keyframes: (0..20).collect(),
        finished: true,
        sampler: loops::Sampler::default(),
    });
    f.submaps.push(Submap {
        grid: None,
        keyframes: (10..40).collect(),
        finished: true,
        sampler: loops::Sampler::default(),
    });
    for i in 0..n {
        let (a, b) = (i % 10, 30 + (i * 7) % 10);
        f.constraints.push(Constraint {
            from: a,
            to: b,
            z: Pose2::new(0.5 * (b - a) as f64, 0.1, 0.0),
            information: diag(1e-2, 1e-2, 4e-4),
            loop_closure: true,
        });
    }
    f.optimize_keyframes().unwrap();
    f.keyframes[30..].iter().map(|k| k.global.y).sum::<f64>() / 10.0
}

/// Loop closures into one submap share its errors, so twenty of them must not pull the
/// estimate further than one does (`closures-share-submap`): with the sharing, twenty
/// closures with a common 0.1 m error move the far keyframes within 30 % of what one such
/// closure moves them (one closure of σ = 0.1 m against the stiffer chain moves them by a
/// fraction of the error, under 0.05 m); counted as independent, twenty move them more
/// than twice as far (the test has teeth). Keyframes in no submap are groups of their own (the square test above).
#[test]
fn closures_into_one_submap_weigh_as_one() {
    let one = offset_from_shared_closures(1, true);
    let shared = offset_from_shared_closures(20, true);
    let independent = offset_from_shared_closures(20, false);
    eprintln!("lateral offset: one closure {one:.4} m, 20 shared {shared:.4} m, 20 independent {independent:.4} m");
    assert!(one > 0.0 && one < 0.05, "one closure moved {one} m");
    assert!(
        (shared / one - 1.0).abs() < 0.3,
        "{shared} m against {one} m"
    );
    assert!(
        independent > 2.0 * one && independent > 0.05,
        "{independent} m"
    );
}

/// A constraint's edge information is the inverse of its error's covariance: with z's
/// translation noisy with covariance C in `from`'s frame (and θ with its own variance and
/// a cross term), the error e = z⁻¹ ⊕ rel (g2o's `EDGE_SE2`, θ normalised) has covariance
/// J C Jᵀ, J = ∂e/∂z by central differences at z = rel. Checked at relative headings of
/// 0, ±90° and 180° with an anisotropic C (a corridor's: 10 × longer along x): taken in
/// `from`'s frame unturned, the information would be wrong by the anisotropy at ±90°.
#[test]
fn edge_information_is_the_error_covariance_inverse() {
    let c = Matrix3::new(
        0.04, 0.0, 0.002, //
        0.0, 0.0004, 0.0, //
        0.002, 0.0, 0.0004,
    );
    for theta in [
        0.0,
        1.3,
        std::f64::consts::FRAC_PI_2,
        -std::f64::consts::FRAC_PI_2,
        3.0,
    ] {
        let rel = Pose2::new(2.0, -1.0, theta);
        let e = |z: &Pose2| {
            let d = z.between(&rel);
            slam_models::Vector3::new(d.x, d.y, slam_models::normalize_angle(d.theta))
        };
        let h = 1e-6;
        let mut j = Matrix3::zeros();
        for u in 0..3 {
            let mut plus = [rel.x, rel.y, rel.theta];
            let mut minus = plus;
            plus[u] += h;
            minus[u] -= h;
            let ep = e(&Pose2::new(plus[0], plus[1], plus[2]));
            let em = e(&Pose2::new(minus[0], minus[1], minus[2]));
            j.set_column(u, &((ep - em) / (2.0 * h)));
        }
        let expected = (j * c * j.transpose()).try_inverse().unwrap();
        let constraint = Constraint {
            from: 0,
            to: 1,
            z: rel,
            information: c.try_inverse().unwrap(),
            loop_closure: true,
        };
        let got = constraint.edge_information();
        let scale = expected.norm();
        assert!(
            (got - expected).norm() < 1e-5 * scale,
            "θ {theta}: {got} against {expected}"
        );
        if theta.abs() > 1.0 && theta.abs() < 2.0 {
            assert!((constraint.information - expected).norm() > 0.5 * scale);
        }
    }
}
