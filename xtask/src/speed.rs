//! `cargo xtask eval speed`: grid FastSLAM against GMapping, side by side on one machine,
//! measured with `/usr/bin/time -v` (issue 21's speed requirement).

use crate::{cargo, run};
use std::path::{Path, PathBuf};
use std::process::Command;

/// One measured run: CPU (user + system) and wall seconds, peak resident set size in KiB.
#[derive(Debug, Clone, Copy)]
struct Usage {
    cpu: f64,
    wall: f64,
    rss_kib: f64,
}

/// The three programs of a pair, in the order of [`RUNNERS`].
const RUNNERS: [&str; 3] = ["gridfast 1 thread", "gridfast 2 threads", "GMapping"];

/// `cargo xtask eval speed [--pairs N] [--other-pairs M] [--only a,b] [--gmapping-src DIR]`:
/// grid FastSLAM (30 particles, seed 0, `--threads 1` and `--threads 2`) and GMapping
/// (`../shared/tools/gmapping`, built from a copy of its public repository, 30 particles,
/// seed 1, the ROS wrapper's defaults) on every log of `../shared/datasets/bench`, each
/// program under `/usr/bin/time -v`.
///
/// The three runs of a round follow each other, and the order rotates from round to round
/// (1-thread, 2-thread, GMapping; then 2-thread, GMapping, 1-thread; ...), so that a change
/// of the machine's load touches all three alike. `bench/intel.log` gets `--pairs` rounds
/// (default 3), every other log `--other-pairs` (default 1). The ratios are taken within each
/// round and their median reported (with the range): on a machine shared with other work
/// the absolute times drift, the ratios of neighbouring runs much less.
///
/// GMapping's source: `--gmapping-src DIR` or `$GMAPPING_SRC`, an unpacked tree of
/// `github.com/ros-perception/openslam_gmapping` (`git clone` it, or
/// `git --git-dir=<its git dir> archive HEAD | tar -x -C DIR`); it is built with cmake into
/// `<target>/speed/gmapping-build` (see `../shared/tools/gmapping/BUILD.md`). `$GMAPPING_BIN`
/// names an already built `gmapping_offline` instead; `$SLAM_BIN` a `slam` executable (else
/// it is built). Every run's output goes to `<target>/speed/` (`<target>` is
/// `$CARGO_TARGET_DIR` or `target`); the table is printed and written to
/// `slam-out/speed/summary.md`.
pub(crate) fn speed(extra: &[String]) -> Result<(), String> {
    let (mut pairs, mut other_pairs) = (3usize, 1usize);
    let mut only: Option<Vec<String>> = None;
    let mut src = std::env::var_os("GMAPPING_SRC").map(PathBuf::from);
    let mut it = extra.iter();
    let count = |v: Option<&String>, what: &str| {
        v.and_then(|v| v.parse().ok())
            .filter(|&n: &usize| n > 0)
            .ok_or(format!("{what} takes a positive count"))
    };
    while let Some(a) = it.next() {
        match a.as_str() {
            "--pairs" => pairs = count(it.next(), "--pairs")?,
            "--other-pairs" => other_pairs = count(it.next(), "--other-pairs")?,
            "--only" => {
                only = Some(
                    it.next()
                        .ok_or("--only takes log names, comma separated")?
                        .split(',')
                        .map(str::to_string)
                        .collect(),
                )
            }
            "--gmapping-src" => {
                src = Some(PathBuf::from(
                    it.next().ok_or("--gmapping-src takes a folder")?,
                ))
            }
            other => return Err(format!("eval speed: unknown argument {other:?}")),
        }
    }
    let data = std::env::var_os("SLAM_DATASETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("../shared/datasets"));
    let tools = data.join("../tools");
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("target"));
    let scratch = target.join("speed");
    std::fs::create_dir_all(&scratch).map_err(|e| format!("{}: {e}", scratch.display()))?;
    let time = Path::new("/usr/bin/time");
    if !time.exists() {
        return Err("/usr/bin/time not found (GNU time: `apt-get install time`)".into());
    }

    let gmapping = match std::env::var_os("GMAPPING_BIN") {
        Some(bin) => PathBuf::from(bin),
        None => {
            let src = src.ok_or(
                "GMapping's source is needed: set GMAPPING_SRC (or --gmapping-src DIR) to an \
                 unpacked copy of github.com/ros-perception/openslam_gmapping (`git clone` it, \
                 or `git --git-dir=<its git dir> archive HEAD | tar -x -C DIR`), outside the \
                 repository; or GMAPPING_BIN to a built gmapping_offline \
                 (see ../shared/tools/gmapping/BUILD.md)",
            )?;
            if !src.join("gridfastslam").is_dir() {
                return Err(format!(
                    "{}: not an openslam_gmapping tree (no gridfastslam/ folder)",
                    src.display()
                ));
            }
            let src = std::fs::canonicalize(&src).map_err(|e| format!("{}: {e}", src.display()))?;
            let build = scratch.join("gmapping-build");
            run(
                "configure GMapping",
                Command::new("cmake")
                    .arg("-S")
                    .arg(tools.join("gmapping"))
                    .arg("-B")
                    .arg(&build)
                    .arg(format!("-DGMAPPING_SRC={}", src.display())),
            )?;
            run(
                "build GMapping",
                Command::new("cmake").arg("--build").arg(&build).arg("-j2"),
            )?;
            build.join("gmapping_offline")
        }
    };
    let slam = match std::env::var_os("SLAM_BIN") {
        Some(bin) => PathBuf::from(bin),
        None => {
            run(
                "build slam",
                cargo().args(["build", "--release", "-p", "slam-cli"]),
            )?;
            target.join("release").join("slam")
        }
    };

    let mut logs: Vec<PathBuf> = std::fs::read_dir(data.join("bench"))
        .map_err(|e| format!("{}: {e}", data.join("bench").display()))?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "log"))
        .collect();
    logs.sort();
    // Intel first: its figures are the ones the issue asks for.
    logs.sort_by_key(|p| p.file_stem().is_none_or(|s| s != "intel"));
    let stem = |p: &Path| {
        p.file_stem()
            .unwrap_or_default()
            .to_string_lossy()
            .to_string()
    };
    logs.retain(|p| only.as_ref().is_none_or(|o| o.contains(&stem(p))));
    if logs.is_empty() {
        return Err("no bench log selected".into());
    }

    let load_before = load_average();
    let mut usage_table = String::from(
        "| log | program | runs | CPU user+sys median (s) | wall median (s) | peak RSS median (MB) |\n|---|---|---|---|---|---|\n",
    );
    let mut ratio_table = String::from(
        "| log | pairs | GMapping CPU / gridfast 1-thread CPU | gridfast wall 1 thread / 2 threads | gridfast 1-thread RSS / GMapping RSS |\n|---|---|---|---|---|\n",
    );
    for log in &logs {
        let name = stem(log);
        let rounds = if name == "intel" { pairs } else { other_pairs };
        // usage[round][runner]
        let mut usage: Vec<[Usage; 3]> = Vec::new();
        for round in 0..rounds {
            let mut got = [Usage {
                cpu: f64::NAN,
                wall: f64::NAN,
                rss_kib: f64::NAN,
            }; 3];
            for k in 0..3 {
                let runner = (round + k) % 3;
                let dir = scratch.join(format!("{name}-{runner}-{round}"));
                let _ = std::fs::remove_dir_all(&dir);
                let report = scratch.join(format!("{name}-{runner}-{round}.time-v.txt"));
                let mut cmd = Command::new(time);
                cmd.arg("-v").arg("-o").arg(&report);
                if runner < 2 {
                    cmd.arg(&slam)
                        .args(["run", "--filter", "gridfast", "--particles", "30"])
                        .args(["--seed", "0", "--quiet", "--threads"])
                        .arg((runner + 1).to_string())
                        .arg("--dataset")
                        .arg(log)
                        .arg("--out")
                        .arg(&dir);
                } else {
                    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
                    cmd.arg(&gmapping)
                        .arg(log)
                        .arg(dir.join(&name))
                        .args(["--seed", "1"]);
                }
                cmd.stdout(std::process::Stdio::null());
                run(
                    &format!("{name} round {} {}", round + 1, RUNNERS[runner]),
                    &mut cmd,
                )?;
                let text = std::fs::read_to_string(&report)
                    .map_err(|e| format!("{}: {e}", report.display()))?;
                got[runner] = parse_time_v(&text)
                    .ok_or(format!("{}: no CPU, wall or RSS line", report.display()))?;
                eprintln!(
                    "xtask:    CPU {:.2} s, wall {:.2} s, peak RSS {:.1} MB",
                    got[runner].cpu,
                    got[runner].wall,
                    got[runner].rss_kib / 1024.0
                );
            }
            usage.push(got);
        }
        for (r, runner) in RUNNERS.iter().enumerate() {
            let col = |f: fn(&Usage) -> f64| median(usage.iter().map(|u| f(&u[r])).collect());
            usage_table.push_str(&format!(
                "| {name} | {runner} | {} | {:.2} | {:.2} | {:.1} |\n",
                usage.len(),
                col(|u| u.cpu),
                col(|u| u.wall),
                col(|u| u.rss_kib) / 1024.0
            ));
        }
        let ratio = |f: fn(&[Usage; 3]) -> f64| {
            let v: Vec<f64> = usage.iter().map(f).collect();
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
        };
        ratio_table.push_str(&format!(
            "| {name} | {} | {} | {} | {} |\n",
            usage.len(),
            ratio(|u| u[2].cpu / u[0].cpu),
            ratio(|u| u[0].wall / u[1].wall),
            ratio(|u| u[0].rss_kib / u[2].rss_kib),
        ));
    }
    let machine = format!(
        "Machine: {} × {}; load average (1/5/15 min) {} before, {} after. Ratios: median over \
         the rounds of the per-round ratio (range in brackets).\n",
        std::thread::available_parallelism().map_or(0, |n| n.get()),
        cpu_model(),
        load_before,
        load_average()
    );
    let summary = format!("{machine}\n{ratio_table}\n{usage_table}");
    println!("{summary}");
    let out = Path::new("slam-out/speed");
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let file = out.join("summary.md");
    std::fs::write(&file, &summary).map_err(|e| format!("{}: {e}", file.display()))?;
    println!("xtask: wrote {}", file.display());
    Ok(())
}

/// CPU (user + system), wall time and peak RSS from GNU time's `-v` report.
fn parse_time_v(text: &str) -> Option<Usage> {
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
    Some(Usage {
        cpu: user + sys,
        wall,
        rss_kib,
    })
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

    /// GNU time 1.9's `-v` report, as printed for a run of `gmapping_offline`.
    #[test]
    fn reads_gnu_time_report() {
        let text = "\tCommand being timed: \"gmapping_offline intel.log out --seed 1\"\n\
            \tUser time (seconds): 52.55\n\tSystem time (seconds): 0.09\n\
            \tPercent of CPU this job got: 41%\n\
            \tElapsed (wall clock) time (h:mm:ss or m:ss): 2:06.42\n\
            \tMaximum resident set size (kbytes): 65652\n";
        let u = parse_time_v(text).unwrap();
        assert!((u.cpu - 52.64).abs() < 1e-9);
        assert!((u.wall - 126.42).abs() < 1e-9);
        assert_eq!(u.rss_kib, 65652.0);
        let long = text.replace("2:06.42", "1:02:06.5");
        assert!((parse_time_v(&long).unwrap().wall - 3726.5).abs() < 1e-9);
        assert!(parse_time_v("User time (seconds): 1\n").is_none());
        assert_eq!(median(vec![3.0, 1.0, 2.0, 10.0]), 2.5);
    }
}
