//! `cargo xtask eval robust`: every laser filter on every input the project can score,
//! with the runs counted lost (see [`robust`]).

use crate::{build_slam, run};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The laser filters of the suite, in the order of the tables and the contact sheet.
const FILTERS: [&str; 3] = ["graph", "gridfast", "scanmatch"];

/// A run is lost above this aligned ATE, metres (issue 21).
const LOST_ATE: f64 = 1.0;

/// A run's map contradicts itself above this fraction of contradicting scans
/// (`metrics.json`'s `map_contradicting_fraction`): slam-eval's default
/// `MapCheckParams::scan_fraction`, which `map_inconsistent` uses. Read from the fraction
/// so that runs written before that default was set are judged alike.
const LOST_CONTRADICTING: f64 = 0.15;

/// One input of the robustness suite: a log with the trajectory it is scored against.
struct RobustCase {
    /// Short name: `<log>`, `<log>-moderate`, `<log>-hard`, `campus` or `office`.
    name: String,
    log: PathBuf,
    truth: PathBuf,
    /// Whether `truth` is exact (simulated or perturbed) or GMapping's reference (bench).
    exact: bool,
    relations: Option<PathBuf>,
}

/// The suite's options (see [`robust`]).
struct Options {
    seeds: u64,
    filters: Vec<String>,
    only: Option<Vec<String>>,
    keep: bool,
    no_run: bool,
}

impl Options {
    fn parse(extra: &[String]) -> Result<Self, String> {
        let mut o = Options {
            seeds: 5,
            filters: FILTERS.iter().map(|f| f.to_string()).collect(),
            only: None,
            keep: false,
            no_run: false,
        };
        let list = |v: Option<&String>, what: &str| -> Result<Vec<String>, String> {
            Ok(v.ok_or(format!("{what} takes names, comma separated"))?
                .split(',')
                .map(str::to_string)
                .collect())
        };
        let mut it = extra.iter();
        while let Some(a) = it.next() {
            match a.as_str() {
                "--seeds" => {
                    o.seeds = it
                        .next()
                        .and_then(|v| v.parse().ok())
                        .filter(|&n| n > 0)
                        .ok_or("--seeds takes a positive count")?
                }
                "--only" => o.only = Some(list(it.next(), "--only")?),
                "--filters" => {
                    o.filters = list(it.next(), "--filters")?;
                    if let Some(f) = o.filters.iter().find(|f| !FILTERS.contains(&f.as_str())) {
                        return Err(format!(
                            "--filters: unknown filter {f:?} (one of {})",
                            FILTERS.join(", ")
                        ));
                    }
                }
                "--keep" => o.keep = true,
                "--no-run" => (o.keep, o.no_run) = (true, true),
                other => return Err(format!("eval robust: unknown argument {other:?}")),
            }
        }
        Ok(o)
    }

    fn wanted(&self, name: &str) -> bool {
        self.only
            .as_ref()
            .is_none_or(|o| o.iter().any(|x| x == name))
    }

    /// The filter seeds of `filter`: 0..N for the particle filter; the graph front end and
    /// scan-matching odometry draw no random numbers (one run, seed 0).
    fn seeds_of(&self, filter: &str) -> u64 {
        if filter == "gridfast" {
            self.seeds
        } else {
            1
        }
    }
}

/// `cargo xtask eval robust`: every laser filter (`graph`, `gridfast` with 30 particles,
/// `scanmatch`; `--filters a,b` to choose), with its defaults, on every log in
/// `../shared/datasets/bench` against its reference trajectory; on every
/// `radish-corrected` log with its odometry replaced by `../shared/tools/perturb-odometry`
/// at the `moderate` and `hard` profiles (the corrected poses are then exact ground truth);
/// and on the simulated `campus` and `office` (seed 1, exact ground truth). Grid FastSLAM
/// with filter seeds 0..N (default 5); the other two are deterministic, one run each.
///
/// A run is lost when it fails, when its aligned ATE is above 1 m, or when its map
/// contradicts itself without any truth (`metrics.json`'s `map_contradicting_fraction`
/// above 15 %, its `map_inconsistent`: the scans look through walls that other scans of the run saw — a bent or
/// doubled map; `slam_eval::metrics::map_contradictions`).
///
/// Prints and writes `slam-out/robust/summary.md`: per filter one line (median and worst
/// aligned ATE over all its runs, lost runs), then per filter and input the median and
/// worst aligned ATE, the median relations error where relations exist, the runs lost
/// (of those, by ATE and by contradiction), the median fraction of contradicting scans
/// and the scan matches failed and recovered; and `slam-out/robust/contact-sheet.png`:
/// one row per input, one column per filter, each the map of its worst run (a lost run
/// first).
///
/// Runs go to `slam-out/robust/<filter>/<input>-seed<s>`. `--only a,b` runs those inputs
/// only; `--keep` reuses the runs already there (a folder with its `metrics.json`)
/// instead of repeating them, so the suite can be run in pieces and summarised at the end;
/// `--no-run` only summarises the runs there (a seed without one is left out, and the
/// table says how many were run). `SLAM_BIN` names a `slam` executable to use instead of
/// building one.
pub(crate) fn robust(extra: &[String]) -> Result<(), String> {
    let o = Options::parse(extra)?;
    let data = std::env::var_os("SLAM_DATASETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("../shared/datasets"));
    if !data.join("bench").is_dir() {
        return Err(format!("{} not found", data.join("bench").display()));
    }
    let exe = match std::env::var_os("SLAM_BIN") {
        Some(bin) => PathBuf::from(bin),
        None => build_slam()?,
    };
    let out = Path::new("slam-out/robust");
    let cases = cases(&o, &data, &exe, out)?;

    let mut per_filter = String::from(
        "| filter | runs | ATE aligned median / worst (m) | worst input | lost (ATE > 1 m / map contradicts itself / failed) |\n|---|---|---|---|---|\n",
    );
    let mut table = String::from(
        "| filter | input | truth | ATE aligned median / worst (m) | relations median (m / deg; on the relations the log's clock leaves unambiguous) | lost of runs (ATE / contradiction / failed) | contradicting scans median / worst | matches failed / recovered (median per run) |\n|---|---|---|---|---|---|---|---|\n",
    );
    // One row per input, one column per filter: the map of the worst run.
    let mut sheet = vec![vec![None; o.filters.len()]; cases.len()];
    for (fi, filter) in o.filters.iter().enumerate() {
        let mut all = Vec::new();
        let mut worst_input: Option<(f64, &str)> = None;
        let mut lost_all = Lost::default();
        for (ci, case) in cases.iter().enumerate() {
            let runs = run_case(&o, &exe, out, filter, case);
            let s = Summary::of(&runs);
            lost_all.add(&s.lost);
            all.extend(s.ates.iter().copied());
            if let Some(w) = s.worst_ate {
                if worst_input.is_none_or(|(x, _)| w > x) {
                    worst_input = Some((w, &case.name));
                }
            }
            let truth = if case.exact {
                "exact"
            } else {
                "GMapping reference"
            };
            table.push_str(&format!(
                "| {filter} | {} | {truth} | {} | {} | {} of {} ({} / {} / {}) | {} | {} |\n",
                case.name,
                median_worst(&s.ates, 3),
                s.relations(),
                s.lost.total(),
                runs.len(),
                s.lost.ate,
                s.lost.contradiction,
                s.lost.failed,
                median_worst(&s.contradicting, 3),
                s.matches(),
            ));
            sheet[ci][fi] = s.worst_map;
        }
        per_filter.push_str(&format!(
            "| {filter} | {} | {} | {} | {} ({} / {} / {}) |\n",
            lost_all.runs,
            median_worst(&all, 3),
            worst_input.map_or("–", |(_, n)| n),
            lost_all.total(),
            lost_all.ate,
            lost_all.contradiction,
            lost_all.failed,
        ));
    }
    let text = format!("{per_filter}\n{table}");
    println!("{text}");
    let summary = out.join("summary.md");
    std::fs::write(&summary, &text).map_err(|e| format!("{}: {e}", summary.display()))?;
    println!("xtask: wrote {}", summary.display());
    let contact = out.join("contact-sheet.png");
    contact_sheet(&sheet, o.filters.len(), &contact)?;
    println!("xtask: wrote {}", contact.display());
    Ok(())
}

/// The suite's inputs that `o` asks for, perturbing and simulating the ones not made yet
/// into `out/inputs`.
fn cases(o: &Options, data: &Path, exe: &Path, out: &Path) -> Result<Vec<RobustCase>, String> {
    let tools = data.join("../tools");
    let inputs = out.join("inputs");
    std::fs::create_dir_all(&inputs).map_err(|e| format!("{}: {e}", inputs.display()))?;
    let mut cases = Vec::new();
    let mut bench: Vec<_> = std::fs::read_dir(data.join("bench"))
        .map_err(|e| e.to_string())?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "log"))
        .collect();
    bench.sort();
    for log in &bench {
        let stem = log
            .file_stem()
            .unwrap_or_default()
            .to_string_lossy()
            .to_string();
        let relations = data.join(format!("slam-benchmark-relations/{stem}.relations"));
        cases.push(RobustCase {
            name: stem.clone(),
            log: log.clone(),
            truth: log.with_extension("ref.tum"),
            exact: false,
            relations: relations.exists().then_some(relations),
        });
    }
    let mut corrected: Vec<_> = std::fs::read_dir(data.join("radish-corrected"))
        .map_err(|e| e.to_string())?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.to_string_lossy().ends_with("-corrected.log.gz"))
        .collect();
    corrected.sort();
    for log in &corrected {
        let file = log
            .file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .to_string();
        let stem = file.trim_end_matches("-corrected.log.gz");
        for profile in ["moderate", "hard"] {
            let name = format!("{stem}-{profile}");
            if !o.wanted(&name) {
                continue;
            }
            let prefix = inputs.join(&name);
            if !prefix.with_extension("log").exists() && !o.no_run {
                run(
                    &format!("perturb {name}"),
                    Command::new(tools.join("perturb-odometry"))
                        .arg(log)
                        .arg(&prefix)
                        .args(["--seed", "1", "--profile", profile]),
                )?;
            }
            cases.push(RobustCase {
                name,
                log: prefix.with_extension("log"),
                truth: inputs.join(format!("{stem}-{profile}.gt.tum")),
                exact: true,
                relations: None,
            });
        }
    }
    for scenario in ["campus", "office"] {
        let dir = inputs.join(scenario);
        let log = dir.join(format!("{scenario}.log"));
        if !log.exists() && o.wanted(scenario) && !o.no_run {
            run(
                &format!("simulate {scenario}"),
                Command::new(exe)
                    .args(["sim", scenario, "--seed", "1", "--out"])
                    .arg(&dir),
            )?;
        }
        cases.push(RobustCase {
            name: scenario.into(),
            log,
            truth: dir.join("ground_truth.tum"),
            exact: true,
            relations: None,
        });
    }
    cases.retain(|c| o.wanted(&c.name));
    Ok(cases)
}

/// One run's figures from its `metrics.json` (`None`: the run failed or is missing).
struct RunResult {
    dir: PathBuf,
    ok: bool,
    metrics: String,
}

/// Runs (or, with `--keep`, reuses) every seed of `filter` on `case`.
fn run_case(
    o: &Options,
    exe: &Path,
    out: &Path,
    filter: &str,
    case: &RobustCase,
) -> Vec<RunResult> {
    let mut runs = Vec::new();
    for seed in 0..o.seeds_of(filter) {
        let dir = out.join(filter).join(format!("{}-seed{seed}", case.name));
        let done = o.keep && dir.join("metrics.json").is_file();
        if o.no_run && !done {
            continue;
        }
        let ok = done || {
            let _ = std::fs::remove_dir_all(&dir);
            let mut cmd = Command::new(exe);
            cmd.args(["run", "--filter", filter, "--quiet"]);
            if filter == "gridfast" {
                cmd.args(["--particles", "30"]);
            }
            cmd.arg("--dataset")
                .arg(&case.log)
                .arg("--ground-truth")
                .arg(&case.truth)
                .args(["--seed", &seed.to_string(), "--out"])
                .arg(&dir);
            if let Some(r) = &case.relations {
                cmd.arg("--relations").arg(r);
            }
            run(&format!("{filter} {} seed {seed}", case.name), &mut cmd).is_ok()
        };
        let metrics = std::fs::read_to_string(dir.join("metrics.json")).unwrap_or_default();
        runs.push(RunResult { dir, ok, metrics });
    }
    runs
}

/// Lost runs by cause (a run lost for two causes counts once, under the first).
#[derive(Default)]
struct Lost {
    runs: usize,
    ate: usize,
    contradiction: usize,
    failed: usize,
}

impl Lost {
    fn total(&self) -> usize {
        self.ate + self.contradiction + self.failed
    }

    fn add(&mut self, o: &Lost) {
        self.runs += o.runs;
        self.ate += o.ate;
        self.contradiction += o.contradiction;
        self.failed += o.failed;
    }
}

/// One filter's runs on one input, summarised.
struct Summary {
    ates: Vec<f64>,
    worst_ate: Option<f64>,
    rel: Vec<(f64, f64)>,
    /// The relations metric over the relations the log's clock leaves unambiguous.
    rel_clear: Vec<(f64, f64)>,
    matches: Vec<(f64, f64)>,
    contradicting: Vec<f64>,
    lost: Lost,
    worst_map: Option<PathBuf>,
}

impl Summary {
    fn of(runs: &[RunResult]) -> Self {
        let mut s = Summary {
            ates: Vec::new(),
            worst_ate: None,
            rel: Vec::new(),
            rel_clear: Vec::new(),
            matches: Vec::new(),
            contradicting: Vec::new(),
            lost: Lost {
                runs: runs.len(),
                ..Lost::default()
            },
            worst_map: None,
        };
        // The worst run: failed, then contradicting, then by ATE.
        let mut worst: Option<(f64, &Path)> = None;
        for r in runs {
            let m = &r.metrics;
            let ate = json_number(m, "ate_rmse_aligned_m").filter(|_| r.ok);
            let inconsistent = json_number(m, "map_contradicting_fraction")
                .is_some_and(|x| x > LOST_CONTRADICTING);
            if let Some(a) = ate {
                s.ates.push(a);
            }
            if let Some(c) = json_number(m, "map_contradicting_fraction") {
                s.contradicting.push(c);
            }
            let badness = match ate {
                None => {
                    s.lost.failed += 1;
                    f64::INFINITY
                }
                Some(a) if a > LOST_ATE => {
                    s.lost.ate += 1;
                    a + 1e6 * f64::from(u8::from(inconsistent))
                }
                Some(a) if inconsistent => {
                    s.lost.contradiction += 1;
                    a + 1e6
                }
                Some(a) => a,
            };
            if worst.is_none_or(|(w, _)| badness > w) {
                worst = Some((badness, &r.dir));
            }
            if let (Some(t), Some(d)) = (
                json_number(m, "relations_trans_mean_m"),
                json_number(m, "relations_rot_mean_deg"),
            ) {
                s.rel.push((t, d));
            }
            if let (Some(t), Some(d)) = (
                json_number(m, "relations_unambiguous_trans_mean_m"),
                json_number(m, "relations_unambiguous_rot_mean_deg"),
            ) {
                s.rel_clear.push((t, d));
            }
            if let (Some(f), Some(rec)) = (
                json_number(m, "match_failed"),
                json_number(m, "match_recovered"),
            ) {
                s.matches.push((f, rec));
            }
        }
        s.worst_ate = s.ates.iter().copied().reduce(f64::max);
        s.worst_map = worst.map(|(_, d)| d.join("map.png"));
        s
    }

    fn relations(&self) -> String {
        let of = |v: &[(f64, f64)]| match (
            median(v.iter().map(|r| r.0).collect()),
            median(v.iter().map(|r| r.1).collect()),
        ) {
            (Some(t), Some(r)) => Some(format!("{t:.4} / {r:.3}")),
            _ => None,
        };
        match (of(&self.rel), of(&self.rel_clear)) {
            (Some(all), Some(clear)) => format!("{all} ({clear})"),
            (Some(all), None) => all,
            _ => "–".into(),
        }
    }

    fn matches(&self) -> String {
        match (
            median(self.matches.iter().map(|m| m.0).collect()),
            median(self.matches.iter().map(|m| m.1).collect()),
        ) {
            (Some(f), Some(r)) => format!("{f} / {r}"),
            _ => "–".into(),
        }
    }
}

/// The median (of an even count, the mean of the middle two), `None` when empty.
fn median(mut v: Vec<f64>) -> Option<f64> {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    (n > 0).then(|| 0.5 * (v[(n - 1) / 2] + v[n / 2]))
}

/// "median / worst" with `digits` decimals, "–" when empty.
fn median_worst(v: &[f64], digits: usize) -> String {
    match (median(v.to_vec()), v.iter().copied().reduce(f64::max)) {
        (Some(m), Some(w)) => format!("{m:.digits$} / {w:.digits$}"),
        _ => "–".into(),
    }
}

/// Writes the pictures `rows` (one row per input, `columns` cells each; missing ones left
/// blank) as one PNG, each scaled to fit a 300 × 300 cell.
fn contact_sheet(rows: &[Vec<Option<PathBuf>>], columns: usize, path: &Path) -> Result<(), String> {
    const CELL: u32 = 300;
    let (w, h) = (columns.max(1) as u32, rows.len().max(1) as u32);
    let mut sheet = image::RgbImage::from_pixel(w * CELL, h * CELL, image::Rgb([255; 3]));
    for (r, row) in rows.iter().enumerate() {
        for (c, png) in row.iter().enumerate() {
            let Some(Ok(picture)) = png.as_ref().map(image::open) else {
                continue;
            };
            let thumb = picture.thumbnail(CELL, CELL).to_rgb8();
            let (x, y) = (c as u32 * CELL, r as u32 * CELL);
            image::imageops::overlay(&mut sheet, &thumb, x.into(), y.into());
        }
    }
    sheet
        .save(path)
        .map_err(|e| format!("{}: {e}", path.display()))
}

/// The number after `"key":` in a flat JSON text (`true`/`false` as 1/0), or `None`
/// (absent, `null`).
fn json_number(json: &str, key: &str) -> Option<f64> {
    let at = json.find(&format!("\"{key}\""))? + key.len() + 2;
    let rest = json[at..].trim_start().strip_prefix(':')?.trim_start();
    if rest.starts_with("true") {
        return Some(1.0);
    }
    if rest.starts_with("false") {
        return Some(0.0);
    }
    let end = rest
        .find(|c: char| !(c.is_ascii_digit() || matches!(c, '.' | '-' | '+' | 'e' | 'E')))
        .unwrap_or(rest.len());
    rest[..end].parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_numbers_and_flags() {
        let j = r#"{"a": 1.5, "b": null, "c": true, "d": false, "e": -2e-3}"#;
        assert_eq!(json_number(j, "a"), Some(1.5));
        assert_eq!(json_number(j, "b"), None);
        assert_eq!(json_number(j, "c"), Some(1.0));
        assert_eq!(json_number(j, "d"), Some(0.0));
        assert_eq!(json_number(j, "e"), Some(-2e-3));
        assert_eq!(json_number(j, "f"), None);
    }

    #[test]
    fn filters_are_checked_and_only_gridfast_has_seeds() {
        let args = |s: &str| s.split(' ').map(str::to_string).collect::<Vec<_>>();
        let o = Options::parse(&args("--filters graph,scanmatch --seeds 3")).unwrap();
        assert_eq!(o.filters, ["graph", "scanmatch"]);
        assert_eq!((o.seeds_of("graph"), o.seeds_of("gridfast")), (1, 3));
        assert!(Options::parse(&args("--filters ekf")).is_err());
        assert!(Options::parse(&args("--seeds 0")).is_err());
    }
}
