//! What `slam run` and `slam sim` may write where (issue 17), and the trajectory figures
//! checked against `evo`, an independent tool (issue 18).
//!
//! The output rules: a new or empty folder, or one the command marked as its own (whose
//! earlier files are replaced, no leftovers), `--force` for `slam run` only; inputs inside
//! `--out` refused; the folder checked before the data is loaded; `metrics.json` last;
//! Ctrl-C leaves nothing. The evo figures are in `tests/fixtures/evo/` with the command lines
//! that made them (its README).

mod common;
use common::{dataset, scratch, slam};

use slam_cli::{CliError, Outcome};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The file names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .collect();
    v.sort();
    v
}

fn metrics(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("metrics.json")).unwrap()).unwrap()
}

/// Issue 17's reproduction: `slam sim figure8 --out s`, then `slam sim loop --out s`, then
/// `slam run --dataset s` scored 6.8 m instead of the loop's 0.15 m, because figure8's
/// sidecars (its initial pose) stayed. Now the second `slam sim` replaces the first's files,
/// and the run scores exactly as on a fresh loop folder.
#[test]
fn a_second_sim_leaves_no_leftovers() {
    let dir = scratch("leftovers");
    let (reused, fresh) = (dir.join("s"), dir.join("fresh"));
    for (scenario, out) in [("figure8", &reused), ("loop", &reused), ("loop", &fresh)] {
        let (r, text) = slam(&["sim", scenario, "--out", s(out)]);
        assert!(matches!(r, Ok(Outcome::Simulated(_))), "{r:?}\n{text}");
    }
    assert_eq!(names(&reused), names(&fresh));
    for f in names(&fresh) {
        assert_eq!(
            std::fs::read(reused.join(&f)).unwrap(),
            std::fs::read(fresh.join(&f)).unwrap(),
            "{f}"
        );
    }
    let run = |data: &Path, out: &str| {
        let out = dir.join(out);
        let (r, text) = slam(&[
            "run",
            "--filter",
            "ekf",
            "--dataset",
            s(data),
            "--quiet",
            "--out",
            s(&out),
        ]);
        assert!(matches!(r, Ok(Outcome::Ran(_))), "{r:?}\n{text}");
        metrics(&out)
    };
    let (a, b) = (run(&reused, "a"), run(&fresh, "b"));
    assert_eq!(a["ate_rmse_m"], b["ate_rmse_m"]);
    assert_eq!(a["landmark_rmse_m"], b["landmark_rmse_m"]);
    assert!(a["ate_rmse_m"].as_f64().unwrap() < 0.5, "{a}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `slam sim` never writes into a folder it did not make: a dataset (or anything else) is
/// left byte for byte, even a `slam run` output folder.
#[test]
fn sim_never_overwrites_a_dataset() {
    let dir = scratch("sim-refuses");
    std::fs::write(dir.join("sensor_data.dat"), "ODOMETRY 0 0.1 0\n").unwrap();
    let (r, _) = slam(&["sim", "loop", "--out", s(&dir)]);
    let e = r.unwrap_err().to_string();
    assert!(
        e.contains("not empty") && e.contains("never overwrites"),
        "{e}"
    );
    assert_eq!(names(&dir), ["sensor_data.dat"]);
    assert_eq!(
        std::fs::read_to_string(dir.join("sensor_data.dat")).unwrap(),
        "ODOMETRY 0 0.1 0\n"
    );
    let run_out = dir.join("run");
    let (r, _) = slam(&[
        "run",
        "--filter",
        "ekf",
        "--sim",
        "loop",
        "--steps",
        "20",
        "--quiet",
        "--out",
        s(&run_out),
    ]);
    assert!(r.is_ok(), "{r:?}");
    let (r, _) = slam(&["sim", "loop", "--out", s(&run_out)]);
    assert!(r.is_err());
    let _ = std::fs::remove_dir_all(&dir);
}

/// `slam run --out`: a folder it did not make is refused unless `--force`, which replaces
/// only slam run's own file names; in its own folder a new run removes the earlier run's
/// files (a landmark run's `landmarks.csv` does not survive a laser run); an input inside
/// `--out` is refused even with `--force`; each output is complete and `metrics.json` is
/// there.
#[test]
fn run_out_is_new_empty_own_or_forced() {
    let dir = scratch("run-out");
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    std::fs::write(out.join("map.png"), "not a png").unwrap();
    let landmark = |extra: &[&str]| {
        let mut a = vec![
            "run",
            "--filter",
            "ekf",
            "--sim",
            "loop",
            "--steps",
            "30",
            "--quiet",
            "--out",
            s(&out),
        ];
        a.extend_from_slice(extra);
        slam(&a)
    };
    let (r, text) = landmark(&[]);
    let e = r.unwrap_err().to_string();
    assert!(e.contains("--force") && e.contains("notes.txt"), "{e}");
    assert!(!text.contains("input:"), "refused before loading: {text}");
    assert_eq!(names(&out), ["map.png", "notes.txt"]);
    let (r, _) = landmark(&["--force"]);
    assert!(r.is_ok(), "{r:?}");
    assert_eq!(
        names(&out),
        [
            ".slam-run",
            "config.toml",
            "estimates.csv",
            "ground_truth.tum",
            "landmarks.csv",
            "map.png",
            "metrics.json",
            "notes.txt",
            "trajectory.tum"
        ]
    );
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "mine"
    );
    assert_ne!(std::fs::read(out.join("map.png")).unwrap(), b"not a png");
    // Its own folder now: a laser run replaces everything the landmark run wrote.
    let (r, text) = slam(&[
        "run",
        "--filter",
        "scanmatch",
        "--sim",
        "office",
        "--steps",
        "20",
        "--quiet",
        "--out",
        s(&out),
    ]);
    assert!(r.is_ok(), "{r:?}\n{text}");
    assert_eq!(
        names(&out),
        [
            ".slam-run",
            "config.toml",
            "ground_truth.tum",
            "map.pgm",
            "map.png",
            "map.yaml",
            "metrics.json",
            "notes.txt",
            "trajectory.tum"
        ]
    );
    assert_eq!(metrics(&out)["filter"], "scanmatch");
    // An input inside --out: refused whatever the flags, and left alone.
    let gt = out.join("ground_truth.tum");
    let before = std::fs::read(&gt).unwrap();
    for force in [false, true] {
        let mut a = vec![
            "run",
            "--filter",
            "scanmatch",
            "--sim",
            "office",
            "--steps",
            "20",
            "--ground-truth",
            s(&gt),
            "--quiet",
            "--out",
            s(&out),
        ];
        if force {
            a.push("--force");
        }
        let (r, _) = slam(&a);
        let e = r.unwrap_err().to_string();
        assert!(
            e.contains("--ground-truth") && e.contains("inside --out"),
            "{e}"
        );
    }
    assert_eq!(std::fs::read(&gt).unwrap(), before);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A place that cannot be written fails before the data is loaded (no `input:` line), with
/// the path in the error, and leaves nothing.
#[test]
fn unwritable_out_fails_before_the_run() {
    let dir = scratch("readonly");
    let ro = dir.join("ro");
    std::fs::create_dir_all(&ro).unwrap();
    let mut perms = std::fs::metadata(&ro).unwrap().permissions();
    std::os::unix::fs::PermissionsExt::set_mode(&mut perms, 0o555);
    std::fs::set_permissions(&ro, perms).unwrap();
    // Root writes through permission bits; /proc refuses new entries even to root.
    let root_ignores_bits = std::fs::write(ro.join("probe"), "").is_ok();
    let _ = std::fs::remove_file(ro.join("probe"));
    let mut places = vec![PathBuf::from("/proc/slam-test-cannot-write")];
    if !root_ignores_bits {
        places.push(ro.clone());
        places.push(ro.join("out"));
    }
    for place in places {
        let (r, text) = slam(&[
            "run",
            "--filter",
            "ekf",
            "--sim",
            "loop",
            "--quiet",
            "--out",
            s(&place),
        ]);
        let Err(CliError::Write { path, .. }) = &r else {
            panic!("{}: {r:?}", place.display())
        };
        assert!(
            path.starts_with(&place) || place.starts_with(path),
            "{path:?}"
        );
        assert!(!text.contains("input:"), "{text}");
        assert!(!place.join("metrics.json").exists());
    }
    let mut perms = std::fs::metadata(&ro).unwrap().permissions();
    std::os::unix::fs::PermissionsExt::set_mode(&mut perms, 0o755);
    std::fs::set_permissions(&ro, perms).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--steps` is exact: the scenario gives that many, or an error says how many it can give
/// (city ends after 19,091 steps at seed 0); `--steps` with `--dataset` is refused.
#[test]
fn steps_are_exact_and_refused_with_a_dataset() {
    let dir = scratch("steps");
    let (r, _) = slam(&["sim", "loop", "--steps", "57", "--out", s(&dir.join("a"))]);
    let Ok(Outcome::Simulated(rep)) = r else {
        panic!("{r:?}")
    };
    assert_eq!(rep.steps, 57);
    let (r, _) = slam(&["sim", "office", "--steps", "13", "--out", s(&dir.join("b"))]);
    let Ok(Outcome::Simulated(_)) = r else {
        panic!("{r:?}")
    };
    let log = std::fs::read_to_string(dir.join("b").join("office.log")).unwrap();
    assert_eq!(
        log.lines().filter(|l| l.starts_with("ROBOTLASER1")).count(),
        13
    );
    let (r, _) = slam(&[
        "sim",
        "city",
        "--steps",
        "20000",
        "--out",
        s(&dir.join("c")),
    ]);
    let e = r.unwrap_err().to_string();
    assert!(e.contains("--steps 20000") && e.contains("at most"), "{e}");
    assert!(!dir.join("c").exists(), "a failed sim leaves no folder");
    let (r, _) = slam(&[
        "run",
        "--filter",
        "ekf",
        "--dataset",
        s(&dir.join("a")),
        "--steps",
        "20",
        "--out",
        s(&dir.join("d")),
    ]);
    let e = r.unwrap_err();
    assert!(matches!(e, CliError::Usage(_)), "{e}");
    assert!(e.to_string().contains("--steps"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `slam run --sim` writes the simulator's ground truth beside the trajectory: the same
/// bytes `slam sim` writes for the same scenario and seed.
#[test]
fn sim_runs_write_their_ground_truth() {
    let dir = scratch("sim-gt");
    let (r, _) = slam(&["sim", "loop", "--seed", "4", "--out", s(&dir.join("data"))]);
    assert!(r.is_ok(), "{r:?}");
    let (r, _) = slam(&[
        "run",
        "--filter",
        "ekf",
        "--sim",
        "loop",
        "--seed",
        "4",
        "--quiet",
        "--out",
        s(&dir.join("run")),
    ]);
    assert!(r.is_ok(), "{r:?}");
    assert_eq!(
        std::fs::read(dir.join("run").join("ground_truth.tum")).unwrap(),
        std::fs::read(dir.join("data").join("ground_truth.tum")).unwrap()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Ctrl-C: SIGINT to the running program stops it between steps with exit code 130; the
/// earlier complete run in the folder stays byte for byte, and no partial file is left. In a
/// new folder, nothing at all is left.
#[test]
fn ctrl_c_leaves_the_earlier_output_or_nothing() {
    let dir = scratch("sigint");
    let out = dir.join("out");
    let (r, _) = slam(&[
        "run",
        "--filter",
        "ekf",
        "--sim",
        "loop",
        "--steps",
        "40",
        "--quiet",
        "--out",
        s(&out),
    ]);
    assert!(r.is_ok(), "{r:?}");
    let before: Vec<(String, Vec<u8>)> = names(&out)
        .into_iter()
        .map(|n| {
            let b = std::fs::read(out.join(&n)).unwrap();
            (n, b)
        })
        .collect();
    for target in [out.clone(), dir.join("new")] {
        // Far too long to finish (minutes), so the signal lands inside the run.
        let mut child = Command::new(env!("CARGO_BIN_EXE_slam"))
            .args([
                "run",
                "--filter",
                "fastslam2",
                "--sim",
                "loop",
                "--steps",
                "30000",
                "--particles",
                "2000",
                "--quiet",
                "--out",
                s(&target),
            ])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let start = Instant::now();
        while !target.join(".slam-partial").exists() {
            assert!(start.elapsed() < Duration::from_secs(60), "never started");
            std::thread::sleep(Duration::from_millis(20));
        }
        std::thread::sleep(Duration::from_millis(500));
        let killed = Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status()
            .unwrap();
        assert!(killed.success());
        let status = loop {
            if let Some(st) = child.try_wait().unwrap() {
                break st;
            }
            if start.elapsed() > Duration::from_secs(120) {
                let _ = child.kill();
                panic!("did not stop after SIGINT");
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        let mut err = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
        assert_eq!(status.code(), Some(130), "{err}");
        assert!(err.contains("interrupted"), "{err}");
        if target == out {
            let after: Vec<(String, Vec<u8>)> = names(&out)
                .into_iter()
                .map(|n| {
                    let b = std::fs::read(out.join(&n)).unwrap();
                    (n, b)
                })
                .collect();
            assert!(
                after == before,
                "the earlier output changed: {:?}",
                names(&out)
            );
        } else {
            assert!(!target.exists(), "left {:?}", names(&target));
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A trajectory scored against itself is exactly 0, for every bench reference (their
/// stamps repeat and step back), with one warning line about the stamps.
#[test]
fn every_bench_reference_scores_zero_against_itself() {
    let Some(bench) = dataset("bench") else {
        return;
    };
    let mut refs: Vec<PathBuf> = std::fs::read_dir(&bench)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().ends_with(".ref.tum"))
        .collect();
    refs.sort();
    assert!(refs.len() >= 7, "{refs:?}");
    for r in refs {
        let (out, text) = slam(&["eval", "--estimate", s(&r), "--ground-truth", s(&r)]);
        let Ok(Outcome::Evaluated(rep)) = out else {
            panic!("{}: {out:?}", r.display())
        };
        let n = text.lines().count();
        assert!(n >= 3, "{text}");
        assert_eq!(rep.ate_rmse_m, Some(0.0), "{}", r.display());
        assert_eq!(rep.ate_rmse_aligned_m, Some(0.0), "{}", r.display());
        assert_eq!(rep.rpe_trans_mean_m, Some(0.0), "{}", r.display());
        assert_eq!(rep.rpe_rot_mean_deg, Some(0.0), "{}", r.display());
        assert_eq!(rep.ate_matched, Some(rep.poses));
    }
}

/// `tests/fixtures/evo/figures.txt`: (case, figure) → the rest of the line.
fn evo_figures() -> Vec<(String, String, String)> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/evo/figures.txt");
    std::fs::read_to_string(p)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let mut w = l.splitn(3, ' ');
            let (c, f, v) = (w.next().unwrap(), w.next().unwrap(), w.next().unwrap());
            (c.to_string(), f.to_string(), v.to_string())
        })
        .collect()
}

fn evo(case: &str, figure: &str) -> f64 {
    evo_figures()
        .into_iter()
        .find(|(c, f, _)| c == case && f == figure)
        .unwrap_or_else(|| panic!("figures.txt has no {case} {figure}"))
        .2
        .parse()
        .unwrap()
}

/// Our ATE (as is, aligned) and RPE (m, deg) against evo's on the fixture trajectories: an
/// EKF and a FastSLAM 2.0 run on the simulated loop (shared frame: plain `evo_ape`), and a
/// gridfast run on the csail bench log (laser: anchored at the first record, evo's
/// `--align_origin`). Agreement to 1 mm and 1e-3 degrees.
#[test]
fn our_figures_match_evo() {
    use slam_eval::metrics::{anchor_at_first_match, ate, rpe};
    use slam_io::tum::read_tum;
    let fx = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/evo");
    let loop_gt = read_tum(&fx.join("loop-ground_truth.tum")).unwrap();
    let mut cases = vec![
        (
            "ekf-loop",
            read_tum(&fx.join("ekf-loop-trajectory.tum")).unwrap(),
            loop_gt.clone(),
            false,
        ),
        (
            "fastslam2-loop",
            read_tum(&fx.join("fastslam2-loop-trajectory.tum")).unwrap(),
            loop_gt,
            false,
        ),
    ];
    if let Some(csail) = dataset("bench/csail.ref.tum") {
        cases.push((
            "gridfast-csail",
            read_tum(&fx.join("gridfast-csail-trajectory.tum.gz")).unwrap(),
            read_tum(&csail).unwrap(),
            true,
        ));
    }
    for (case, est, gt, laser) in cases {
        let gt_as_is = if laser {
            anchor_at_first_match(&est, &gt)
        } else {
            gt.clone()
        };
        let ours = [
            ("ate_as_is", ate(&est, &gt_as_is).unwrap().rmse),
            ("ate_aligned", ate(&est, &gt).unwrap().rmse_aligned),
            ("rpe_trans_mean", rpe(&est, &gt).unwrap().trans_mean),
            ("rpe_rot_mean_deg", rpe(&est, &gt).unwrap().rot_mean_deg),
        ];
        for (figure, v) in ours {
            let want = evo(case, figure);
            eprintln!("{case} {figure}: ours {v:.6}, evo {want:.6}");
            assert!(
                (v - want).abs() <= 1e-3,
                "{case} {figure}: ours {v}, evo {want}"
            );
        }
    }
}

/// Issue 18: on `bench/intel.log` (gridfast, 30 particles, seed 0) `metrics.json`'s ATE as
/// is, `slam eval` on the same two files and evo's `--align_origin` figure agree to 1 mm
/// (before the anchor fix: 0.337 m against evo's 1.496 m).
#[test]
fn intel_ate_as_is_matches_slam_eval_and_evo() {
    let (Some(log), Some(reference)) = (dataset("bench/intel.log"), dataset("bench/intel.ref.tum"))
    else {
        return;
    };
    let dir = scratch("intel-evo");
    let out = dir.join("run");
    let (r, text) = slam(&[
        "run",
        "--filter",
        "gridfast",
        "--particles",
        "30",
        "--seed",
        "0",
        "--dataset",
        s(&log),
        "--ground-truth",
        s(&reference),
        "--quiet",
        "--out",
        s(&out),
    ]);
    assert!(matches!(r, Ok(Outcome::Ran(_))), "{r:?}\n{text}");
    let tum = std::fs::read_to_string(out.join("trajectory.tum")).unwrap();
    let last = evo_figures()
        .into_iter()
        .find(|(c, f, _)| c == "gridfast-intel" && f == "last_line")
        .unwrap()
        .2;
    assert_eq!(
        tum.lines().last().unwrap(),
        last,
        "gridfast's Intel trajectory changed: re-measure evo's figure \
         (tests/fixtures/evo/README.md) before comparing"
    );
    let from_run = metrics(&out)["ate_rmse_m"].as_f64().unwrap();
    let (r, _) = slam(&[
        "eval",
        "--estimate",
        s(&out.join("trajectory.tum")),
        "--ground-truth",
        s(&reference),
    ]);
    let Ok(Outcome::Evaluated(rep)) = r else {
        panic!("{r:?}")
    };
    let from_eval = rep.ate_rmse_m.unwrap();
    let from_evo = evo("gridfast-intel", "ate_as_is");
    assert!(
        (from_run - from_eval).abs() <= 1e-3 && (from_run - from_evo).abs() <= 1e-3,
        "metrics.json {from_run}, slam eval {from_eval}, evo --align_origin {from_evo}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Options are checked before the data is loaded (no `input:` line, no folder made): a bad
/// config key, `--particles` for a filter without particles.
#[test]
fn bad_options_fail_before_loading() {
    let dir = scratch("early");
    let cfg = dir.join("bad.toml");
    std::fs::write(&cfg, "no_such_parameter = 3\n").unwrap();
    let out = dir.join("out");
    for extra in [
        vec!["--filter", "gridfast", "--config", s(&cfg)],
        vec!["--filter", "scanmatch", "--particles", "5"],
    ] {
        let mut a = vec!["run", "--sim", "office", "--quiet", "--out", s(&out)];
        a.extend(extra);
        let (r, text) = slam(&a);
        assert!(r.is_err(), "{a:?}");
        assert!(!text.contains("input:"), "{a:?}: {text}");
        assert!(!out.exists(), "{a:?}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
