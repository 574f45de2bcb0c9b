//! Simulated checks against the simulator's ground truth: a kidnapped robot (teleported
//! by the simulator, its odometry unaware) is re-localized, and global localization in a
//! symmetric world is never confidently wrong for long.

use slam_mcl::{InitialBelief, Mcl, MclConfig, MclMap};
use slam_models::Pose2;
use slam_sim::laser::{simulate_laser, LaserScanner, LaserSimConfig, Segment, Teleport, World};
use slam_sim::path::Path;
use slam_sim::scenario::laser::{office_path, office_world};

/// One row per record: distance the true robot drove so far (a teleport adds nothing),
/// the filter's estimate, its cloud spread, the truth, and the modes the filter reported
/// at its last update.
type Row = (f64, Pose2, f64, Pose2, usize);

/// slam-sim drives the robot along `path` (0.8 m/s, odometry every 0.1 s, a scan every
/// third record, odometry α = (0.02, 0.002, 0.02, 0.001), 181 beams over 180°, 20 m,
/// σ 1 cm), `scans` scans, with the kidnappings `teleports`; every record is fed to the
/// filter.
fn drive(
    world: &World,
    path: &Path,
    mcl: &mut Mcl,
    scans: usize,
    teleports: &[Teleport],
) -> Vec<Row> {
    let cfg = LaserSimConfig {
        scans,
        teleports: teleports.to_vec(),
        scanner: LaserScanner {
            beams: 181,
            max_range: 20.0,
            sigma: 0.01,
            ..LaserScanner::default()
        },
        ..LaserSimConfig::default()
    };
    let run = simulate_laser(world, path, &cfg, 5).unwrap();
    let gt = run.dataset.ground_truth.as_ref().unwrap();
    let mut travelled = 0.0;
    let mut out = Vec::with_capacity(gt.len());
    let mut modes = 0;
    for (k, (r, truth)) in run.dataset.records.iter().zip(gt).enumerate() {
        if k > 0 && !teleports.iter().any(|t| t.record == k) {
            travelled += gt[k - 1].pose.distance(&truth.pose);
        }
        let info = mcl.process(r).unwrap();
        if info.updated {
            modes = info.modes;
        }
        out.push((travelled, info.pose, info.spread, truth.pose, modes));
    }
    out
}

/// Kidnapped after 20 m along the office corridor: slam-sim carries the robot to the
/// path's pose 30 m further on (`Teleport`: the truth jumps, the odometry does not). The
/// filter, sure of the old place, must notice (w_fast falls below w_slow), spread random
/// particles and find the robot again. Measured (seed 3): back within 0.3 m after
/// 5.0 m; the bound is 25 m, and it must then stay within 0.3 m.
#[test]
fn a_kidnapped_robot_is_found_again() {
    let world = office_world();
    let path = office_path();
    let config = MclConfig::default();
    let map = MclMap::new(world.rasterize(0.05, 1.0).unwrap(), &config).unwrap();
    let mut mcl = Mcl::new(
        config,
        map,
        InitialBelief::Gaussian {
            mean: path.start_pose(),
            sigma: [0.1, 0.1, 0.05],
        },
        3,
    )
    .unwrap();
    // 0.08 m per record: record 250 is 20 m along.
    let kidnap = Teleport {
        record: 250,
        to: 50.0,
    };
    let steps = drive(&world, &path, &mut mcl, 250, &[kidnap]);
    let err = |(_, e, _, t, _): &Row| e.distance(t);
    let at = steps[kidnap.record].0;
    // Tracking before the kidnapping.
    assert!(steps[..kidnap.record]
        .iter()
        .filter(|s| s.0 > 2.0)
        .all(|s| err(s) < 0.3));
    // Lost right after it.
    let after = &steps[kidnap.record..];
    assert!(err(&after[1]) > 5.0, "the teleport did not move the robot");
    // Found again: the first step from which the error stays below 0.3 m.
    let last_bad = after.iter().rposition(|s| err(s) >= 0.3).unwrap();
    assert!(last_bad + 1 < after.len(), "not found again by the end");
    let found_after = after[last_bad + 1].0 - at;
    eprintln!(
        "re-localized {found_after:.1} m after the kidnapping ({:.1} m driven after it)",
        steps.last().unwrap().0 - at
    );
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
/// step the cloud is either wide (spread ≥ 0.5 m: unsure, or several places at once) or
/// its estimate within 0.5 m of the truth; "confident and wrong" may last at most 5 m of
/// travel in all (issue 35's stated distance), and the run must end on the truth. The
/// modes kept by clustered resampling hold the mirrored place and the true one side by
/// side until the pillar tells them apart; the filter reports the two (`modes` ≥ 2) on
/// the way. Seeds 1–5 (measured: 0 m confidently wrong on each, up to 2–12 modes). Before
/// the global start's own tempering floor (`sensor.global-min-n-eff-ratio` 0.1 while
/// converging) seed 1 was confidently wrong for 58.6 of 59.5 m: the mirrored mode won the
/// first metres.
#[test]
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
    for seed in [1, 2, 3, 4, 5] {
        let config = MclConfig::default();
        let map = MclMap::new(world.rasterize(0.05, 0.5).unwrap(), &config).unwrap();
        let mut mcl = Mcl::new(config, map, InitialBelief::Global, seed).unwrap();
        // 250 scans, 0.24 m apart: 60 m, the loop once and a half.
        let steps = drive(&world, &path, &mut mcl, 250, &[]);
        let wrong: f64 = steps
            .windows(2)
            .filter(|w| {
                let (_, e, spread, t, _) = w[1];
                spread < 0.5 && e.distance(&t) > 0.5
            })
            .map(|w| w[1].0 - w[0].0)
            .sum();
        let total = steps.last().unwrap().0;
        let most_modes = steps.iter().map(|r| r.4).max().unwrap();
        eprintln!(
            "seed {seed}: confidently wrong for {wrong:.2} m of {total:.1} m, up to {most_modes} modes"
        );
        assert!(wrong <= 5.0, "seed {seed}: confidently wrong for {wrong} m");
        assert!(most_modes >= 2, "seed {seed}: never reported two places");
        // And it ends converged on the truth.
        let (_, e, spread, t, _) = steps.last().unwrap();
        assert!(
            *spread < 0.5 && e.distance(t) < 0.3,
            "seed {seed}: {e:?} vs {t:?}, spread {spread}"
        );
    }
}
