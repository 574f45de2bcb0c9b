//! Grid-based FastSLAM (slam-gridfast) against ground truth: the simulated office (slam-sim:
//! two laps of a corridor loop with biased odometry) — the loop closes, every proposal beats
//! dead reckoning, and the output does not depend on the thread count — and a prefix of
//! the Intel benchmark log (real scans, recovered odometry), scored by the Kümmerle et al.
//! 2009 relations with slam-io.

/// A closed loop in the office, metres of position RMSE against the truth, for the median
/// of five filter seeds: scan matching without loop closure drifts 0.17 m over the two laps
/// of seed 3 (`slam run --filter scanmatch`; 0.78 m before it used the endpoint model), dead reckoning 1.3–3.3 m (seeds 1–7); the
/// improved proposal with 8 particles on seed 3 scores 0.05–0.14 m with filter seeds 1–5.
/// Single runs have a tail: filter seed 42 scores 0.27 m, a consistent map whose long
/// corridors came out ≈ 0.2 m short (0.19 m after SE(2) alignment).
const LOOP_CLOSED_RMSE: f64 = 0.2;

mod common;

use slam::gridfast::{GridFastConfig, GridFastSlam, Proposal, ProposalConfig};
use slam::models::{Pose2, ScanRecord, TimedPose};
use slam::sim::scenario::{generate, ScenarioOptions};
use slam::sim::SimOutput;

/// Runs the filter (seed 42) over `records` on a pool of `threads` threads: its trajectory
/// and the number of processed scans.
fn run(records: &[ScanRecord], config: GridFastConfig, threads: usize) -> (Vec<TimedPose>, usize) {
    run_seeded(records, config, threads, 42)
}

/// [`run`] with the filter's seed given.
fn run_seeded(
    records: &[ScanRecord],
    config: GridFastConfig,
    threads: usize,
    seed: u64,
) -> (Vec<TimedPose>, usize) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let mut slam = GridFastSlam::new(config, Pose2::IDENTITY, seed).unwrap();
    let run = pool.install(|| common::run_scans(&mut slam, records));
    let processed = run.updates.iter().map(|u| u.processed_scan as usize).sum();
    (run.trajectory, processed)
}

/// The median of a few values.
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The output does not depend on the thread count, and the run beats dead reckoning
/// fivefold; whether the loop closes is judged on the median of five filter seeds in
/// [`every_proposal_beats_dead_reckoning_in_the_office`] (one run is a lottery).
#[test]
fn office_output_is_thread_count_independent() {
    let (records, truth) = common::office(3);
    let odo_err = common::rmse(&common::dead_reckoning(&records), &truth);
    let config = GridFastConfig {
        particles: 8,
        ..Default::default()
    };
    let (one, processed) = run(&records, config.clone(), 1);
    let (two, _) = run(&records, config, 2);
    // One pose per input record, scans skipped between updates.
    assert_eq!(one.len(), records.len());
    assert!(
        processed > 40 && processed < records.len() / 3,
        "{processed} updates"
    );
    // Bit-identical whatever the thread count.
    assert!(one
        .iter()
        .zip(&two)
        .all(|(a, b)| a.pose == b.pose && a.t == b.t));
    let err = common::rmse(&one, &truth);
    eprintln!("office: odometry RMSE {odo_err:.3} m, gridfast improved RMSE {err:.3} m");
    assert!(
        odo_err > 1.0,
        "the odometry must be bad for the test to mean anything: {odo_err}"
    );
    assert!(err < 0.2 * odo_err, "gridfast RMSE {err} m");
}

/// Every proposal beats dead reckoning, judged on the median over five filter seeds (one run
/// of a particle filter is a lottery: on office seeds 1–4 single runs of the odometry
/// proposal with 100 particles scored 0.09–0.58 of dead reckoning, of scan-matched odometry
/// with 10 particles 0.05–0.59, and of the improved proposal with 10 particles 0.01–0.22).
/// The odometry proposal needs many particles in the office's long corridors; scan-matched
/// odometry corrects each increment but has no loop closure of its own; the improved
/// proposal closes the loop (its median is held to [`LOOP_CLOSED_RMSE`]).
#[test]
fn every_proposal_beats_dead_reckoning_in_the_office() {
    let (records, truth) = common::office(3);
    let odo_err = common::rmse(&common::dead_reckoning(&records), &truth);
    eprintln!("dead reckoning: RMSE {odo_err:.3} m");
    assert!(
        odo_err > 1.0,
        "the odometry must be bad for the test to mean anything"
    );
    for (proposal, particles, bound) in [
        (Proposal::Odometry, 100, 0.5 * odo_err),
        (Proposal::ScanMatchedOdometry, 10, 0.5 * odo_err),
        (Proposal::Improved, 10, LOOP_CLOSED_RMSE),
    ] {
        let config = GridFastConfig {
            particles,
            proposal: ProposalConfig {
                kind: proposal,
                ..Default::default()
            },
            ..Default::default()
        };
        let errs: Vec<f64> = (1..=5)
            .map(|seed| common::rmse(&run_seeded(&records, config.clone(), 2, seed).0, &truth))
            .collect();
        eprintln!("{proposal:?} with {particles} particles: RMSE {errs:.3?} m");
        let med = median(errs);
        assert!(
            med < bound,
            "{proposal:?}: median RMSE {med} m, bound {bound} m"
        );
    }
}

#[test]
fn intel_prefix_relations_error() {
    let (Some(log), Some(rel)) = (
        common::dataset("bench/intel.log"),
        common::dataset("slam-benchmark-relations/intel.relations"),
    ) else {
        return;
    };
    let data = slam::io::carmen::read_carmen(&log).unwrap().dataset;
    let relations = slam::io::relations::read_relations(&rel).unwrap();
    // The first 3,000 records (≈ 200 keyframe scans, the first ~10 minutes).
    let records = &data.records[..3000];
    let t_end = records.last().unwrap().t;
    let inside: Vec<_> = relations
        .iter()
        .filter(|r| r.t1.max(r.t2) <= t_end)
        .cloned()
        .collect();
    assert!(
        inside.len() > 300,
        "{} relations in the prefix",
        inside.len()
    );
    let odo = slam::eval::metrics::relations_error(&common::dead_reckoning(records), &inside);
    let config = GridFastConfig {
        particles: 10,
        ..Default::default()
    };
    let mut slam = GridFastSlam::new(config, Pose2::IDENTITY, 42).unwrap();
    let traj = common::run_scans(&mut slam, records).trajectory;
    assert_eq!(traj.len(), records.len());
    let e = slam::eval::metrics::relations_error(&traj, &inside);
    eprintln!(
        "intel prefix: {} relations; odometry {:.3} m / {:.2} deg; gridfast {:.4} m / {:.3} deg",
        e.used, odo.trans_mean, odo.rot_mean_deg, e.trans_mean, e.rot_mean_deg
    );
    assert_eq!(e.dropped, 0);
    assert!(odo.trans_mean > 0.3);
    // GMapping's full-log figures are 0.057–0.070 m and 2.3–2.7°.
    assert!(e.trans_mean < 0.07 && e.rot_mean_deg < 3.0, "{e:?}");
}

/// The whole benchmark input with the settings (30 particles, improved proposal,
/// defaults), scored by the relations metric. Bounds from published figures on this same
/// input: a fresh GMapping run with 30 particles scores 0.070 m / 2.65° and the original
/// GMapping run 0.057 m / 2.32° (dataset README); we require better than the original run
/// in both: < 0.057 m and < 2.32°. Filter seeds 0–31 score 0.0537–0.0559 m and
/// 2.288–2.306° (README), so the check judges the filter, not a seed; the issue's own
/// targets (≤ 0.055 m, ≤ 2.3°, met by the mean over those seeds and by 25 of them) are too
/// close to single runs for a test. ≈ 10 s in release on two threads.
#[test]
fn intel_whole_log_beats_gmapping() {
    let (Some(log), Some(rel)) = (
        common::dataset("bench/intel.log"),
        common::dataset("slam-benchmark-relations/intel.relations"),
    ) else {
        return;
    };
    let records = slam::io::carmen::read_carmen(&log).unwrap().dataset.records;
    let relations = slam::io::relations::read_relations(&rel).unwrap();
    let mut slam = GridFastSlam::new(GridFastConfig::default(), Pose2::IDENTITY, 0).unwrap();
    let run = common::run_scans(&mut slam, &records);
    assert_eq!(slam.processed_scans(), 910);
    let e = slam::eval::metrics::relations_error(&run.trajectory, &relations);
    eprintln!(
        "intel whole log, 30 particles, seed 0: {} relations, {:.4} m / {:.3} deg",
        e.used, e.trans_mean, e.rot_mean_deg
    );
    assert_eq!((e.used, e.dropped), (2984, 0));
    assert!(e.trans_mean < 0.057 && e.rot_mean_deg < 2.32, "{e:?}");
}

/// The pose-at-every-record rule (`slam_models::keyframes`, used by the filter's
/// `trajectory()`) is GMapping's own: rebuilt from GMapping's corrected poses at the 910
/// Intel keyframes and the recovered odometry, it reproduces `intel.ref.tum` (GMapping's
/// trajectory at every ODOM record, written by the dataset's tool, not by us) at all
/// 13,700 records to the file's 6 printed decimals. Composing the readings that share a
/// keyframe's printed time stamp backwards from that keyframe instead (our rule before
/// session 3) misses 372 of them, so the check can fail.
#[test]
fn keyframe_pose_rule_reproduces_gmappings_trajectory() {
    use slam::models::keyframes::{poses_at_records, Keyframe};
    let (Some(log), Some(reference)) = (
        common::dataset("bench/intel.log"),
        common::dataset("bench/intel.ref.tum"),
    ) else {
        return;
    };
    let records = slam::io::carmen::read_carmen(&log).unwrap().dataset.records;
    let reference = slam::io::tum::read_tum(&reference).unwrap();
    let odom: Vec<usize> = (0..records.len())
        .filter(|&i| records[i].scan.is_none())
        .collect();
    assert_eq!(odom.len(), reference.len());
    assert_eq!(odom.len(), 13_700);
    // GMapping's corrected pose at a keyframe is its pose at the keyframe's own ODOM line,
    // the record just before the FLASER line (same time, same odometry).
    let mut ref_at = vec![None; records.len()];
    for (&i, p) in odom.iter().zip(&reference) {
        assert_eq!(records[i].t, p.t);
        ref_at[i] = Some(p.pose);
    }
    let keyframes: Vec<Keyframe> = (0..records.len())
        .filter(|&i| records[i].scan.is_some())
        .map(|i| {
            assert_eq!(records[i - 1].odometry, records[i].odometry);
            Keyframe {
                record: i,
                pose: ref_at[i - 1].expect("an ODOM line before every FLASER line"),
            }
        })
        .collect();
    assert_eq!(keyframes.len(), 910);
    let times: Vec<f64> = records.iter().map(|r| r.t).collect();
    let odometry: Vec<_> = records.iter().map(|r| r.odometry).collect();
    let rebuilt = poses_at_records(&times, &odometry, &keyframes).unwrap();
    let mut worst = (0.0f64, 0.0f64);
    for &i in &odom {
        let (r, p) = (ref_at[i].unwrap(), rebuilt[i]);
        worst.0 = worst.0.max((r.x - p.x).abs().max((r.y - p.y).abs()));
        worst.1 = worst
            .1
            .max(slam::models::normalize_angle(r.theta - p.theta).abs());
    }
    eprintln!(
        "intel.ref.tum rebuilt: worst |Δx|,|Δy| {:.2e} m, |Δθ| {:.2e} rad",
        worst.0, worst.1
    );
    // 6 printed decimals in both files: 5e-7 each, plus composition round-off.
    assert!(worst.0 < 5e-6 && worst.1 < 5e-6, "{worst:?}");
}

/// The fast subset of `cargo xtask eval robust` (issue 21), with exact ground truth: the
/// first 800 scans (≈ 360 m) of the simulated outdoor `campus` (seed 1, as the suite
/// simulates it). The preset and the range limit come from the data: outdoor (returns
/// 10–25 m away) and the laser's 80 m. With the earlier fixed settings (50 m, 5 cm cells)
/// seed 0 of the whole run scored 0.646 m aligned (docs/results.md), and the bound
/// for the whole run's worst seed is 0.5 m; a short stretch must stay well inside it.
#[test]
fn campus_prefix_takes_outdoor_settings_from_the_data_and_holds() {
    let opts = ScenarioOptions {
        seed: 1,
        steps: Some(800),
        ..Default::default()
    };
    let Ok(SimOutput::Laser(run)) = generate("campus", &opts) else {
        panic!("campus scenario did not generate a laser run");
    };
    let truth = run.dataset.ground_truth.expect("campus has ground truth");
    let records = run.dataset.records;
    let odometry = slam::eval::metrics::ate(&common::dead_reckoning(&records), &truth).unwrap();
    for seed in [0, 1] {
        let mut slam = GridFastSlam::new(
            GridFastConfig {
                particles: 10,
                ..Default::default()
            },
            Pose2::IDENTITY,
            seed,
        )
        .unwrap();
        let run = common::run_scans(&mut slam, &records);
        let c = slam.config();
        assert_eq!(c.preset, slam::gridfast::Preset::Outdoor);
        assert_eq!(c.sensor.max_range, Some(80.0));
        let e = slam::eval::metrics::ate(&run.trajectory, &truth).unwrap();
        eprintln!(
            "campus prefix, seed {seed}: ATE aligned {:.3} m (dead reckoning {:.3} m)",
            e.rmse_aligned, odometry.rmse_aligned
        );
        assert!(e.rmse_aligned < 0.3, "{e:?}");
        assert!(e.rmse_aligned < odometry.rmse_aligned / 3.0);
    }
}

/// The other half of the fast subset: Intel's corrected scans with odometry perturbed at
/// the `moderate` and `hard` profiles by the shared tool (`perturb-odometry --seed 1
/// --profile …`, as the suite does), first 400 scans, exact ground truth (the corrected
/// poses). Lost, in the suite's terms, is an aligned ATE above 1 m. At the `hard` profile
/// the odometry of keyframes that turned in place is up to 0.88 rad off in heading; with
/// the earlier ±0.3 rad coarse search the filter was lost on this prefix from scan 238 on
/// (32 m off at scan 400, filter seed 0: docs/gridfast.md).
#[test]
fn perturbed_intel_prefix_is_not_lost() {
    for (profile, bound) in [("moderate", 0.15), ("hard", 0.3)] {
        perturbed_intel_prefix(profile, bound);
    }
}

fn perturbed_intel_prefix(profile: &str, bound: f64) {
    let (Some(corrected), Some(tool)) = (
        common::dataset("radish-corrected/intel-corrected.log.gz"),
        common::dataset("../tools/perturb-odometry"),
    ) else {
        return;
    };
    let dir = std::env::temp_dir().join(format!(
        "slam-gridfast-perturbed-{profile}-{}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let prefix = dir.join("intel");
    let status = std::process::Command::new(&tool)
        .arg(&corrected)
        .arg(&prefix)
        .args(["--seed", "1", "--profile", profile])
        .status()
        .unwrap();
    assert!(status.success());
    let records = slam::io::carmen::read_carmen(&prefix.with_extension("log"))
        .unwrap()
        .dataset
        .records;
    let truth = slam::io::tum::read_tum(&dir.join("intel.gt.tum")).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    // One ODOM and one FLASER record per scan.
    let records = &records[..800];
    let odometry = slam::eval::metrics::ate(&common::dead_reckoning(records), &truth).unwrap();
    let mut slam = GridFastSlam::new(GridFastConfig::default(), Pose2::IDENTITY, 0).unwrap();
    let run = common::run_scans(&mut slam, records);
    let e = slam::eval::metrics::ate(&run.trajectory, &truth).unwrap();
    eprintln!(
        "intel-{profile} prefix: ATE aligned {:.3} m (dead reckoning {:.3} m)",
        e.rmse_aligned, odometry.rmse_aligned
    );
    assert!(odometry.rmse_aligned > 0.3, "{odometry:?}");
    assert!(e.rmse_aligned < bound, "{profile}: {e:?}");
}

/// A far odometry jump is noticed and answered by the wide (branch-and-bound) search: the
/// simulated office (seed 3) with a jump E = (0.9 m, −0.8 m, 0.15 rad) in the robot frame
/// injected into the odometry a third of the way in (|E| = 1.2 m; every later odometry
/// reading carries it). With the recovery the filter notices poor matches at the jump,
/// recovers particles, and ends within the loop-closed bound of the exact ground truth;
/// with it switched off (trigger fraction 0) the same run is worse than that bound, so the
/// test can fail.
#[test]
fn a_far_odometry_jump_in_the_office_is_recovered() {
    let (mut records, truth) = common::office(3);
    let k0 = records.len() / 3;
    let before = records[k0 - 1].odometry;
    let jump = Pose2::new(0.9, -0.8, 0.15);
    // odom'_k = o ⊕ E ⊕ o⁻¹ ⊕ odom_k with o the last reading before the jump: the increment
    // from record k0 − 1 to k0 carries exactly E on top of the true motion.
    let j = before.compose(&jump).compose(&before.inverse());
    for r in &mut records[k0..] {
        r.odometry = j.compose(&r.odometry);
    }
    let run = |trigger: f64| {
        let mut config = GridFastConfig {
            particles: 10,
            ..Default::default()
        };
        config.matching.recovery.trigger_fraction = trigger;
        let mut slam = GridFastSlam::new(config, Pose2::IDENTITY, 1).unwrap();
        let run = common::run_scans(&mut slam, &records);
        let recovered: usize = run.updates.iter().map(|u| u.match_recoveries).sum();
        (common::rmse(&run.trajectory, &truth), recovered)
    };
    let (with, recovered) = run(0.4);
    let (without, none) = run(0.0);
    eprintln!(
        "office with a 1.2 m jump: RMSE {with:.3} m with the recovery ({recovered} particle \
         recoveries), {without:.3} m without"
    );
    assert_eq!(none, 0);
    assert!(recovered > 0, "the jump must trigger the recovery");
    assert!(with < LOOP_CLOSED_RMSE, "RMSE {with} m with the recovery");
    assert!(
        without > LOOP_CLOSED_RMSE,
        "RMSE {without} m without the recovery"
    );
}

/// Settings a configuration file may give that reach the matcher's corner cases run to the
/// end of the office's first 180 records (60 scans) instead of killing the process:
/// `sensor.max-range = 1` m leaves some scans without a usable end point, whose poor match
/// sent an empty scan to the wide search's lattice (an index out of bounds panic), and
/// `matching.search-range-xy = 0` with the preset's heading window made the coarse search a
/// single translation per heading, which the branch and bound halved without end (a stack
/// overflow that aborted the process).
#[test]
fn corner_settings_of_the_matcher_run_to_the_end() {
    let (records, _) = common::office(0);
    let records = &records[..180];
    let mut short_range = GridFastConfig {
        particles: 4,
        ..Default::default()
    };
    short_range.sensor.max_range = Some(1.0);
    let mut headings_only = GridFastConfig {
        particles: 4,
        ..Default::default()
    };
    headings_only.matching.search_range_xy = Some(0.0);
    for (name, config) in [
        ("max-range 1 m", short_range),
        ("search-range-xy 0", headings_only),
    ] {
        let (trajectory, processed) = run(records, config, 1);
        assert_eq!(trajectory.len(), records.len(), "{name}");
        assert!(processed > 0, "{name}: {processed} updates");
        assert!(
            trajectory.iter().all(|p| p.pose.is_finite()),
            "{name}: a pose is not finite"
        );
    }
}
