//! `cargo xtask`: the project's automation, as a plain binary with no dependencies
//! (the matklad xtask pattern). Invoked through the alias in `.cargo/config.toml`.
//!
//! * `cargo xtask test-all`: fmt check, clippy with warnings as errors, the whole test suite
//!   in release mode (doc tests included), rustdoc with warnings as errors, then a one-line
//!   summary. Exits non-zero if any step fails. This is what CI runs.
//! * `cargo xtask tidy`: only the cheap source checks of `test-all` (see `tidy`).
//! * `cargo xtask bench [NAME]`: the criterion benches (all, or one crate's: `ekf`,
//!   `fastslam`, `grid`, `gridfast`, `graph`, `sim`).
//! * `cargo xtask eval`: the long dataset runs (every filter on every real dataset), writing
//!   into `slam-out/eval/`; not part of the test suite.
//! * `cargo xtask eval robust [--filters graph,gridfast,scanmatch] [--seeds N] [--only NAME,…]
//!   [--keep | --no-run]`: every laser filter's robustness suite (see [`robust::robust`]),
//!   writing into `slam-out/robust/`.
//! * `cargo xtask eval mcap`: `slam run --mcap` read back by independent Python readers and
//!   by Foxglove's own TypeScript readers (see [`mcap_check`]), and `slam localize --mcap` by
//!   the Python readers, writing into `slam-out/mcap/`.
//! * `cargo xtask eval hostile`: ROS 1 bags of 2.5 and 5 GiB (sparse, generated) through
//!   `slam info` and `slam run` under `/usr/bin/time -v`: right counts, peak RSS bounded
//!   (see [`hostile::hostile`]).
//! * `cargo xtask eval speed [--pairs N] [--other-pairs M] [--only NAME,…] [--peers P,…]
//!   [--install-peers]`: grid FastSLAM (1 and 2 threads) beside the peer programs found
//!   (GMapping from `$GMAPPING_BIN`, MRPT's `rbpf-slam`) under `/usr/bin/time -v` on the
//!   bench logs, each run scored against the log's reference (see [`speed::speed`]),
//!   writing into `slam-out/speed/`.

use std::io::{BufRead, BufReader};
use std::process::{Command, ExitCode, Stdio};
use std::time::Instant;

mod hostile;
mod robust;
mod speed;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    // Every step works on paths relative to the workspace root (`crates/`, `configs/`), so
    // start there whichever folder of the workspace `cargo xtask` was called from.
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask lives one folder below the workspace root");
    if let Err(e) = std::env::set_current_dir(root) {
        eprintln!(
            "xtask: cannot enter the workspace root {}: {e}",
            root.display()
        );
        return ExitCode::FAILURE;
    }
    let result = match args.first().map(String::as_str) {
        Some("test-all") => test_all(),
        Some("tidy") => tidy(),
        Some("bench") => bench(args.get(1).map(String::as_str)),
        Some("eval") if args.get(1).map(String::as_str) == Some("robust") => {
            robust::robust(&args[2..])
        }
        Some("eval") if args.get(1).map(String::as_str) == Some("mcap") => mcap_check(),
        Some("eval") if args.get(1).map(String::as_str) == Some("ros2") => ros2_check(&args[2..]),
        Some("eval") if args.get(1).map(String::as_str) == Some("hostile") => hostile::hostile(),
        Some("eval") if args.get(1).map(String::as_str) == Some("speed") => {
            speed::speed(&args[2..])
        }
        Some("eval") => eval(&args[1..]),
        _ => {
            eprintln!(
                "usage: cargo xtask <test-all | tidy | bench [ekf|fastslam|grid|gridfast|graph|sim] | eval [robust|mcap|speed|ros2|hostile]>"
            );
            return ExitCode::from(2);
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(msg) => {
            eprintln!("xtask: {msg}");
            ExitCode::FAILURE
        }
    }
}

fn cargo() -> Command {
    Command::new(cargo_path())
}

/// The cargo target folder: `$CARGO_TARGET_DIR` when set (cargo itself honours it), else
/// `target`.
fn target_dir() -> std::path::PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::path::PathBuf::from("target"))
}

/// Builds the `slam` program (release) and returns its path, `<target>/release/slam`.
fn build_slam() -> Result<std::path::PathBuf, String> {
    run(
        "build slam",
        cargo().args(["build", "--release", "-p", "slam-cli"]),
    )?;
    Ok(target_dir().join("release").join("slam"))
}

/// The cargo program (`$CARGO`, else `cargo` on the path).
fn cargo_path() -> String {
    std::env::var("CARGO").unwrap_or_else(|_| "cargo".into())
}

fn run(step: &str, cmd: &mut Command) -> Result<(), String> {
    eprintln!("xtask: == {step}");
    let t = Instant::now();
    let status = cmd
        .status()
        .map_err(|e| format!("{step}: cannot start: {e}"))?;
    eprintln!("xtask: {step} took {:.1} s", t.elapsed().as_secs_f64());
    if status.success() {
        Ok(())
    } else {
        Err(format!("{step} failed ({status})"))
    }
}

/// Runs `cargo test`, streaming its output, and adds up the `test result:` lines.
fn run_tests(cmd: &mut Command) -> Result<(usize, usize, usize), String> {
    eprintln!("xtask: == tests");
    let t = Instant::now();
    let mut child = cmd
        .stdout(Stdio::piped())
        .spawn()
        .map_err(|e| format!("tests: cannot start: {e}"))?;
    let (mut passed, mut failed, mut ignored) = (0, 0, 0);
    if let Some(out) = child.stdout.take() {
        for line in BufReader::new(out).lines().map_while(Result::ok) {
            println!("{line}");
            if let Some(rest) = line.trim().strip_prefix("test result:") {
                passed += count(rest, " passed");
                failed += count(rest, " failed");
                ignored += count(rest, " ignored");
            }
        }
    }
    let status = child.wait().map_err(|e| format!("tests: {e}"))?;
    eprintln!("xtask: tests took {:.1} s", t.elapsed().as_secs_f64());
    if !status.success() && failed == 0 {
        failed += 1; // a build failure or a crashed test binary
    }
    Ok((passed, failed, ignored))
}

/// The number just before `label` in a `test result:` line.
fn count(line: &str, label: &str) -> usize {
    line.split(';')
        .find(|part| part.contains(label))
        .and_then(|part| part.split_whitespace().rev().nth(1))
        .and_then(|n| n.parse().ok())
        .unwrap_or(0)
}

fn test_all() -> Result<(), String> {
    let t = Instant::now();
    run("fmt", cargo().args(["fmt", "--all", "--", "--check"]))?;
    tidy()?;
    run(
        "clippy",
        cargo().args([
            "clippy",
            "--workspace",
            "--all-targets",
            "--release",
            "--",
            "-D",
            "warnings",
        ]),
    )?;
    // slam-io for its readers and writers alone: no PNG renderer, no bag reader.
    run(
        "slam-io without default features",
        cargo().args([
            "build",
            "--release",
            "-p",
            "slam-io",
            "--no-default-features",
        ]),
    )?;
    // In the release profile, so that the dependencies' metadata checked by clippy above is
    // reused instead of checked again in the dev profile (8.5 of 35 CI minutes once slam-ros
    // brought RustDDS's tree).
    run(
        "doc",
        cargo()
            .args(["doc", "--workspace", "--no-deps", "--release"])
            .env("RUSTDOCFLAGS", "-D warnings"),
    )?;
    // The particle filters without rayon (their `parallel` feature off): the sequential
    // path must keep compiling; only the two crates rebuild (about 30 s on 2 cores).
    run(
        "build without the parallel feature",
        cargo().args([
            "build",
            "--release",
            "-p",
            "slam-fastslam",
            "-p",
            "slam-gridfast",
            "--no-default-features",
        ]),
    )?;
    // Downstream users of single crates (tests/downstream, outside the workspace): each
    // program compiles with only the crates it names. The workspace's target folder is
    // shared (same lock file versions, same release profile), so only the programs build;
    // those that need no data run (they check their results against known geometry or
    // the simulator's truth; filter_swap once per arm of its one-line swap).
    let target = std::env::var_os("CARGO_TARGET_DIR").unwrap_or_else(|| "target".into());
    let target = std::fs::canonicalize(&target).unwrap_or_else(|_| target.into());
    run(
        "downstream crates",
        cargo()
            .args([
                "build",
                "--release",
                "--manifest-path",
                "tests/downstream/Cargo.toml",
            ])
            .env("CARGO_TARGET_DIR", &target),
    )?;
    let tests_dir = std::env::current_dir().map_err(|e| e.to_string())?;
    let configs = tests_dir.join("tests/downstream/configs");
    let data = std::env::var_os("SLAM_DATASETS")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::path::PathBuf::from("../shared/datasets"));
    let ci = std::env::var("CI").is_ok_and(|v| v == "true" || v == "1");
    // Each program with its arguments; a path under the datasets folder is checked first
    // (missing: a failure under CI=true, a skip with a message otherwise).
    let programs: Vec<(&str, Vec<std::ffi::OsString>, Option<&str>)> = vec![
        ("ekf_alone", vec![], None),
        ("grid_alone", vec![], None),
        ("scan_match_alone", vec![], None),
        ("filter_swap", vec!["ekf".into()], None),
        ("filter_swap", vec!["fastslam2".into()], None),
        (
            "filter_swap",
            vec!["--config".into(), configs.join("ekf.toml").into()],
            None,
        ),
        (
            "filter_swap",
            vec!["--config".into(), configs.join("fastslam2.toml").into()],
            None,
        ),
        ("grid_io", vec![], Some("freiburg-robot-mapping/csail.log")),
        ("gridfast_io", vec![], Some("bench/intel.log")),
    ];
    for (bin, mut args, dataset) in programs {
        if let Some(rel) = dataset {
            let path = data.join(rel);
            if !path.exists() {
                if ci {
                    return Err(format!(
                        "downstream {bin}: dataset {} is missing and CI=true",
                        path.display()
                    ));
                }
                println!(
                    "xtask: SKIPPED downstream {bin}: {} not found",
                    path.display()
                );
                continue;
            }
            args.insert(0, path.into());
        }
        let mut command = Command::new(target.join("release").join(bin));
        command.args(&args);
        let shown: Vec<_> = args.iter().map(|a| a.to_string_lossy()).collect();
        run(
            &format!("downstream {bin} {}", shown.join(" ")),
            &mut command,
        )?;
    }
    let (passed, failed, ignored) =
        run_tests(cargo().args(["test", "--workspace", "--release", "--no-fail-fast"]))?;
    println!("test-all took {:.0} s", t.elapsed().as_secs_f64());
    println!("test-all: {passed} passed, {failed} failed, {ignored} skipped");
    if failed > 0 {
        return Err(format!("{failed} test(s) failed"));
    }
    Ok(())
}

/// Cheap source checks (rust-analyzer's "tidy"): every library source file opens with a
/// module doc comment; no `dbg!` left behind; no `#[should_panic]` standing in for an error
/// type; the simulator's path uses deterministic maths only (see [`deterministic_math`]).
fn tidy() -> Result<(), String> {
    eprintln!("xtask: == tidy");
    let mut problems = Vec::new();
    for_each_rs_file(std::path::Path::new("crates"), |path, text| {
        let in_src = path.components().any(|c| c.as_os_str() == "src");
        let first = text
            .lines()
            .map(str::trim)
            .find(|l| !l.is_empty())
            .unwrap_or("");
        if in_src && !first.starts_with("//!") {
            problems.push(format!(
                "{}: no module doc comment (`//! ...`) at the top",
                path.display()
            ));
        }
        for (i, line) in text.lines().enumerate() {
            if line.contains("dbg!(") {
                problems.push(format!("{}:{}: dbg! left in", path.display(), i + 1));
            }
            if line.contains("#[should_panic") {
                problems.push(format!(
                    "{}:{}: #[should_panic]: return an error type instead",
                    path.display(),
                    i + 1
                ));
            }
        }
    })?;
    for dir in DETERMINISTIC_DIRS {
        deterministic_math(std::path::Path::new(dir), &mut problems)?;
    }
    if problems.is_empty() {
        Ok(())
    } else {
        for p in &problems {
            eprintln!("tidy: {p}");
        }
        Err(format!("tidy found {} problem(s)", problems.len()))
    }
}

/// The sources whose output must be bit-identical on every machine: the simulator and the
/// models it calls.
const DETERMINISTIC_DIRS: &[&str] = &["crates/slam-models/src", "crates/slam-sim/src"];

/// Calls whose result comes from the platform's math library (or, for `powi`, an evaluation
/// order LLVM leaves unspecified) and may differ in the last bit between machines. Method
/// form (`x.sin()`) and path form (`f64::sin(x)`) are both caught.
const NON_DETERMINISTIC_MATH: &[&str] = &[
    "sin", "cos", "sin_cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh",
    "asinh", "acosh", "atanh", "exp", "exp2", "exp_m1", "ln", "ln_1p", "log", "log2", "log10",
    "hypot", "powf", "powi", "cbrt",
];

/// Checks every `.rs` file under `dir` for std transcendental calls and `rand_distr` outside
/// test code (the item after a `#[cfg(test)]` is skipped; comments, doc examples included,
/// are ignored). Such code must use `slam_models::detmath` and `slam_models::sampling`.
fn deterministic_math(dir: &std::path::Path, problems: &mut Vec<String>) -> Result<(), String> {
    for_each_rs_file(dir, |path, text| {
        for (line, code) in non_test_code(text) {
            for f in NON_DETERMINISTIC_MATH {
                if code.contains(&format!(".{f}("))
                    || code.contains(&format!("f64::{f}("))
                    || code.contains(&format!("f32::{f}("))
                {
                    problems.push(format!(
                        "{}:{line}: `{f}` may differ in the last bit between machines; use \
                     slam_models::detmath (or write a `powi` out as products)",
                        path.display()
                    ));
                }
            }
            if code.contains("rand_distr") {
                problems.push(format!(
                    "{}:{line}: rand_distr (its samplers call the platform's exp/ln); use \
                 slam_models::sampling",
                    path.display()
                ));
            }
        }
    })
}

/// Calls `f(path, text)` for every `.rs` file below `root`.
fn for_each_rs_file(
    root: &std::path::Path,
    mut f: impl FnMut(&std::path::Path, &str),
) -> Result<(), String> {
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let entries = std::fs::read_dir(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        for entry in entries.flatten() {
            let path = entry.path();
            if path.is_dir() {
                stack.push(path);
                continue;
            }
            if path.extension().and_then(|e| e.to_str()) != Some("rs") {
                continue;
            }
            let text =
                std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
            f(&path, &text);
        }
    }
    Ok(())
}

/// The lines of `text` (1-based number, code with comments and string contents blanked)
/// that are not test code: an item annotated `#[cfg(test)]` is skipped up to its matching
/// closing brace (or its `;`). A light lexer, enough for this codebase's sources: it knows
/// line comments, block comments, string literals and the char literals `'{'`/`'}'`.
fn non_test_code(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut in_block_comment = false;
    let mut in_string = false;
    // Brace depth inside a skipped test item, and whether a `#[cfg(test)]` item is pending.
    let mut skip_depth: Option<usize> = None;
    let mut pending_test_item = false;
    for (i, raw) in text.lines().enumerate() {
        let mut code = String::with_capacity(raw.len());
        let chars: Vec<char> = raw.chars().collect();
        let mut k = 0;
        while k < chars.len() {
            let c = chars[k];
            let next = chars.get(k + 1).copied();
            if in_block_comment {
                if c == '*' && next == Some('/') {
                    in_block_comment = false;
                    k += 1;
                }
            } else if in_string {
                if c == '\\' {
                    k += 1;
                } else if c == '"' {
                    in_string = false;
                    code.push('"');
                }
            } else if c == '/' && next == Some('/') {
                break;
            } else if c == '/' && next == Some('*') {
                in_block_comment = true;
                k += 1;
            } else if c == '"' {
                in_string = true;
                code.push('"');
            } else if c == '\''
                && matches!(next, Some('{') | Some('}'))
                && chars.get(k + 2) == Some(&'\'')
            {
                code.push_str("' '");
                k += 2;
            } else {
                code.push(c);
            }
            k += 1;
        }
        let trimmed = code.trim();
        if skip_depth.is_none() && trimmed.starts_with("#[cfg(test)]") {
            pending_test_item = true;
            continue;
        }
        if pending_test_item && skip_depth.is_none() {
            if trimmed.is_empty() || trimmed.starts_with("#[") {
                continue;
            }
            skip_depth = Some(0);
            pending_test_item = false;
        }
        if let Some(depth) = skip_depth.as_mut() {
            let mut opened = false;
            for c in code.chars() {
                match c {
                    '{' => {
                        *depth += 1;
                        opened = true;
                    }
                    '}' => *depth = depth.saturating_sub(1),
                    _ => {}
                }
            }
            // The item ends when its braces close, or at a `;` before any brace (`mod t;`).
            if *depth == 0 && (opened || code.contains('}') || trimmed.ends_with(';')) {
                skip_depth = None;
            }
            continue;
        }
        out.push((i + 1, code));
    }
    out
}

fn bench(name: Option<&str>) -> Result<(), String> {
    // The benches live in the root package's `benches/`, one group per crate measured.
    let mut cmd = cargo();
    cmd.args(["bench", "-p", "slam"]);
    let benches: &[&str] = match name {
        None => &[],
        Some("ekf") => &["ekf_update"],
        Some("fastslam") => &["fastslam_step"],
        Some("grid") => &["grid_update", "scan_match"],
        Some("gridfast") => &["gridfast"],
        Some("graph") => &["graph"],
        Some("sim") => &["raycast", "scenarios"],
        Some(other) => return Err(format!("unknown bench group {other:?}")),
    };
    for b in benches {
        cmd.args(["--bench", b]);
    }
    if benches.is_empty() {
        cmd.arg("--benches");
    }
    run("bench", &mut cmd)?;
    if matches!(name, None | Some("gridfast")) {
        gridfast_intel()?;
    }
    Ok(())
}

/// Issue 8's speed figures on the whole Intel benchmark input, one process per run so each
/// peak RSS is the run's own: `examples/gridfast_intel` with 30 particles and filter seed 0
/// (`slam run`'s default, so the command) on one thread and on all threads (wall time, CPU time, real-time factor, time per particle per processed
/// scan, peak RSS). Skipped with a message when the dataset is missing.
fn gridfast_intel() -> Result<(), String> {
    let data = std::env::var_os("SLAM_DATASETS")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::path::PathBuf::from("../shared/datasets"));
    if !data.join("bench/intel.log").exists() {
        println!(
            "xtask: SKIPPED the whole-Intel gridfast run: {} not found",
            data.join("bench/intel.log").display()
        );
        return Ok(());
    }
    for threads in ["1", "0"] {
        let label = if threads == "1" {
            "1 thread"
        } else {
            "all threads"
        };
        println!("xtask: gridfast on intel.log, 30 particles, {label}");
        run(
            "gridfast_intel",
            cargo().args([
                "run",
                "--release",
                "-p",
                "slam",
                "--example",
                "gridfast_intel",
                "--",
                "--particles",
                "30",
                "--seed",
                "0",
                "--threads",
                threads,
            ]),
        )?;
    }
    Ok(())
}

fn eval(extra: &[String]) -> Result<(), String> {
    let exe = build_slam()?;
    let plan = std::path::Path::new("configs/eval.txt");
    let text = std::fs::read_to_string(plan).map_err(|e| {
        format!(
            "{}: {e} (one `slam run ...` argument list per line)",
            plan.display()
        )
    })?;
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut cmd = Command::new(&exe);
        cmd.args(line.split_whitespace()).args(extra);
        run(&format!("eval line {}: slam {line}", i + 1), &mut cmd)?;
    }
    Ok(())
}

/// The Python of a throwaway venv (`$ENV_VAR`, default `default`) holding `packages`
/// (pinned). The venv is made on first use; the packages are installed unless the venv's
/// `slam-packages.txt` (written only after pip succeeded) lists exactly them, so a failed or
/// interrupted install is retried rather than leaving a venv without them.
fn python_venv(
    env_var: &str,
    default: &str,
    packages: &[&str],
) -> Result<std::path::PathBuf, String> {
    let venv = std::env::var_os(env_var)
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::path::PathBuf::from(default));
    let python = venv.join("bin").join("python");
    if !python.exists() {
        run(
            "make the Python venv",
            Command::new("python3").args(["-m", "venv"]).arg(&venv),
        )?;
    }
    let marker = venv.join("slam-packages.txt");
    let want = packages.join("\n") + "\n";
    if std::fs::read_to_string(&marker).ok().as_deref() != Some(want.as_str()) {
        run(
            &format!("install {}", packages.join(", ")),
            Command::new(&python)
                .args(["-m", "pip", "install", "--quiet"])
                .args(packages),
        )?;
        std::fs::write(&marker, want).map_err(|e| format!("{}: {e}", marker.display()))?;
    }
    Ok(python)
}

/// `cargo xtask eval ros2 [SCANS]`: the ROS 2 node and the Foxglove live view against
/// software we did not write. Makes a Python venv (`$ROS2_VENV`, default
/// `/tmp/slam-ros2-venv`) with Eclipse Cyclone DDS (`cyclonedds`, one of ROS 2's middlewares)
/// and `websockets`, builds `slam`, then runs, one at a time:
///
/// 1. `scripts/ros2_interop.py` at real time: Cyclone publishes the first SCANS (default 300)
///    scans and odometry of `bench/intel.log` to `slam ros2`, receives `/map` and `/tf`, and
///    checks them against the node's files and an offline `slam run` on the scans it
///    processed;
/// 2. the same data at 10× real time (`--rate 10`): skipped scans, memory and latency are
///    reported (the comparison is again against the scans processed);
/// 3. `scripts/foxglove_check.py`: `slam run --live` on the ROS 2 bag fixture, read by the
///    `websockets` client with Cyclone's CDR decoder (every channel decodes; map and
///    trajectory against the run's files).
///
/// The DDS runs (1 and 2) are confined to this machine: each runs in a network namespace
/// of its own ([`isolated_network`]), so no packet leaves the machine and no other DDS
/// participant on the network can join; each script starts and stops its processes.
/// Outputs in `slam-out/ros2/`.
fn ros2_check(extra: &[String]) -> Result<(), String> {
    let scans = extra.first().map(String::as_str).unwrap_or("300");
    let python = python_venv(
        "ROS2_VENV",
        "/tmp/slam-ros2-venv",
        &["cyclonedds==11.0.1", "websockets==17.4"],
    )?;
    let exe = std::env::current_dir()
        .map_err(|e| format!("current folder: {e}"))?
        .join(build_slam()?);
    let log = "../shared/datasets/bench/intel.log";
    if !std::path::Path::new(log).is_file() {
        return Err(format!(
            "{log}: missing (../shared/datasets, see its README)"
        ));
    }
    for (name, rate, compare) in [("realtime", "1", true), ("replay10x", "10", true)] {
        let out = format!("slam-out/ros2/{name}");
        let mut cmd = Command::new(&python);
        cmd.arg("scripts/ros2_interop.py")
            .arg("--slam")
            .arg(&exe)
            .args([
                "--log", log, "--scans", scans, "--rate", rate, "--out", &out,
            ]);
        if !compare {
            cmd.arg("--no-compare");
        }
        run(
            &format!("ROS 2 node with Cyclone DDS, {name}"),
            &mut isolated_network(cmd)?,
        )?;
    }
    run(
        "Foxglove live view, independent client",
        Command::new(&python)
            .arg("scripts/foxglove_check.py")
            .arg("--slam")
            .arg(&exe)
            .args([
                "--dataset",
                "crates/slam-io/tests/fixtures/rosbag/intel-tf",
                "--out",
                "slam-out/ros2/live",
            ]),
    )?;
    Ok(())
}

/// `cmd` run inside a network namespace of its own (`unshare -rn`, an unprivileged user
/// namespace), whose only network is a veth pair 10.99.0.1 ↔ 10.99.0.2 with the multicast
/// route on it, and loopback: DDS discovery (multicast) and traffic stay inside it, which
/// RustDDS needs because it ignores the 127.0.0.1 locators a peer announces (so plain
/// loopback does not work). Errors when the namespace cannot be made, unless
/// `SLAM_ROS2_HOST_NETWORK=1` asks to run on the host's network instead.
fn isolated_network(cmd: Command) -> Result<Command, String> {
    let host = std::env::var("SLAM_ROS2_HOST_NETWORK").is_ok_and(|v| v == "1");
    let probe = Command::new("unshare")
        .args(["-rn", "true"])
        .status()
        .is_ok_and(|s| s.success());
    if !probe {
        if host {
            eprintln!("xtask: no network namespace (unshare -rn failed): on the host's network");
            return Ok(cmd);
        }
        return Err(
            "unshare -rn failed: cannot confine DDS to this machine (user \
                    namespaces off?); SLAM_ROS2_HOST_NETWORK=1 runs on the host's network"
                .into(),
        );
    }
    let setup = "ip link add v0 type veth peer name v1 && \
                 ip addr add 10.99.0.1/24 dev v0 && ip addr add 10.99.0.2/24 dev v1 && \
                 ip link set lo up && ip link set v0 up && ip link set v1 up && \
                 ip route add 224.0.0.0/4 dev v0 && exec \"$@\"";
    let mut wrapped = Command::new("unshare");
    wrapped
        .args(["-rn", "sh", "-c", setup, "sh"])
        .arg(cmd.get_program())
        .args(cmd.get_args());
    if let Some(dir) = cmd.get_current_dir() {
        wrapped.current_dir(dir);
    }
    for (k, v) in cmd.get_envs() {
        match v {
            Some(v) => wrapped.env(k, v),
            None => wrapped.env_remove(k),
        };
    }
    Ok(wrapped)
}

/// `cargo xtask eval mcap`: the MCAP files `slam run --mcap` writes, read back by
/// independent readers. Makes a Python venv (`$MCAP_VENV`, default `/tmp/slam-mcap-venv`)
/// with the `mcap`, `mcap-ros2-support` and `rosbags` packages, runs grid FastSLAM on the
/// ROS 2 bag fixture (`/tf` odometry, laser mounted off-centre), FastSLAM 1.0 and the EKF on
/// the simulated `loop`, each with `--mcap`, and checks every file with
/// `scripts/check_mcap.py` (every topic present, every message decoded by `mcap-ros2` and by
/// `rosbags` with its own ROS 2 definitions, the map's dimensions, origin and cells against
/// map.yaml/map.pgm, the path against trajectory.tum, tf against the poses, the ellipses
/// against landmarks.csv); then with `scripts/check_mcap_foxglove.mjs` under Node.js, which
/// reads each file as Foxglove opens a local file (npm's `@mcap/core` indexed and streaming
/// readers with CRC validation, `@foxglove/rosmsg2-serialization` decoding every message
/// with the file's own `ros2msg` schemas, no trailing bytes) and checks what `ros2 bag play`
/// needs (profile `ros2`, a Statistics record matching the messages, `cdr` channels, the
/// QoS metadata, `/map` and `/tf_static` transient local). Its npm packages, pinned, are
/// installed on first use into `$CARGO_TARGET_DIR/mcap-check-node` (default
/// `target/mcap-check-node`). With `$MCAP_CLI` naming an `mcap` executable (the official
/// CLI, built by hand: no registry has it), also `mcap doctor --strict-message-order`.
fn mcap_check() -> Result<(), String> {
    let python = python_venv(
        "MCAP_VENV",
        "/tmp/slam-mcap-venv",
        &["mcap==1.6.0", "mcap-ros2-support==0.6.0", "rosbags==0.11.9"],
    )?;
    let exe = build_slam()?;
    let target = target_dir();
    // Foxglove's readers, installed once under the target folder.
    let node_dir = std::env::current_dir()
        .map_err(|e| format!("current folder: {e}"))?
        .join(&target)
        .join("mcap-check-node");
    if !node_dir.join("node_modules/@mcap/core").is_dir() {
        std::fs::create_dir_all(&node_dir).map_err(|e| format!("{}: {e}", node_dir.display()))?;
        std::fs::write(
            node_dir.join("package.json"),
            "{\"name\": \"slam-mcap-check\", \"private\": true, \"type\": \"module\"}\n",
        )
        .map_err(|e| format!("{}: {e}", node_dir.display()))?;
        run(
            "install @mcap/core, @mcap/support, @foxglove/rosmsg, @foxglove/rosmsg2-serialization",
            Command::new("npm")
                .args(["install", "--no-audit", "--no-fund", "--prefix"])
                .arg(&node_dir)
                .args([
                    "@mcap/core@2.2.2",
                    "@mcap/support@1.1.0",
                    "@foxglove/rosmsg@5.0.5",
                    "@foxglove/rosmsg2-serialization@3.1.0",
                ]),
        )?;
    }
    // Node resolves packages from the script's folder: the script goes beside them.
    let node_script = node_dir.join("check_mcap_foxglove.mjs");
    std::fs::copy("scripts/check_mcap_foxglove.mjs", &node_script)
        .map_err(|e| format!("scripts/check_mcap_foxglove.mjs: {e}"))?;
    // The official `mcap` CLI is in no package registry (docs/rosbag.md): run its doctor
    // when `$MCAP_CLI` names one built by hand.
    let mcap_cli = std::env::var_os("MCAP_CLI");
    let out = std::path::Path::new("slam-out/mcap");
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let bag = "crates/slam-io/tests/fixtures/rosbag/intel-tf";
    let cases: [(&str, &[&str], &str); 3] = [
        (
            "gridfast-intel-tf",
            &["--filter", "gridfast", "--dataset", bag],
            "/map,/particles,/pose,/scan,/tf,/tf_static,/trajectory",
        ),
        (
            "fastslam1-loop",
            &["--filter", "fastslam1", "--sim", "loop"],
            "/ground_truth,/landmarks,/particles,/pose,/tf,/trajectory",
        ),
        (
            "ekf-loop",
            &["--filter", "ekf", "--sim", "loop"],
            "/ground_truth,/landmarks,/pose,/tf,/trajectory",
        ),
    ];
    for (name, args, topics) in cases {
        let dir = out.join(name);
        let file = out.join(format!("{name}.mcap"));
        run(
            &format!("slam run {name} --mcap"),
            Command::new(&exe)
                .arg("run")
                .args(args)
                .args(["--quiet", "--out"])
                .arg(&dir)
                .arg("--mcap")
                .arg(&file),
        )?;
        run(
            &format!("check {name}"),
            Command::new(&python)
                .arg("scripts/check_mcap.py")
                .arg(&file)
                .arg("--out")
                .arg(&dir)
                .args(["--topics", topics]),
        )?;
        run(
            &format!("check {name} with Foxglove's readers"),
            Command::new("node")
                .arg(&node_script)
                .arg(&file)
                .arg("--out")
                .arg(&dir)
                .args(["--topics", topics]),
        )?;
        if let Some(cli) = &mcap_cli {
            run(
                &format!("mcap doctor {name}"),
                Command::new(cli)
                    .args(["doctor", "--strict-message-order"])
                    .arg(&file),
            )?;
        }
    }
    localize_mcap_check(&exe, &python, out, bag)
}

/// `slam localize --mcap` on the `intel-tf` bag, localized on its own known-poses map from
/// its first pose, checked by `scripts/check_mcap.py` (the map's files are copied beside
/// the localization's outputs, where the script looks for them).
fn localize_mcap_check(
    exe: &std::path::Path,
    python: &std::path::Path,
    out: &std::path::Path,
    bag: &str,
) -> Result<(), String> {
    let map_dir = out.join("known-poses-intel-tf");
    run(
        "slam run known-poses intel-tf",
        Command::new(exe)
            .args([
                "run",
                "--filter",
                "known-poses",
                "--dataset",
                bag,
                "--quiet",
            ])
            .arg("--out")
            .arg(&map_dir),
    )?;
    let (dir, file) = (
        out.join("localize-intel-tf"),
        out.join("localize-intel-tf.mcap"),
    );
    run(
        "slam localize intel-tf --mcap",
        Command::new(exe)
            .args(["localize", "--dataset", bag, "--global", "--force", "--map"])
            .arg(map_dir.join("map.yaml"))
            .arg("--out")
            .arg(&dir)
            .arg("--mcap")
            .arg(&file),
    )?;
    for f in ["map.yaml", "map.pgm"] {
        std::fs::copy(map_dir.join(f), dir.join(f)).map_err(|e| format!("{f}: {e}"))?;
    }
    run(
        "check localize-intel-tf",
        Command::new(python)
            .arg("scripts/check_mcap.py")
            .arg(&file)
            .arg("--out")
            .arg(&dir)
            .args([
                "--topics",
                "/map,/particles,/pose,/scan,/tf,/tf_static,/trajectory",
            ]),
    )
}
