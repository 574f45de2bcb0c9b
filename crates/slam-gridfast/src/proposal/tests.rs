//! The proposals on small simulated corridors and rooms: the gain, the start rule, the
//! wide search's trigger and acceptance.

use super::*;
use crate::matcher::field;
use crate::matcher::tests::{empty_map, room_map, room_scan};
use crate::setup::sample_offsets;
use rand::SeedableRng;

/// The gain tempers the weight and nothing else: for the same σ and random stream,
/// gains 1 and 3 draw the same pose, and the weights are η over p(z | m, xⱼ)^(1/g),
/// recomputed here from the K samples independently of the function.
#[test]
fn the_gain_tempers_the_weight_not_the_proposal() {
    let mut map = empty_map();
    for p in [Pose2::new(0.0, 0.0, 0.0), Pose2::new(-1.0, -0.5, 1.0)] {
        map.integrate_scan(&p, &room_scan(&p));
    }
    let truth = Pose2::new(0.3, 0.4, 0.3);
    let scan = RangeData::with_limits(&room_scan(&truth), &Default::default(), 0.0, 50.0).unwrap();
    let motion = OdometryModel::new([0.05, 0.002, 0.02, 0.002]);
    let previous = Pose2::new(0.0, 0.0, 0.0);
    // Odometry that overshoots the true pose by a few centimetres.
    let u = motion.control_from_poses(&previous, &Pose2::new(0.33, 0.37, 0.31));
    // The indoor preset (σ 0.05 m, r 0.15 m, capture 0.2 m, 3³ samples over ±1 cm /
    // ±0.005 rad, that motion model) with climbing steps of 0.05 m / 0.05 rad, no
    // recovery, a match failing below 5 % of the beams.
    let draw = |gain: f64| {
        let setup = indoor_setup(|c| {
            c.matching.gain = gain;
            c.matching.linear_step = Some(0.05);
            c.matching.angular_step = 0.05;
            c.matching.min_inlier_fraction = 0.05;
            c.matching.recovery.trigger_fraction = 0.0;
        });
        assert_eq!((setup.likelihood.radius, setup.capture.radius), (0.15, 0.2));
        assert_eq!(setup.odometry, motion);
        let step = Step {
            setup: &setup,
            scan: &scan,
            u,
            correction: Pose2::IDENTITY,
        };
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
        let drawn = improved(&previous, &map, &field(&map), &step, &mut rng);
        (drawn, setup)
    };
    let (d1, _) = draw(1.0);
    let (d3, ctx3) = draw(3.0);
    let offsets = &ctx3.offsets;
    assert!(!d1.match_failed && !d3.match_failed);
    assert!(
        d1.pose.distance(&d3.pose) < 1e-9,
        "{:?} vs {:?}",
        d1.pose,
        d3.pose
    );
    assert!((d1.pose.theta - d3.pose.theta).abs() < 1e-9);
    assert!(d1.pose.distance(&truth) < 0.03, "{:?}", d1.pose);
    // η with the tempered likelihood, from the mode the matcher finds.
    let predicted = motion.predict(&previous, &u);
    let m = hill_climb(
        &field(&map),
        &scan,
        &predicted,
        &ctx3.capture,
        &ctx3.likelihood,
        &ctx3.climb,
    );
    // The samples' end points: every 2nd, scaled to the whole scan.
    let half = scan.half_points();
    let scale = scan.points().len() as f64 / half.len() as f64;
    let cov = motion.noise_covariance(&previous, &u) + Matrix3::from_diagonal(&ctx3.min_var);
    let (inv, det) = (cov.try_inverse().unwrap(), cov.determinant());
    let log_tau: Vec<f64> = offsets
        .iter()
        .map(|o| {
            let xj = Pose2::new(m.pose.x + o[0], m.pose.y + o[1], m.pose.theta + o[2]);
            let l = scale * score(&field(&map), half, &xj, &ctx3.likelihood).log_likelihood;
            let e = Vector3::new(
                xj.x - predicted.x,
                xj.y - predicted.y,
                xj.theta - predicted.theta,
            );
            l - 0.5 * (e.dot(&(inv * e)) + det.ln())
        })
        .collect();
    let top = log_tau.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let log_eta = top + log_tau.iter().map(|t| (t - top).exp()).sum::<f64>().ln();
    assert!(
        (d3.log_weight - log_eta).abs() < 1e-6,
        "{} vs {log_eta}",
        d3.log_weight
    );
    assert!(d1.log_weight < d3.log_weight);
}

/// A wall segment, from one end point (x, y) to the other, metres.
type Segment = ((f64, f64), (f64, f64));

/// A 361-beam, 360° scan from `pose` of the walls `segments`: each reading the range to
/// the nearest wall along the beam, readings from `max_range` on (and beams that meet
/// no wall) no returns at `max_range`.
fn scan_of(segments: &[Segment], pose: &Pose2, max_range: f64) -> slam_models::LaserScan {
    let n = 361;
    let inc = std::f64::consts::TAU / n as f64;
    let ranges = (0..n)
        .map(|k| {
            let a = pose.theta - std::f64::consts::PI + k as f64 * inc;
            let d = (a.cos(), a.sin());
            let mut best = f64::INFINITY;
            for &((px, py), (qx, qy)) in segments {
                // The ray pose + t·d against the segment p + u·(q − p), u in [0, 1].
                let e = (qx - px, qy - py);
                let den = d.0 * e.1 - d.1 * e.0;
                if den.abs() < 1e-12 {
                    continue;
                }
                let w = (px - pose.x, py - pose.y);
                let t = (w.0 * e.1 - w.1 * e.0) / den;
                let u = (w.0 * d.1 - w.1 * d.0) / den;
                if t > 0.0 && (0.0..=1.0).contains(&u) {
                    best = best.min(t);
                }
            }
            best.min(max_range)
        })
        .collect();
    slam_models::LaserScan {
        angle_min: -std::f64::consts::PI,
        angle_increment: inc,
        ranges,
        max_range,
        sensor_pose: Pose2::IDENTITY,
    }
}

/// A corridor from x = −20 to 20 m whose walls are saw-toothed with a period of one
/// metre (y = ±1 at whole metres, ±1.3 half-way): shifted by one metre along x it looks
/// the same, and every wall beam says where along the period the robot is.
fn corridor_scan(pose: &Pose2, max_range: f64) -> slam_models::LaserScan {
    let mut segments = vec![((-20.0, -1.0), (-20.0, 1.0)), ((20.0, -1.0), (20.0, 1.0))];
    for k in -20..20 {
        let x0 = k as f64;
        for s in [-1.0, 1.0] {
            segments.push(((x0, s * 1.0), (x0 + 0.5, s * 1.3)));
            segments.push(((x0 + 0.5, s * 1.3), (x0 + 1.0, s * 1.0)));
        }
    }
    scan_of(&segments, pose, max_range)
}

/// The indoor preset's setup ([`crate::Preset::Indoor`]: σ 0.05 m, r 0.15 m, capture
/// 0.2 m, gain 3, steps 0.1 m / 0.1 rad halved 6 times, 3³ samples over ±1 cm / ±0.3°,
/// Intel's motion model), changed by `edit`.
fn indoor_setup(edit: impl FnOnce(&mut crate::GridFastConfig)) -> Setup {
    let mut c = crate::GridFastConfig {
        preset: crate::Preset::Indoor,
        ..Default::default()
    };
    edit(&mut c);
    Setup::new(&c.resolve(None).unwrap()).unwrap()
}

/// One particle's draw with `setup`, moving from `previous` to where the odometry
/// says, `to`, with the best particle's coarse correction `correction`.
fn indoor_draw(
    map: &slam_grid::OccupancyGrid,
    scan: &RangeData,
    (previous, to): (Pose2, Pose2),
    correction: Pose2,
    setup: &Setup,
) -> Drawn {
    let step = Step {
        setup,
        scan,
        u: setup.odometry.control_from_poses(&previous, &to),
        correction,
    };
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(3);
    improved(&previous, map, &field(map), &step, &mut rng)
}

/// The indoor preset's recovery (trigger 40 %, ±1.5 m, ±0.9 rad), counted among all
/// the beams or among the observed ones, taking a wide match with at least
/// `accept_fraction` of the beams on the map (no recovery when `None`).
fn indoor_recovery(recovery: Option<(bool, f64)>) -> impl FnOnce(&mut crate::GridFastConfig) {
    move |c| {
        let rc = &mut c.matching.recovery;
        match recovery {
            Some((observed_only, accept_fraction)) => {
                rc.observed_only = observed_only;
                rc.accept_fraction = accept_fraction;
            }
            None => rc.trigger_fraction = 0.0,
        }
    }
}

/// The csail failure in miniature (docs/gridfast.md): the map holds the corridor only up
/// to about `last` + 1.3 m (24 scans with a 1.6 m range from x ≤ `last`), the robot
/// moved from x = 1.1 to 1.9 m with exact odometry, and its 361-beam scan looks mostly
/// into the part not yet mapped. The beams the map can judge fit the true pose, but the
/// alias one metre back (every tooth on a tooth) puts more beams on mapped walls.
/// Returns the true pose and the particle's draw for the given start rule, coarse
/// correction and recovery (min-inlier fraction 5 %).
fn corridor_draw(
    last: f64,
    start_choice: StartChoice,
    correction: Pose2,
    recovery: Option<(bool, f64)>,
) -> (Pose2, Drawn) {
    let mut map = empty_map();
    for k in 0..24 {
        let x = last - 0.5 * k as f64;
        let p = Pose2::new(x, 0.05, 0.02 * k as f64);
        map.integrate_scan(&p, &corridor_scan(&p, 1.6));
    }
    let truth = Pose2::new(1.9, 0.1, 0.05);
    let previous = Pose2::new(1.1, 0.05, 0.0);
    let scan = RangeData::with_limits(&corridor_scan(&truth, 30.0), &Default::default(), 0.0, 29.9)
        .unwrap();
    let setup = indoor_setup(|c| {
        c.matching.min_inlier_fraction = 0.05;
        c.matching.start_choice = start_choice;
        indoor_recovery(recovery)(c);
    });
    let drawn = indoor_draw(&map, &scan, (previous, truth), correction, &setup);
    (truth, drawn)
}

/// The indoor preset's recovery (±1.5 m, ±0.9 rad), counted among all the beams or
/// among the observed ones; any wide match with more inliers is accepted
/// (`accept-fraction` 0), so that only the trigger is tested.
fn corridor_recovery(observed_only: bool) -> Option<(bool, f64)> {
    Some((observed_only, 0.0))
}

/// A scan looking into space not yet mapped is no poor match when the beams the map can
/// judge fit: counted among those (`observed-only`), the particle keeps the true pose;
/// counted among all the beams, the wide search replaces it by the alias a metre away.
#[test]
fn a_scan_into_new_space_does_not_trigger_the_wide_search() {
    // Mapped up to x ≈ 1 m: 26 % of the beams find the map at the true pose, all of
    // those the map can judge; 51 % at the alias.
    let (truth, kept) = corridor_draw(
        -0.3,
        StartChoice::Posterior,
        Pose2::IDENTITY,
        corridor_recovery(true),
    );
    assert!(!kept.match_recovered && !kept.match_failed);
    // Within the climber's reach of the truth (the map's edge pulls it a few cm).
    assert!(
        kept.pose.distance(&truth) < 0.1
            && normalize_angle(kept.pose.theta - truth.theta).abs() < 0.02,
        "{:?} against the truth {truth:?}",
        kept.pose
    );
    let (_, lost) = corridor_draw(
        -0.3,
        StartChoice::Posterior,
        Pose2::IDENTITY,
        corridor_recovery(false),
    );
    assert!(lost.match_recovered);
    assert!(lost.pose.distance(&truth) > 0.5, "{:?}", lost.pose);
}

/// When the best particle's coarse correction points at the alias (it fits more beams),
/// the posterior rule keeps the match the motion prior supports, the true pose; the
/// coarse-score rule climbs from the alias and stays there.
#[test]
fn the_start_is_chosen_by_likelihood_times_motion_prior() {
    // Mapped up to x ≈ −1 m: the alias's likelihood is 25 nats larger (51 against 34
    // beams on the map), its motion prior far smaller (1 m off a 0.8 m step whose
    // translation deviation is 0.11 m).
    let alias = Pose2::new(-1.0, 0.0, 0.0);
    let (truth, kept) = corridor_draw(-2.3, StartChoice::Posterior, alias, None);
    assert!(
        kept.pose.distance(&truth) < 0.1
            && normalize_angle(kept.pose.theta - truth.theta).abs() < 0.02,
        "{:?} against the truth {truth:?}",
        kept.pose
    );
    let (_, lost) = corridor_draw(-2.3, StartChoice::CoarseScore, alias, None);
    assert!(lost.pose.distance(&truth) > 0.5, "{:?}", lost.pose);
}

#[test]
fn offsets_are_a_symmetric_grid() {
    let o = sample_offsets(3, 0.01, 0.005);
    assert_eq!(o.len(), 27);
    let s: [f64; 3] = o
        .iter()
        .fold([0.0; 3], |a, b| [a[0] + b[0], a[1] + b[1], a[2] + b[2]]);
    assert!(s.iter().all(|v| v.abs() < 1e-12));
    assert!(o.contains(&[-0.01, 0.01, 0.005]));
    assert_eq!(sample_offsets(1, 0.01, 0.005), vec![[0.0, 0.0, 0.0]]);
}

/// A corridor (walls at y = ±1 m) with a rib 0.4 m deep on each wall every
/// `RIB_PERIOD` metres, scanned with 361 beams over 360° up to 3 m: a repetitive
/// structure in which a scan shifted by whole periods fits the walls again.
const RIB_PERIOD: f64 = 0.7;

fn ribbed_corridor_scan(pose: &Pose2) -> slam_grid::LaserScan {
    let mut walls = vec![((-20.0, 1.0), (20.0, 1.0)), ((-20.0, -1.0), (20.0, -1.0))];
    for i in -30..=30 {
        let x = RIB_PERIOD * i as f64;
        walls.push(((x, 1.0), (x, 0.6)));
        walls.push(((x, -1.0), (x, -0.6)));
    }
    scan_of(&walls, pose, 3.0)
}

/// Issue 21, fhw: where the robot faces space not yet mapped, its true pose fits few
/// beams (here 29 %: the match is poor and the wide search runs), while in a repetitive
/// structure a pose two rib periods (1.4 m) back fits more (56 %). The odometry is
/// exact. The wide search's match used to replace the local one whenever more beams
/// found the map there, and the particle jumped to the alias; with
/// `recovery.accept-fraction` (0.6 by default) it keeps its local match at the truth.
#[test]
fn a_wide_match_in_unmapped_space_needs_most_beams_on_the_map() {
    let mut map = empty_map();
    // The corridor mapped up to x ≈ 0 (scans from x = −6 … −3 reaching 3 m).
    for i in 0..5 {
        let p = Pose2::new(-6.0 + i as f64 * 0.75, 0.0, 0.0);
        map.integrate_scan(&p, &ribbed_corridor_scan(&p));
    }
    let truth = Pose2::new(0.0, 0.0, 0.0);
    let previous = Pose2::new(-1.0, 0.0, 0.0);
    let scan = RangeData::with_limits(
        &ribbed_corridor_scan(&truth),
        &Default::default(),
        0.0,
        2.999,
    )
    .unwrap();
    // The trigger counted among all the beams (`observed-only` off), so that the wide
    // search runs and only the acceptance rule is tested.
    let draw = |accept_fraction: f64| {
        let setup = indoor_setup(indoor_recovery(Some((false, accept_fraction))));
        indoor_draw(&map, &scan, (previous, truth), Pose2::IDENTITY, &setup)
    };
    let kept = draw(crate::RecoveryConfig::default().accept_fraction);
    assert!(!kept.match_recovered && !kept.match_failed);
    assert!(
        kept.pose.distance(&truth) < 0.05 && kept.pose.theta.abs() < 0.02,
        "{:?}",
        kept.pose
    );
    // Taking the wide match whenever more beams fit (the rule before) jumps to the alias.
    let jumped = draw(0.0);
    assert!(jumped.match_recovered);
    assert!(jumped.pose.distance(&truth) > 1.0, "{:?}", jumped.pose);
}

/// A turn in place in the room of [`room_scan`] that the odometry measured +0.89 rad for
/// a true −0.35 rad (1.24 rad off, 6σ of the motion model: fhw's scan 62 on
/// `perturb-odometry --seed 2 --profile hard`, docs/gridfast.md). Returns the true pose
/// and the particle's draw with `edit` applied to the indoor preset.
fn missed_turn_draw(edit: impl FnOnce(&mut crate::GridFastConfig)) -> (Pose2, Drawn) {
    let map = room_map();
    let previous = Pose2::new(-0.5, 0.4, 0.3);
    let truth = Pose2::new(-0.5, 0.4, 0.3 - 0.35);
    let measured = Pose2::new(-0.5, 0.4, 0.3 + 0.89);
    let scan = RangeData::with_limits(&room_scan(&truth), &Default::default(), 0.0, 29.9).unwrap();
    let setup = indoor_setup(edit);
    let drawn = indoor_draw(&map, &scan, (previous, measured), Pose2::IDENTITY, &setup);
    (truth, drawn)
}

/// The heading the odometry got 1.24 rad wrong on a turn in place lies outside the wide
/// window (±0.9 rad): only the turn search (every heading at the predicted position)
/// finds the true pose; with it off (`turn-trigger` above the turn) the particle stays
/// off by more than 0.3 rad.
#[test]
fn a_turn_the_odometry_got_wrong_is_found_by_the_turn_search() {
    let (truth, found) = missed_turn_draw(|_| {});
    assert!(found.match_recovered && !found.match_failed);
    assert!(
        found.pose.distance(&truth) < 0.05
            && normalize_angle(found.pose.theta - truth.theta).abs() < 0.02,
        "{:?} against the truth {truth:?}",
        found.pose
    );
    let (_, lost) = missed_turn_draw(|c| c.matching.recovery.turn_trigger = 10.0);
    assert!(
        normalize_angle(lost.pose.theta - truth.theta).abs() > 0.3,
        "{:?}",
        lost.pose
    );
}

/// The recovered particle's weight is the normaliser of the proposal under the mixture
/// (1 − ε)·N(x′, R) + ε·N(x′, R + W): 6σ from x′ (σ_θ 0.2 rad for this turn) the first
/// component is ~e⁻¹⁹ of the second, so η scales with ε/(1 − ε), and ln η moves by the log-odds ratio between two
/// values of `outlier-weight` (the same pose drawn: the proposal itself barely changes).
#[test]
fn the_recovered_weight_carries_the_outlier_prior() {
    let draw = |eps: f64| missed_turn_draw(|c| c.matching.recovery.outlier_weight = eps).1;
    let (a, b) = (draw(0.01), draw(0.1));
    assert!(a.match_recovered && b.match_recovered);
    // (The samples' relative weights change by the first component's share, ~e⁻¹⁹.)
    assert!(
        a.pose.distance(&b.pose) < 1e-6 && (a.pose.theta - b.pose.theta).abs() < 1e-6,
        "{:?} vs {:?}",
        a.pose,
        b.pose
    );
    let expected = (0.1f64 / 0.9).ln() - (0.01f64 / 0.99).ln();
    let got = b.log_weight - a.log_weight;
    // Less the first component's share of η, which is ε/(1 − ε)·e⁻¹⁹·det ratio ~ 10⁻⁴
    // of the broad one's at ε = 0.01.
    assert!((got - expected).abs() < 1e-3, "{got} vs {expected}");
}
