//! `cargo xtask eval speed`: grid FastSLAM against peer SLAM programs the user already has,
//! side by side on one machine: CPU, wall time and peak memory from `/usr/bin/time -v`, and
//! the aligned ATE of every run against the bench log's reference (issue 21's speed
//! requirement; issue 34's peers from package registries).
//!
//! The harness builds no other project's code. Its peers are programs the user installed:
//! GMapping's `gmapping_offline` named by `$GMAPPING_BIN`, and MRPT's `rbpf-slam` with
//! `carmen2rawlog` (Debian's `mrpt-apps`; `scripts/peers/install-mrpt.sh` installs it,
//! `--install-peers` runs that script). A peer that is missing is named, with how to get it,
//! and left out.

use crate::{build_slam, run, target_dir};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// One measured run: CPU (user + system) and wall seconds, peak resident set size in KiB,
/// and the aligned ATE (m) of the trajectory at the log's scans against the reference.
#[derive(Debug, Clone, Copy)]
struct Usage {
    cpu: f64,
    wall: f64,
    rss_kib: f64,
    ate_aligned: f64,
}

/// A program the harness times.
#[derive(Debug, Clone)]
enum Runner {
    /// `slam run --filter gridfast --particles 30 --seed 0 --threads N`.
    Gridfast { threads: usize },
    /// GMapping's `gmapping_offline LOG OUT --seed 1` (30 particles, the ROS wrapper's
    /// defaults), at the path `$GMAPPING_BIN` names.
    Gmapping { bin: PathBuf },
    /// MRPT's `rbpf-slam INI RAWLOG` with `configs/peers/rbpf-slam.ini` (30 particles,
    /// seed 1), on the log as `carmen2rawlog` and `rawlog-to-sf` converted it (untimed).
    RbpfSlam { bin: PathBuf, converter: PathBuf },
}

impl Runner {
    /// The name in the tables.
    fn name(&self) -> String {
        match self {
            Runner::Gridfast { threads: 1 } => "gridfast 1 thread".into(),
            Runner::Gridfast { threads } => format!("gridfast {threads} threads"),
            Runner::Gmapping { .. } => "GMapping".into(),
            Runner::RbpfSlam { .. } => "MRPT rbpf-slam".into(),
        }
    }
}

/// `cargo xtask eval speed [--pairs N] [--other-pairs M] [--only a,b] [--peers p,q]
/// [--install-peers]`: grid FastSLAM (30 particles, seed 0, `--threads 1` and
/// `--threads 2`) and every peer found (GMapping from `$GMAPPING_BIN`; MRPT's `rbpf-slam`
/// from `$RBPF_SLAM_BIN` or the `PATH`) on every log of `../shared/datasets/bench`, each
/// program under `/usr/bin/time -v`. `--peers gmapping,rbpf-slam` (or `none`) chooses the
/// peers; a chosen peer that is missing is an error that says how to get it, an unchosen
/// default peer that is missing a note.
///
/// The runs of a round follow each other, and the order rotates from round to round
/// (1-thread, 2-thread, peers...; then 2-thread, peers..., 1-thread; ...), so that a change
/// of the machine's load touches all alike. `bench/intel.log` gets `--pairs` rounds
/// (default 3), every other log `--other-pairs` (default 1). The ratios are taken within each
/// round and their median reported (with the range): on a machine shared with other work
/// the absolute times drift, the ratios of neighbouring runs much less.
///
/// Accuracy: every run's trajectory at the log's FLASER scans (the poses a peer reports;
/// gridfast's `trajectory.tum` rows of those records) is scored by `slam eval` against
/// `<log>.ref.tum` (docs/evaluation.md: nearest stamp within 6 ms, Umeyama alignment);
/// the aligned ATE is reported. `$SLAM_BIN` names a `slam` executable (else it is built).
/// Every run's output goes to `<target>/speed/` (`<target>` is `$CARGO_TARGET_DIR` or
/// `target`); the table is printed and written to `slam-out/speed/summary.md`.
pub(crate) fn speed(extra: &[String]) -> Result<(), String> {
    let (mut pairs, mut other_pairs) = (3usize, 1usize);
    let mut only: Option<Vec<String>> = None;
    let mut peers: Option<Vec<String>> = None;
    let mut install = false;
    let mut it = extra.iter();
    let count = |v: Option<&String>, what: &str| {
        v.and_then(|v| v.parse().ok())
            .filter(|&n: &usize| n > 0)
            .ok_or(format!("{what} takes a positive count"))
    };
    let list = |v: Option<&String>, what: &str| -> Result<Vec<String>, String> {
        Ok(v.ok_or(format!("{what} takes names, comma separated"))?
            .split(',')
            .map(str::to_string)
            .collect())
    };
    while let Some(a) = it.next() {
        match a.as_str() {
            "--pairs" => pairs = count(it.next(), "--pairs")?,
            "--other-pairs" => other_pairs = count(it.next(), "--other-pairs")?,
            "--only" => only = Some(list(it.next(), "--only")?),
            "--peers" => peers = Some(list(it.next(), "--peers")?),
            "--install-peers" => install = true,
            other => return Err(format!("eval speed: unknown argument {other:?}")),
        }
    }
    if let Some(p) = &peers {
        if let Some(bad) = p
            .iter()
            .find(|p| !["gmapping", "rbpf-slam", "none"].contains(&p.as_str()))
        {
            return Err(format!(
                "--peers: unknown peer {bad:?} (gmapping, rbpf-slam or none)"
            ));
        }
    }
    let data = std::env::var_os("SLAM_DATASETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("../shared/datasets"));
    let target = target_dir();
    let scratch = target.join("speed");
    std::fs::create_dir_all(&scratch).map_err(|e| format!("{}: {e}", scratch.display()))?;
    let time = Path::new("/usr/bin/time");
    if !time.exists() {
        return Err("/usr/bin/time not found (GNU time: `apt-get install time`)".into());
    }
    if install {
        run(
            "install MRPT's rbpf-slam (scripts/peers/install-mrpt.sh)",
            Command::new("sh").arg("scripts/peers/install-mrpt.sh"),
        )?;
    }

    let mut runners = vec![
        Runner::Gridfast { threads: 1 },
        Runner::Gridfast { threads: 2 },
    ];
    let wanted = |p: &str| peers.as_ref().is_none_or(|l| l.iter().any(|x| x == p));
    let asked = |p: &str| peers.as_ref().is_some_and(|l| l.iter().any(|x| x == p));
    if wanted("gmapping") {
        match std::env::var_os("GMAPPING_BIN").map(PathBuf::from) {
            Some(bin) if bin.is_file() => runners.push(Runner::Gmapping { bin }),
            found => {
                let why = match found {
                    Some(bin) => format!("$GMAPPING_BIN = {} is not a file", bin.display()),
                    None => "$GMAPPING_BIN is not set".into(),
                };
                let msg = format!(
                    "GMapping: {why}. The harness runs a `gmapping_offline` (LOG OUT --seed S) \
                     you already have and builds none"
                );
                if asked("gmapping") {
                    return Err(msg);
                }
                eprintln!("xtask: {msg}; left out.");
            }
        }
    }
    if wanted("rbpf-slam") {
        match rbpf_slam(&scratch) {
            Ok((bin, converter)) => runners.push(Runner::RbpfSlam { bin, converter }),
            Err(why) => {
                let msg = format!(
                    "MRPT rbpf-slam: {why}. `sh scripts/peers/install-mrpt.sh` (or \
                     `cargo xtask eval speed --install-peers`) installs Debian's mrpt-apps \
                     and libmrpt-obs-dev with apt-get"
                );
                if asked("rbpf-slam") {
                    return Err(msg);
                }
                eprintln!("xtask: {msg}; left out.");
            }
        }
    }
    if runners.len() == 2 {
        eprintln!(
            "xtask: no peer program: only gridfast's two thread counts are timed, and the \
             table has no peer column (see `cargo xtask eval speed --help` in xtask/src/speed.rs)"
        );
    }
    let slam = match std::env::var_os("SLAM_BIN") {
        Some(bin) => PathBuf::from(bin),
        None => build_slam()?,
    };

    let mut logs: Vec<PathBuf> = std::fs::read_dir(data.join("bench"))
        .map_err(|e| format!("{}: {e}", data.join("bench").display()))?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "log"))
        .collect();
    logs.sort();
    // Intel first: its figures are the ones the issues ask for.
    logs.sort_by_key(|p| p.file_stem().is_none_or(|s| s != "intel"));
    logs.retain(|p| only.as_ref().is_none_or(|o| o.contains(&stem(p))));
    if logs.is_empty() {
        return Err("no bench log selected".into());
    }

    let load_before = load_average();
    let mut usage_table = String::from(
        "| log | program | runs | CPU user+sys median (s) | wall median (s) | peak RSS median (MB) | ATE aligned at the scans, median (m) |\n|---|---|---|---|---|---|---|\n",
    );
    let mut ratio_table = String::from(
        "| log | rounds | peer | peer CPU / gridfast 1-thread CPU | gridfast 1-thread RSS / peer RSS | ATE aligned, gridfast / peer (m) |\n|---|---|---|---|---|---|\n",
    );
    let mut thread_table =
        String::from("| log | rounds | gridfast wall 1 thread / 2 threads |\n|---|---|---|\n");
    let n = runners.len();
    for log in &logs {
        let name = stem(log);
        let reference = log.with_extension("ref.tum");
        let scans = scan_records(
            &std::fs::read_to_string(log).map_err(|e| format!("{}: {e}", log.display()))?,
        );
        if scans.is_empty() {
            return Err(format!("{}: no FLASER line", log.display()));
        }
        let rounds = if name == "intel" { pairs } else { other_pairs };
        let mut usage: Vec<Vec<Usage>> = Vec::new();
        for round in 0..rounds {
            let mut got = vec![
                Usage {
                    cpu: f64::NAN,
                    wall: f64::NAN,
                    rss_kib: f64::NAN,
                    ate_aligned: f64::NAN,
                };
                n
            ];
            for k in 0..n {
                let r = (round + k) % n;
                let dir = scratch.join(format!("{name}-{r}-{round}"));
                let _ = std::fs::remove_dir_all(&dir);
                std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
                let report = scratch.join(format!("{name}-{r}-{round}.time-v.txt"));
                let mut cmd = Command::new(time);
                cmd.arg("-v").arg("-o").arg(&report);
                match &runners[r] {
                    Runner::Gridfast { threads } => {
                        cmd.arg(&slam)
                            .args(["run", "--filter", "gridfast", "--particles", "30"])
                            .args(["--seed", "0", "--quiet", "--threads"])
                            .arg(threads.to_string())
                            .arg("--dataset")
                            .arg(log)
                            .arg("--out")
                            .arg(&dir);
                    }
                    Runner::Gmapping { bin } => {
                        cmd.arg(bin)
                            .arg(log)
                            .arg(dir.join(&name))
                            .args(["--seed", "1"]);
                    }
                    Runner::RbpfSlam { bin, converter } => {
                        let rawlog = mrpt_rawlog(log, &scratch, converter)?;
                        let ini = dir.join("rbpf-slam.ini");
                        write_rbpf_ini(&ini, &dir.join("out"), 1)?;
                        cmd.arg(bin).arg(&ini).arg(&rawlog);
                    }
                }
                // rbpf-slam waits for a key after an error: give it no terminal to wait on.
                cmd.stdin(Stdio::null()).stdout(Stdio::null());
                run(
                    &format!("{name} round {} {}", round + 1, runners[r].name()),
                    &mut cmd,
                )?;
                let text = std::fs::read_to_string(&report)
                    .map_err(|e| format!("{}: {e}", report.display()))?;
                let (cpu, wall, rss_kib) = parse_time_v(&text)
                    .ok_or(format!("{}: no CPU, wall or RSS line", report.display()))?;
                // GMapping's output is not read (its format depends on the user's build):
                // its ATE stays NaN, "NaN" in the tables.
                type AtScans = fn(&str, &[(usize, f64)]) -> Result<String, String>;
                let output: Option<(&str, AtScans)> = match &runners[r] {
                    Runner::Gridfast { .. } => Some(("trajectory.tum", gridfast_at_scans)),
                    Runner::Gmapping { .. } => None,
                    Runner::RbpfSlam { .. } => {
                        Some(("out/most_likely_path.txt", rbpf_path_at_scans))
                    }
                };
                let tum = match output {
                    Some((name, at_scans)) => {
                        let file = dir.join(name);
                        let text = std::fs::read_to_string(&file)
                            .map_err(|e| format!("{}: {e}", file.display()))?;
                        Some(
                            at_scans(&text, &scans)
                                .map_err(|e| format!("{}: {e}", file.display()))?,
                        )
                    }
                    None => None,
                };
                let ate_aligned = match tum {
                    Some(tum) => {
                        let estimate = dir.join("at-scans.tum");
                        std::fs::write(&estimate, tum)
                            .map_err(|e| format!("{}: {e}", estimate.display()))?;
                        score(&slam, &estimate, &reference)?
                    }
                    None => f64::NAN,
                };
                got[r] = Usage {
                    cpu,
                    wall,
                    rss_kib,
                    ate_aligned,
                };
                eprintln!(
                    "xtask:    CPU {cpu:.2} s, wall {wall:.2} s, peak RSS {:.1} MB, ATE aligned {ate_aligned:.3} m",
                    rss_kib / 1024.0
                );
            }
            usage.push(got);
        }
        for (r, runner) in runners.iter().enumerate() {
            let col = |f: fn(&Usage) -> f64| median(usage.iter().map(|u| f(&u[r])).collect());
            usage_table.push_str(&format!(
                "| {name} | {} | {} | {:.2} | {:.2} | {:.1} | {:.3} |\n",
                runner.name(),
                usage.len(),
                col(|u| u.cpu),
                col(|u| u.wall),
                col(|u| u.rss_kib) / 1024.0,
                col(|u| u.ate_aligned),
            ));
        }
        thread_table.push_str(&format!(
            "| {name} | {} | {} |\n",
            usage.len(),
            ratio(usage.iter().map(|u| u[0].wall / u[1].wall).collect())
        ));
        for (p, peer) in runners.iter().enumerate().skip(2) {
            ratio_table.push_str(&format!(
                "| {name} | {} | {} | {} | {} | {:.3} / {:.3} |\n",
                usage.len(),
                peer.name(),
                ratio(usage.iter().map(|u| u[p].cpu / u[0].cpu).collect()),
                ratio(usage.iter().map(|u| u[0].rss_kib / u[p].rss_kib).collect()),
                median(usage.iter().map(|u| u[0].ate_aligned).collect()),
                median(usage.iter().map(|u| u[p].ate_aligned).collect()),
            ));
        }
    }
    let machine = format!(
        "Machine: {} × {}; load average (1/5/15 min) {} before, {} after. Ratios: median over \
         the rounds of the per-round ratio (range in brackets). ATE: aligned, at the log's \
         scans, against its `.ref.tum` (GMapping's trajectory: a reference, not ground truth).\n",
        std::thread::available_parallelism().map_or(0, |n| n.get()),
        cpu_model(),
        load_before,
        load_average()
    );
    let peers_part = if n > 2 {
        format!("{ratio_table}\n")
    } else {
        "No peer program was run.\n\n".into()
    };
    let summary = format!("{machine}\n{peers_part}{thread_table}\n{usage_table}");
    println!("{summary}");
    let out = Path::new("slam-out/speed");
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let file = out.join("summary.md");
    std::fs::write(&file, &summary).map_err(|e| format!("{}: {e}", file.display()))?;
    println!("xtask: wrote {}", file.display());
    Ok(())
}

/// A path's file stem as a string ("intel" for `bench/intel.log`).
fn stem(p: &Path) -> String {
    p.file_stem()
        .unwrap_or_default()
        .to_string_lossy()
        .to_string()
}

/// MRPT's `rbpf-slam` (`$RBPF_SLAM_BIN`, else on the `PATH`), with `carmen2rawlog` beside it,
/// and our converter `scripts/peers/rawlog-to-sf.cpp` compiled into `scratch` against the
/// installed MRPT headers (rebuilt when the source is newer). Err: what is missing.
fn rbpf_slam(scratch: &Path) -> Result<(PathBuf, PathBuf), String> {
    let bin = match std::env::var_os("RBPF_SLAM_BIN") {
        Some(b) => PathBuf::from(b),
        None => on_path("rbpf-slam").ok_or("`rbpf-slam` is not on the PATH")?,
    };
    if !bin.is_file() {
        return Err(format!("{} is not a file", bin.display()));
    }
    on_path("carmen2rawlog").ok_or("`carmen2rawlog` (mrpt-apps) is not on the PATH")?;
    let include = Path::new("/usr/include/mrpt");
    if !include.join("obs").is_dir() {
        return Err("MRPT's headers (/usr/include/mrpt/obs, libmrpt-obs-dev) are missing".into());
    }
    let source = Path::new("scripts/peers/rawlog-to-sf.cpp");
    let converter = scratch.join("rawlog-to-sf");
    let modified = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    if modified(&converter).is_none() || modified(&converter) < modified(source) {
        let mut cmd = Command::new("c++");
        cmd.args(["-O2", "-std=c++17", "-o"])
            .arg(&converter)
            .arg(source)
            .arg(format!("-I{}", include.display()));
        // Debian installs each MRPT module's headers under /usr/include/mrpt/<module>/include.
        let mut modules: Vec<PathBuf> = std::fs::read_dir(include)
            .map_err(|e| format!("{}: {e}", include.display()))?
            .flatten()
            .map(|e| e.path().join("include"))
            .filter(|p| p.is_dir())
            .collect();
        modules.sort();
        for m in modules {
            cmd.arg(format!("-I{}", m.display()));
        }
        cmd.arg("-I/usr/include/eigen3");
        for lib in [
            "obs",
            "io",
            "serialization",
            "poses",
            "math",
            "system",
            "core",
            "rtti",
        ] {
            cmd.arg(format!("-lmrpt-{lib}"));
        }
        run("compile scripts/peers/rawlog-to-sf.cpp", &mut cmd)?;
    }
    Ok((bin, converter))
}

/// The first executable called `name` on the `PATH`.
fn on_path(name: &str) -> Option<PathBuf> {
    std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|d| d.join(name))
            .find(|p| p.is_file())
    })
}

/// `log` converted for `rbpf-slam` (cached in `scratch`; not timed): `carmen2rawlog` makes
/// an observation-only rawlog, `rawlog-to-sf` pairs each scan with its odometry increment.
fn mrpt_rawlog(log: &Path, scratch: &Path, converter: &Path) -> Result<PathBuf, String> {
    let name = stem(log);
    let out = scratch.join(format!("{name}-sf.rawlog"));
    if out.is_file() {
        return Ok(out);
    }
    let plain = scratch.join(format!("{name}.rawlog"));
    run(
        &format!("carmen2rawlog {name}"),
        Command::new("carmen2rawlog")
            .arg("-q")
            .arg("-w")
            .arg("-i")
            .arg(log)
            .arg("-o")
            .arg(&plain)
            .stdout(Stdio::null()),
    )?;
    run(
        &format!("rawlog-to-sf {name}"),
        Command::new(converter).arg(&plain).arg(&out),
    )?;
    Ok(out)
}

/// The ini `rbpf-slam` runs with: MRPT's own configuration named by the `base` key of
/// `configs/peers/rbpf-slam.ini` (a file Debian's mrpt-apps installs), with every other
/// `key = value` line of that file put in place of the base's line for the same key (or
/// added at the top of `[MappingApplication]` when the base has none), and the output
/// folder and random seed of this run.
fn write_rbpf_ini(ini: &Path, out_dir: &Path, seed: u32) -> Result<(), String> {
    let source = Path::new("configs/peers/rbpf-slam.ini");
    let text = std::fs::read_to_string(source).map_err(|e| format!("{}: {e}", source.display()))?;
    let mut overrides = ini_pairs(&text);
    let base = overrides
        .iter()
        .position(|(k, _)| k == "base")
        .map(|i| overrides.remove(i).1)
        .ok_or(format!("{}: no `base = <MRPT ini>` line", source.display()))?;
    let base_text = std::fs::read_to_string(&base)
        .map_err(|e| format!("{base} (the base of {}): {e}", source.display()))?;
    let out_dir =
        std::path::absolute(out_dir).map_err(|e| format!("{}: {e}", out_dir.display()))?;
    overrides.push(("logOutput_dir".into(), out_dir.display().to_string()));
    overrides.push(("RANDOM_SEED".into(), seed.to_string()));
    std::fs::write(ini, override_ini(&base_text, &overrides))
        .map_err(|e| format!("{}: {e}", ini.display()))
}

/// The `key = value` lines of an ini text (comments, blank lines and `[sections]` left
/// out; a trailing `// comment` removed), in order.
fn ini_pairs(text: &str) -> Vec<(String, String)> {
    text.lines()
        .map(|l| l.split("//").next().unwrap_or_default().trim())
        .filter(|l| !l.is_empty() && !l.starts_with('#') && !l.starts_with('['))
        .filter_map(|l| l.split_once('='))
        .map(|(k, v)| (k.trim().to_string(), v.trim().to_string()))
        .collect()
}

/// `base` with each `(key, value)` written in place of the base's line for `key` in its
/// `[MappingApplication]` section, or, where that section has none, right after its header.
fn override_ini(base: &str, overrides: &[(String, String)]) -> String {
    let key_of = |l: &str| {
        let l = l.trim_start();
        (!l.starts_with('#') && !l.starts_with('[') && !l.starts_with("//"))
            .then(|| l.split_once('=').map(|(k, _)| k.trim().to_string()))
            .flatten()
    };
    const MAIN: &str = "[MappingApplication]";
    let mut section = String::new();
    let mut present = Vec::new();
    for l in base.lines() {
        if l.trim_start().starts_with('[') {
            section = l.trim().to_string();
        } else if let Some(k) = key_of(l).filter(|_| section == MAIN) {
            present.push(k);
        }
    }
    let mut out = String::new();
    section.clear();
    for l in base.lines() {
        if l.trim_start().starts_with('[') {
            section = l.trim().to_string();
        }
        let replaced = key_of(l)
            .filter(|_| section == MAIN)
            .and_then(|k| overrides.iter().find(|(o, _)| *o == k));
        match replaced {
            Some((k, v)) => out.push_str(&format!("{k}={v}\n")),
            None => {
                out.push_str(l);
                out.push('\n');
            }
        }
        if l.trim() == MAIN {
            for (k, v) in overrides.iter().filter(|(k, _)| !present.contains(k)) {
                out.push_str(&format!("{k}={v}\n"));
            }
        }
    }
    out
}

/// For each FLASER line of a CARMEN log, in file order: its record index (the position
/// among the log's non-comment, non-empty lines, which is the row of `slam run`'s
/// `trajectory.tum` for that record) and its time stamp (the `ipc_timestamp` field, third
/// from the end). Lines that do not parse are left out.
fn scan_records(log: &str) -> Vec<(usize, f64)> {
    log.lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .enumerate()
        .filter_map(|(i, l)| {
            let f: Vec<&str> = l.split_whitespace().collect();
            if f.first() != Some(&"FLASER") || f.len() < 4 {
                return None;
            }
            f[f.len() - 3].parse().ok().map(|t| (i, t))
        })
        .collect()
}

/// The rows of a gridfast `trajectory.tum` (one per log record, after a `#` header) at the
/// scans' record indices, as TUM text.
fn gridfast_at_scans(tum: &str, scans: &[(usize, f64)]) -> Result<String, String> {
    let rows: Vec<&str> = tum
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .collect();
    let mut out = String::new();
    for &(i, _) in scans {
        out.push_str(rows.get(i).ok_or(format!(
            "{} rows, but the log has a scan at record {i}",
            rows.len()
        ))?);
        out.push('\n');
    }
    Ok(out)
}

/// rbpf-slam's `most_likely_path.txt` (`x y yaw`: the final most likely particle's path,
/// its initial pose first, then one pose per processed scan, in order) as TUM text on the
/// scans' time stamps. The path must have one pose per scan after the initial one.
fn rbpf_path_at_scans(path: &str, scans: &[(usize, f64)]) -> Result<String, String> {
    let poses: Vec<[f64; 3]> = path
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('%'))
        .map(|l| {
            let v: Vec<f64> = l
                .split_whitespace()
                .filter_map(|x| x.parse().ok())
                .collect();
            (v.len() == 3)
                .then(|| [v[0], v[1], v[2]])
                .ok_or(format!("not `x y yaw`: {l:?}"))
        })
        .collect::<Result<_, _>>()?;
    if poses.len() != scans.len() + 1 {
        return Err(format!(
            "{} poses for {} scans and the initial pose (every scan must be processed: \
             lower the ini's localize distances)",
            poses.len(),
            scans.len()
        ));
    }
    Ok(poses[1..]
        .iter()
        .zip(scans)
        .map(|(p, (_, t))| {
            let (s, c) = (0.5 * p[2]).sin_cos();
            format!("{t:.6} {} {} 0 0 0 {s} {c}\n", p[0], p[1])
        })
        .collect())
}

/// The aligned ATE (m) `slam eval` prints for `estimate` against `reference`.
fn score(slam: &Path, estimate: &Path, reference: &Path) -> Result<f64, String> {
    let out = Command::new(slam)
        .arg("eval")
        .arg("--estimate")
        .arg(estimate)
        .arg("--ground-truth")
        .arg(reference)
        .stderr(Stdio::null())
        .output()
        .map_err(|e| format!("slam eval: cannot start: {e}"))?;
    let text = String::from_utf8_lossy(&out.stdout);
    parse_aligned_ate(&text).ok_or(format!(
        "slam eval {}: no `aligned … m` figure in {text:?}",
        estimate.display()
    ))
}

/// The figure after "aligned " in `slam eval`'s `ATE RMSE … m, aligned … m` line.
fn parse_aligned_ate(text: &str) -> Option<f64> {
    text.lines()
        .find(|l| l.trim_start().starts_with("ATE RMSE"))?
        .split("aligned ")
        .nth(1)?
        .trim_end_matches(" m")
        .trim()
        .parse()
        .ok()
}

/// CPU (user + system) and wall seconds, and peak RSS (KiB), from GNU time's `-v` report.
fn parse_time_v(text: &str) -> Option<(f64, f64, f64)> {
    let field = |label: &str| {
        text.lines()
            .find_map(|l| l.trim().strip_prefix(label))
            .and_then(|rest| rest.rsplit(": ").next())
            .map(str::trim)
    };
    let user: f64 = field("User time (seconds)")?.parse().ok()?;
    let sys: f64 = field("System time (seconds)")?.parse().ok()?;
    // h:mm:ss or m:ss.ss
    let wall = field("Elapsed (wall clock) time")?
        .split(':')
        .try_fold(0.0, |acc, part| {
            part.parse::<f64>().ok().map(|x| acc * 60.0 + x)
        })?;
    let rss_kib: f64 = field("Maximum resident set size (kbytes)")?.parse().ok()?;
    Some((user + sys, wall, rss_kib))
}

/// The median with the range in brackets when there is more than one value.
fn ratio(v: Vec<f64>) -> String {
    let (lo, hi) = v
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    if v.len() > 1 {
        format!("{:.2} ({lo:.2}–{hi:.2})", median(v))
    } else {
        format!("{:.2}", median(v))
    }
}

/// The median (of an even count, the mean of the middle two); NaN for none.
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else {
        0.5 * (v[(n - 1) / 2] + v[n / 2])
    }
}

/// `/proc/loadavg`'s first three fields, or "unknown".
fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|| "unknown".into())
}

/// The CPU's model name from `/proc/cpuinfo`, or "unknown CPU".
fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// GNU time 1.9's `-v` report, as printed for a run of `rbpf-slam`.
    #[test]
    fn reads_gnu_time_report() {
        let text = "\tCommand being timed: \"rbpf-slam run.ini intel-sf.rawlog\"\n\
            \tUser time (seconds): 52.55\n\tSystem time (seconds): 0.09\n\
            \tPercent of CPU this job got: 41%\n\
            \tElapsed (wall clock) time (h:mm:ss or m:ss): 2:06.42\n\
            \tMaximum resident set size (kbytes): 65652\n";
        let (cpu, wall, rss) = parse_time_v(text).unwrap();
        assert!((cpu - 52.64).abs() < 1e-9);
        assert!((wall - 126.42).abs() < 1e-9);
        assert_eq!(rss, 65652.0);
        let long = text.replace("2:06.42", "1:02:06.5");
        assert!((parse_time_v(&long).unwrap().1 - 3726.5).abs() < 1e-9);
        assert!(parse_time_v("User time (seconds): 1\n").is_none());
        assert_eq!(median(vec![3.0, 1.0, 2.0, 10.0]), 2.5);
    }

    /// A bench log's first lines: the comment is not a record, the FLASER line is record 2
    /// with its `ipc_timestamp`; `slam eval`'s aligned figure is read from its ATE line.
    #[test]
    fn finds_the_scans_and_the_aligned_ate() {
        let log = "# made by gfs-to-bench\n\
            ODOM 0 0 0 0 0 0 10.5 bench 10.5\n\
            ODOM 0.1 0 0 0 0 0 10.7 bench 10.7\n\
            FLASER 3 1.0 2.0 3.0 0.1 0 0 0.1 0 0 10.75 bench 10.75\n\
            ODOM 0.2 0 0 0 0 0 10.9 bench 10.9\n";
        assert_eq!(scan_records(log), vec![(2, 10.75)]);
        let tum = "# timestamp x y z qx qy qz qw\n10.5 0 0 0 0 0 0 1\n10.7 1 0 0 0 0 0 1\n\
            10.75 2 0 0 0 0 0 1\n10.9 3 0 0 0 0 0 1\n";
        assert_eq!(
            gridfast_at_scans(tum, &scan_records(log)).unwrap(),
            "10.75 2 0 0 0 0 0 1\n"
        );
        assert!(gridfast_at_scans("10.5 0 0 0 0 0 0 1\n", &[(3, 1.0)]).is_err());
        let eval = "estimate: a.tum (910 poses)\nground truth: b (13700 poses, 998 matched)\n  \
            ATE RMSE 1.4520 m, aligned 0.2804 m\n  RPE mean 0.0337 m / 0.845 deg\n";
        assert_eq!(parse_aligned_ate(eval), Some(0.2804));
        assert_eq!(parse_aligned_ate("RPE mean 1 m\n"), None);
    }

    /// MRPT's base ini with the overrides: a key the base has is replaced in place (its
    /// `// comment` goes with it), a key it lacks is added under `[MappingApplication]`,
    /// other sections keep their own keys of the same name.
    #[test]
    fn builds_the_peer_ini_from_mrpt_s_own() {
        let base = "# MRPT\n[MappingApplication]\nsampleSize=10\t\t// Sample size\n\
            SAVE_3D_SCENE=1\n[MappingApplication_pointsMap_00_insertOpts]\nsampleSize=3\n";
        let ours = "# ours\nbase = /usr/share/x.ini\n[MappingApplication]\nsampleSize = 30 // N\n\
            RANDOM_SEED=1\n";
        let pairs = ini_pairs(ours);
        assert_eq!(pairs[0], ("base".into(), "/usr/share/x.ini".into()));
        let got = override_ini(base, &pairs[1..]);
        assert_eq!(
            got,
            "# MRPT\n[MappingApplication]\nRANDOM_SEED=1\nsampleSize=30\nSAVE_3D_SCENE=1\n\
             [MappingApplication_pointsMap_00_insertOpts]\nsampleSize=3\n"
        );
    }

    /// The initial pose is dropped, a quarter turn's yaw becomes the quaternion
    /// (0, 0, sin 45°, cos 45°) on the scan's time stamp; a path with a pose missing, or a
    /// line that is not `x y yaw`, is refused.
    #[test]
    fn writes_the_peer_path_as_tum() {
        let scans = [(0, 1.0), (5, 2.5)];
        let path = "0.000 0.000 0.000\n0.000 0.000 0.000\n1.000 -2.000 1.5707963\n";
        let tum = rbpf_path_at_scans(path, &scans).unwrap();
        let rows: Vec<Vec<f64>> = tum
            .lines()
            .map(|l| l.split(' ').map(|x| x.parse().unwrap()).collect())
            .collect();
        assert_eq!(rows[0], vec![1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
        assert_eq!(&rows[1][..4], &[2.5, 1.0, -2.0, 0.0]);
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert!((rows[1][6] - h).abs() < 1e-7 && (rows[1][7] - h).abs() < 1e-7);
        assert!(rbpf_path_at_scans("0 0 0\n1 1 1\n", &scans).is_err());
        assert!(rbpf_path_at_scans("0 0 0\n0 0\n1 1 1\n", &scans).is_err());
    }
}
