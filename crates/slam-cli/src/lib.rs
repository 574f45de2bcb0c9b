//! # slam-cli: the `slam` program
//!
//! ```text
//! slam run  --filter <name> (--sim <scenario> [--seed N] [--steps N] | --dataset <path> [--robot N]
//!           [--scan-topic T] [--odom-topic T] [--laser-pose x,y,θ])
//!           [--particles N] [--config <file.toml>] [--ground-truth <file.tum>] [--relations <file>]
//!           [--out <dir>] [--force] [--threads N] [--frames <dir> [--frame-every K]]
//!           [--mcap <file.mcap> [--mcap-every K]] [--quiet]
//! slam sim  <scenario> [--seed N] [--steps N] --out <dir>
//! slam eval --estimate <file.tum> (--ground-truth <file.tum> | --relations <file>)
//! slam optimize <graph.g2o> --out <dir> [--config <file.toml>] [--kernel <name:param>]
//! slam list
//! slam info <path>
//! slam completions <bash|zsh|fish|elvish|powershell>
//! ```
//!
//! The program is this library plus a thin `main`: [`main_with_args`] parses a command line,
//! runs it, writes the human summary to the given writer and returns what it did
//! ([`Outcome`]), so tests drive the program without a subprocess. Errors are a
//! [`CliError`], printed by `main` as one line `slam: error: …` with a non-zero exit code.
//!
//! Output of `slam run` (in `--out`, default `./slam-out/<filter>-<dataset>`):
//! `trajectory.tum`, `map.png`, `landmarks.csv` (landmark filters) or `map.pgm` + `map.yaml`
//! (laser filters), `config.toml` (the configuration actually used) and `metrics.json`
//! ([`Metrics`], a fixed set of keys, `null` where a figure cannot be computed), written
//! last: a folder with `metrics.json` holds one complete run (see `outdir` for the rules on
//! whose folder may be written and how an interrupted run leaves nothing behind).
//! `map.png` has a title (filter, data, particle count, seed), a legend, and axes and a
//! scale bar in metres. With `--frames DIR` a landmark run also writes
//! `DIR/frame-000001.png`, … every `--frame-every` steps, the frames of an animation of the
//! run. With `--mcap FILE` the run is also written as an MCAP file of ROS 2 messages for
//! Foxglove and `ros2 bag play` (docs/rosbag.md).

#![warn(missing_docs)]

pub mod cli;
mod config;
pub mod error;
pub mod eval;
pub mod filters;
mod info;
mod list;
pub mod localize;
mod mcap;
pub mod optimize;
mod outdir;
mod pictures;
mod poses;
mod progress;
pub mod ros2;
pub mod run;
pub mod sim;

pub use error::CliError;
pub use eval::EvalReport;
pub use optimize::OptimizeOutput;
pub use run::RunReport;
pub use sim::SimReport;
pub use slam_eval::Metrics;

use clap::error::ErrorKind;
use clap::{CommandFactory, Parser};
use std::ffi::OsString;
use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};

/// Set when the user asked the program to stop (Ctrl-C); `slam run` checks it between steps.
static STOP: AtomicBool = AtomicBool::new(false);

/// Asks a running `slam run` to stop at its next step (what `main`'s Ctrl-C handler calls);
/// returns whether a stop had been asked for already.
pub fn request_stop() -> bool {
    STOP.swap(true, Ordering::SeqCst)
}

/// Whether a stop was asked for.
pub(crate) fn stop_requested() -> bool {
    STOP.load(Ordering::SeqCst)
}

/// `--live [ADDRESS]`: the Foxglove WebSocket server of a run, on its topics, announced on
/// `out`; `None` without the option.
pub(crate) fn start_live(
    address: Option<&str>,
    topics: impl Fn(slam_ros::Out) -> String,
    out: &mut dyn Write,
) -> Result<Option<slam_ros::LiveServer>, CliError> {
    let Some(address) = address else {
        return Ok(None);
    };
    let server =
        slam_ros::LiveServer::start(address, topics).map_err(|e| CliError::Ros(Box::new(e)))?;
    let _ = writeln!(
        out,
        "live: Foxglove WebSocket on ws://{} (Foxglove: Open connection → Foxglove WebSocket)",
        server.address()
    );
    Ok(Some(server))
}

/// `--live-hold` (`hold`): the finished run or localization stays on the live view until
/// Ctrl-C.
pub(crate) fn hold_live(hold: bool, live: Option<&slam_ros::LiveServer>) {
    if let (true, Some(server)) = (hold, live) {
        eprintln!(
            "live: the run is done; serving its last state on ws://{} until Ctrl-C",
            server.address()
        );
        while !stop_requested() {
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
    }
}

/// What a successful command did.
#[derive(Debug)]
pub enum Outcome {
    /// Help or version text was printed.
    Help,
    /// `slam list` printed the filters and scenarios.
    Listed,
    /// `slam run` finished.
    Ran(Box<RunReport>),
    /// `slam sim` wrote a dataset.
    Simulated(SimReport),
    /// `slam eval` computed metrics.
    Evaluated(EvalReport),
    /// `slam optimize` optimised a pose graph.
    Optimized(Box<OptimizeOutput>),
    /// `slam info` described a dataset.
    Described,
    /// `slam localize` ran.
    Localized(Box<localize::LocalizeReport>),
    /// `slam completions` printed a shell completion script.
    Completions,
    /// `slam ros2` ran until Ctrl-C.
    Ros2(Box<slam_ros::NodeReport>),
}

impl Outcome {
    /// The process exit status of a successful command: 0, except 3 for a `slam optimize`
    /// whose result is worse than its start or that diverged or was singular.
    pub fn exit_code(&self) -> u8 {
        match self {
            Outcome::Optimized(r) if r.worse_than_start => 3,
            _ => 0,
        }
    }
}

/// Parses `args` (the first item is the program name, as in `std::env::args_os()`), runs
/// the command and writes its human-readable output to `out`.
pub fn main_with_args<I, T>(args: I, out: &mut dyn Write) -> Result<Outcome, CliError>
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let parsed = match cli::Cli::try_parse_from(args) {
        Ok(c) => c,
        Err(e) => {
            return match e.kind() {
                ErrorKind::DisplayHelp | ErrorKind::DisplayVersion => {
                    let _ = write!(out, "{}", e.render());
                    Ok(Outcome::Help)
                }
                _ => Err(CliError::Usage(usage_message(&e))),
            }
        }
    };
    match parsed.command {
        cli::Command::Run(a) => run::run(&a, out).map(|r| Outcome::Ran(Box::new(r))),
        cli::Command::Sim(a) => sim::sim(&a, out).map(Outcome::Simulated),
        cli::Command::Eval(a) => eval::eval(&a, out).map(Outcome::Evaluated),
        cli::Command::Optimize(a) => {
            optimize::optimize(&a, out).map(|r| Outcome::Optimized(Box::new(r)))
        }
        cli::Command::Localize(a) => {
            localize::localize(&a, out).map(|r| Outcome::Localized(Box::new(r)))
        }
        cli::Command::Ros2(a) => ros2::ros2(&a, out).map(|r| Outcome::Ros2(Box::new(r))),
        cli::Command::Info(a) => info::info(&a, out).map(|_| Outcome::Described),
        cli::Command::Completions(a) => {
            // Into a buffer first: clap_complete panics on a write error (a closed pipe,
            // `slam completions bash | head`); like the other outputs, ours ignores it.
            let mut script = Vec::new();
            clap_complete::generate(a.shell, &mut cli::Cli::command(), "slam", &mut script);
            let _ = out.write_all(&script);
            Ok(Outcome::Completions)
        }
        cli::Command::List => {
            list::list(out);
            Ok(Outcome::Listed)
        }
    }
}

/// Clap's error as one line: its first paragraph (with the possible values when it lists
/// them) and its `tip:` lines (clap's "a similar subcommand/value/argument exists"
/// suggestions), whitespace collapsed, without the `error:` prefix, plus a pointer to `--help`.
fn usage_message(e: &clap::Error) -> String {
    if e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
        return "missing subcommand: run, sim, eval, optimize, localize, ros2, info, list or completions (see `slam --help`)"
            .into();
    }
    let text = e.render().to_string();
    let first: Vec<&str> = text
        .lines()
        .take_while(|l| !l.trim().is_empty())
        .map(str::trim)
        .collect();
    let tips = text
        .lines()
        .map(str::trim)
        .filter(|l| l.starts_with("tip:"));
    let line = first.into_iter().chain(tips).collect::<Vec<_>>().join(" ");
    let line = line.strip_prefix("error:").unwrap_or(&line).trim();
    format!("{line} (see `slam --help`)")
}
