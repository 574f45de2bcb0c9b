//! Simulated checks against the simulator's ground truth: a kidnapped robot (teleported
//! by the simulator, its odometry unaware) is re-localized, and global localization in a
//! symmetric world is never confidently wrong for long.

use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;
use slam_mcl::{InitialBelief, Mcl, MclConfig, MclMap};
use slam_models::{Pose2, ScanRecord};
use slam_sim::laser::{LaserScanner, Segment, World};
use slam_sim::path::Path;
use slam_sim::scenario::laser::{office_path, office_world};

/// The robot drives `path` in 0.25 m steps for `length` metres from arc length `s0`; at
/// arc length `teleport.0` (if any) the simulator moves it to arc length `teleport.1`
/// without the odometry noticing. Odometry: the true increments with 2 % translation and
/// 1° per metre heading noise (seeded). Returns, per step, the filter's estimate, its
/// spread and the truth, with the distance travelled.
fn drive(
    world: &World,
    path: &Path,
    mcl: &mut Mcl,
    s0: f64,
    length: f64,
    teleport: Option<(f64, f64)>,
) -> Vec<(f64, Pose2, f64, Pose2)> {
    let scanner = LaserScanner::default();
    let mut rng = Pcg64Mcg::seed_from_u64(5);
    let pose_at = |s: f64| {
        let s = s.rem_euclid(path.length());
        let p = path.point_at(s);
        Pose2::new(p.x, p.y, path.heading_at(s))
    };
    let mut odom = Pose2::new(0.0, 0.0, 0.0);
    let mut s = s0;
    let mut prev = pose_at(s);
    let mut out = Vec::new();
    let mut travelled = 0.0;
    let mut k = 0;
    while travelled < length {
        let truth = pose_at(s);
        let d = prev.between(&truth);
        let noise = 1.0 + 0.02 * slam_models::sampling::standard_normal(&mut rng);
        let dth = 0.0175 * d.x.hypot(d.y) * slam_models::sampling::standard_normal(&mut rng);
        odom = odom.compose(&Pose2::new(d.x * noise, d.y * noise, d.theta + dth));
        let scan = scanner.scan(world, &truth, &mut rng);
        let info = mcl
            .process(&ScanRecord {
                t: k as f64 * 0.25,
                odometry: odom,
                scan: Some(scan),
            })
            .unwrap();
        out.push((travelled, info.pose, info.spread, truth));
        prev = truth;
        s += 0.25;
        travelled += 0.25;
        k += 1;
        if let Some((at, to)) = teleport {
            if (s - s0 - at).abs() < 0.125 {
                s = to;
                prev = pose_at(s); // the odometry does not see the jump
            }
        }
    }
    out
}

/// Kidnapped after 20 m along the office corridor, carried 30 m further along it: the
/// filter, sure of the old place, must notice (w_fast falls below w_slow), spread random
/// particles and find the robot again. Measured (seed 3): back within 0.3 m after
/// ≈ 9 m; the bound is 25 m, and it must then stay within 0.3 m.
#[test]
fn a_kidnapped_robot_is_found_again() {
    let world = office_world();
    let path = office_path();
    let config = MclConfig::default();
    let map = MclMap::new(world.rasterize(0.05, 1.0).unwrap(), &config).unwrap();
    let s0 = 2.0;
    let p = path.point_at(s0);
    let start = Pose2::new(p.x, p.y, path.heading_at(s0));
    let mut mcl = Mcl::new(
        config,
        map,
        InitialBelief::Gaussian {
            mean: start,
            sigma: [0.1, 0.1, 0.05],
        },
        3,
    )
    .unwrap();
    let steps = drive(&world, &path, &mut mcl, s0, 60.0, Some((20.0, s0 + 50.0)));
    let err = |(_, e, _, t): &(f64, Pose2, f64, Pose2)| e.distance(t);
    // Tracking before the kidnapping.
    assert!(steps
        .iter()
        .filter(|s| s.0 > 2.0 && s.0 < 20.0)
        .all(|s| err(s) < 0.3));
    // Lost right after it.
    let after: Vec<_> = steps.iter().filter(|s| s.0 > 20.0).collect();
    assert!(err(after[1]) > 5.0, "the teleport did not move the robot");
    // Found again: the first step from which the error stays below 0.3 m.
    let last_bad = after.iter().rposition(|s| err(s) >= 0.3).unwrap();
    let found_after = after[last_bad + 1].0 - 20.0;
    eprintln!("re-localized {found_after:.1} m after the kidnapping");
    assert!(
        found_after <= 25.0,
        "re-localized only after {found_after} m"
    );
}

/// A world with a 180° rotational symmetry about (10, 5): a 20 m × 10 m hall with two
/// identical boxes placed point-symmetrically, and one small pillar that breaks the
/// symmetry near one end.
fn symmetric_hall() -> World {
    let mut s = Vec::new();
    let mut rect = |x0: f64, y0: f64, x1: f64, y1: f64| {
        s.push(Segment::new(x0, y0, x1, y0));
        s.push(Segment::new(x1, y0, x1, y1));
        s.push(Segment::new(x1, y1, x0, y1));
        s.push(Segment::new(x0, y1, x0, y0));
    };
    rect(0.0, 0.0, 20.0, 10.0);
    rect(4.0, 2.0, 6.0, 4.0);
    rect(14.0, 6.0, 16.0, 8.0);
    rect(18.5, 8.5, 19.0, 9.0);
    World::new(s).unwrap()
}

/// Global localization in the symmetric hall, driving a loop around the boxes: at every
/// step the cloud is either wide (spread ≥ 0.5 m, "multi-modal or unsure") or its estimate
/// within 0.5 m of the truth; "confident and wrong" may last at most 15 m of travel in
/// all. KNOWN FAILURE (seed 1): the cloud collapses onto the mirrored mode within the
/// first metres and stays there, confidently wrong for 87 of 90 m: the small pillar that
/// breaks the symmetry costs the wrong mode too little with `weight-exponent` 0.2 for
/// augmented MCL to notice. Kept, ignored, as the target of the open part of issue 35.
#[test]
#[ignore = "known failure: confidently wrong for 87 m of 90 m (issue 35, open)"]
fn global_localization_in_a_symmetric_world_is_never_confidently_wrong_for_long() {
    let world = symmetric_hall();
    let path = Path::rounded(
        &[
            slam_models::Point2::new(2.0, 1.0),
            slam_models::Point2::new(18.0, 1.0),
            slam_models::Point2::new(18.0, 9.0),
            slam_models::Point2::new(2.0, 9.0),
        ],
        true,
        0.8,
        0.05,
    )
    .unwrap();
    let config = MclConfig::default();
    let map = MclMap::new(world.rasterize(0.05, 0.5).unwrap(), &config).unwrap();
    let mut mcl = Mcl::new(config, map, InitialBelief::Global, 1).unwrap();
    let steps = drive(&world, &path, &mut mcl, 0.0, 90.0, None);
    let wrong: f64 = steps
        .iter()
        .filter(|(_, e, spread, t)| *spread < 0.5 && e.distance(t) > 0.5)
        .count() as f64
        * 0.25;
    eprintln!("confidently wrong for {wrong:.2} m of 90 m");
    assert!(wrong <= 15.0, "confidently wrong for {wrong} m");
    // And it ends converged on the truth.
    let (_, e, spread, t) = steps.last().unwrap();
    assert!(
        *spread < 0.5 && e.distance(t) < 0.3,
        "{e:?} vs {t:?}, spread {spread}"
    );
}
