//! Output folders that never lose the user's data and never look complete when they are not.
//!
//! `slam run` and `slam sim` write through an [`OutDir`]:
//!
//! * **Whose folder.** A command writes into a new or empty folder, or into one that it marked
//!   as its own on an earlier run (the marker file `.slam-run` or `.slam-sim`, which lists the
//!   files that run wrote). `slam run --force` also takes a non-empty folder it did not make;
//!   `slam sim` never does (it must not overwrite a dataset). A folder holding one of the
//!   command's inputs (`--ground-truth`, `--dataset`, …) is refused whatever the flags.
//! * **Checked before the work.** [`OutDir::prepare`] creates the staging folder
//!   `.slam-partial` inside the output folder before any data is read, so a read-only or
//!   missing place fails at once, not after the run.
//! * **Staged, then renamed.** Every output is written into the staging folder and renamed
//!   into place by [`OutDir::commit`] (a rename within one file system is atomic), so no
//!   file is ever seen half-written. The commit first removes the earlier run's
//!   `metrics.json`, then the rest of the earlier run's files (nothing else: only what the
//!   marker lists, or with `--force` the names `slam run` writes), renames the new files and
//!   `metrics.json` last. A folder with `metrics.json` holds one complete run; a folder
//!   without it, or a `.slam-partial` folder, holds an interrupted one.
//! * **Interrupted.** An [`OutDir`] dropped without a commit (an error, Ctrl-C) removes its
//!   staging folder, and the output folder too when it made it and it is still empty: an
//!   interrupted run leaves nothing behind, and an earlier complete run stays as it was.

use crate::error::CliError;
use std::path::{Path, PathBuf};

/// The name of the staging folder inside an output folder.
pub(crate) const STAGE: &str = ".slam-partial";

/// Every file name `slam run` writes (what `--force` replaces in a folder it did not make).
pub(crate) const RUN_OUTPUTS: &[&str] = &[
    "trajectory.tum",
    "trajectory-online.tum",
    "ground_truth.tum",
    "estimates.csv",
    "landmarks.csv",
    "map.pgm",
    "map.yaml",
    "map.png",
    "config.toml",
    "metrics.json",
];

/// The sign of a complete `slam run`, written last.
pub(crate) const METRICS: &str = "metrics.json";

/// Which command owns the folder.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Owner {
    /// `slam run`: marker `.slam-run`.
    Run,
    /// `slam sim`: marker `.slam-sim`.
    Sim,
    /// `slam optimize`: marker `.slam-optimize`.
    Optimize,
    /// `slam localize`: marker `.slam-localize`.
    Localize,
}

impl Owner {
    fn marker(self) -> &'static str {
        match self {
            Owner::Run => ".slam-run",
            Owner::Sim => ".slam-sim",
            Owner::Optimize => ".slam-optimize",
            Owner::Localize => ".slam-localize",
        }
    }

    fn command(self) -> &'static str {
        match self {
            Owner::Run => "slam run",
            Owner::Sim => "slam sim",
            Owner::Optimize => "slam optimize",
            Owner::Localize => "slam localize",
        }
    }
}

/// An output folder being written (see the module docs).
#[derive(Debug)]
pub(crate) struct OutDir {
    dir: PathBuf,
    stage: PathBuf,
    owner: Owner,
    /// `--force` in a folder without our marker: replace the files named in [`RUN_OUTPUTS`].
    force: bool,
    /// The folder did not exist before.
    created: bool,
    committed: bool,
}

fn write_err(path: &Path) -> impl FnOnce(std::io::Error) -> CliError + '_ {
    move |e| CliError::Write {
        path: path.to_path_buf(),
        source: e,
    }
}

/// True when `inner` (an existing path) lies inside the existing folder `dir`.
fn lies_inside(inner: &Path, dir: &Path) -> bool {
    match (inner.canonicalize(), dir.canonicalize()) {
        (Ok(i), Ok(d)) => i.starts_with(d),
        _ => false,
    }
}

impl OutDir {
    /// Checks that `dir` may be written by `owner` and that it can be written at all, before
    /// any work: creates the folder (if new) and its staging folder. `inputs` are the
    /// command's input files as (option, path); none may lie inside `dir`. `force` (for
    /// `slam run`) accepts a non-empty folder the command did not make.
    pub(crate) fn prepare(
        dir: &Path,
        owner: Owner,
        force: bool,
        inputs: &[(&str, &Path)],
    ) -> Result<Self, CliError> {
        let invalid = |msg: String| Err(CliError::InvalidArgument(msg));
        let exists = dir.exists();
        if exists && !dir.is_dir() {
            return invalid(format!(
                "--out {}: exists and is not a folder",
                dir.display()
            ));
        }
        for (option, path) in inputs {
            if exists && lies_inside(path, dir) {
                return invalid(format!(
                    "{option} {} lies inside --out {}, where {} would replace or remove it; \
                     choose another output folder",
                    path.display(),
                    dir.display(),
                    owner.command()
                ));
            }
        }
        let mut ours = false;
        if exists {
            let mut others = Vec::new();
            for entry in std::fs::read_dir(dir).map_err(|source| CliError::Read {
                path: dir.to_path_buf(),
                source,
            })? {
                let entry = entry.map_err(|source| CliError::Read {
                    path: dir.to_path_buf(),
                    source,
                })?;
                let name = entry.file_name().to_string_lossy().to_string();
                if name == owner.marker() {
                    ours = true;
                } else if name != STAGE {
                    others.push(name);
                }
            }
            others.sort();
            if !ours && !others.is_empty() {
                let shown = if others.len() > 4 {
                    format!("{}, … ({} entries)", others[..4].join(", "), others.len())
                } else {
                    others.join(", ")
                };
                match owner {
                    Owner::Run | Owner::Localize if !force => {
                        return invalid(format!(
                            "--out {} is not empty ({shown}) and is not a folder {} \
                             wrote; choose a new or empty folder, or pass --force to replace \
                             its output files in it",
                            dir.display(),
                            owner.command()
                        ))
                    }
                    Owner::Run | Owner::Localize => {}
                    Owner::Sim => {
                        return invalid(format!(
                            "--out {} is not empty ({shown}) and is not a folder slam sim \
                             wrote; slam sim writes only into a new or empty folder, so that \
                             it never overwrites a dataset",
                            dir.display()
                        ))
                    }
                    Owner::Optimize => {
                        return invalid(format!(
                            "--out {} is not empty ({shown}) and is not a folder slam \
                             optimize wrote; slam optimize writes only into a new or empty \
                             folder, so that it never overwrites a user's files",
                            dir.display()
                        ))
                    }
                }
            }
        } else {
            std::fs::create_dir_all(dir).map_err(write_err(dir))?;
        }
        let stage = dir.join(STAGE);
        if stage.exists() {
            // Left by a run that was killed (SIGKILL, power loss): never a complete output.
            std::fs::remove_dir_all(&stage).map_err(write_err(&stage))?;
        }
        let made = OutDir {
            dir: dir.to_path_buf(),
            stage: stage.clone(),
            owner,
            force: force && !ours,
            created: !exists,
            committed: false,
        };
        // The writability check: a read-only folder fails here, before the run.
        std::fs::create_dir(&stage).map_err(write_err(&stage))?;
        let probe = stage.join(".probe");
        std::fs::write(&probe, b"").map_err(write_err(&probe))?;
        std::fs::remove_file(&probe).map_err(write_err(&probe))?;
        Ok(made)
    }

    /// The staging folder: every output is written here first.
    pub(crate) fn stage(&self) -> &Path {
        &self.stage
    }

    /// The files the marker lists (the earlier run's outputs), or with `--force` the names
    /// this command writes that are present.
    fn earlier_files(&self) -> Vec<String> {
        let marker = self.dir.join(self.owner.marker());
        let mut names: Vec<String> = std::fs::read_to_string(&marker)
            .map(|s| {
                s.lines()
                    .map(str::trim)
                    .filter(|l| !l.is_empty() && !l.starts_with('#'))
                    // Only plain names in this folder: a hand-edited marker cannot reach out.
                    .filter(|l| !l.contains('/') && !l.contains('\\') && *l != "..")
                    .map(str::to_string)
                    .collect()
            })
            .unwrap_or_default();
        if self.force {
            names.extend(
                RUN_OUTPUTS
                    .iter()
                    .filter(|n| self.dir.join(n).is_file())
                    .map(|n| n.to_string()),
            );
        }
        names.sort();
        names.dedup();
        names
    }

    fn write_marker(&self, names: &[String], complete: bool) -> Result<(), CliError> {
        let mut text = format!(
            "# Written by {}: this folder is its output. {}\n",
            self.owner.command(),
            if complete {
                "The files below are one complete output."
            } else {
                "INCOMPLETE: an output was being replaced when this was written."
            }
        );
        for n in names {
            text.push_str(n);
            text.push('\n');
        }
        let tmp = self.stage.join(self.owner.marker());
        std::fs::write(&tmp, text).map_err(write_err(&tmp))?;
        let dst = self.dir.join(self.owner.marker());
        std::fs::rename(&tmp, &dst).map_err(write_err(&dst))
    }

    /// Moves every file of the staging folder into the output folder (see the module docs
    /// for the order) and removes the earlier output's files; returns the final paths, in
    /// the order of `order` (names not staged are skipped, staged names not in `order`
    /// come before `metrics.json`, sorted).
    pub(crate) fn commit(mut self, order: &[&str]) -> Result<Vec<PathBuf>, CliError> {
        let mut staged: Vec<String> = std::fs::read_dir(&self.stage)
            .map_err(|source| CliError::Read {
                path: self.stage.clone(),
                source,
            })?
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().to_string())
            .collect();
        staged.sort();
        let mut names: Vec<String> = order
            .iter()
            .filter(|n| staged.iter().any(|s| s == *n))
            .map(|n| n.to_string())
            .collect();
        for s in &staged {
            if !names.contains(s) {
                names.push(s.clone());
            }
        }
        // metrics.json last: its presence says the output is complete.
        if let Some(i) = names.iter().position(|n| n == METRICS) {
            let m = names.remove(i);
            names.push(m);
        }
        let earlier = self.earlier_files();
        let old_metrics = self.dir.join(METRICS);
        if earlier.iter().any(|n| n == METRICS) && old_metrics.is_file() {
            std::fs::remove_file(&old_metrics).map_err(write_err(&old_metrics))?;
        }
        let mut all = earlier.clone();
        all.extend(names.iter().cloned());
        all.sort();
        all.dedup();
        self.write_marker(&all, false)?;
        for old in earlier.iter().filter(|o| !names.contains(o)) {
            let p = self.dir.join(old);
            if p.is_file() {
                std::fs::remove_file(&p).map_err(write_err(&p))?;
            }
        }
        let mut out = Vec::with_capacity(names.len());
        for n in &names {
            let dst = self.dir.join(n);
            std::fs::rename(self.stage.join(n), &dst).map_err(write_err(&dst))?;
            out.push(dst);
        }
        self.write_marker(&names, true)?;
        std::fs::remove_dir(&self.stage).map_err(write_err(&self.stage))?;
        self.committed = true;
        Ok(out)
    }
}

impl Drop for OutDir {
    /// Without a commit: the staging folder goes, and the output folder too when this run
    /// made it and nothing else is in it.
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.stage);
            if self.created {
                let _ = std::fs::remove_dir(&self.dir);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("slam-outdir-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn commit_replaces_the_earlier_output_and_nothing_else() {
        let d = scratch("commit");
        let o = OutDir::prepare(&d, Owner::Run, false, &[]).unwrap();
        for n in ["metrics.json", "map.png", "landmarks.csv"] {
            std::fs::write(o.stage().join(n), n).unwrap();
        }
        let files = o
            .commit(&["landmarks.csv", "metrics.json", "map.png"])
            .unwrap();
        let last = files.last().unwrap();
        assert!(last.ends_with("metrics.json"), "{files:?}");
        assert_eq!(
            names(&d),
            [".slam-run", "landmarks.csv", "map.png", "metrics.json"]
        );
        // The user adds a file; the next run in the folder (ours) keeps it and drops the
        // earlier run's landmarks.csv, which it does not write.
        std::fs::write(d.join("notes.txt"), "mine").unwrap();
        let o = OutDir::prepare(&d, Owner::Run, false, &[]).unwrap();
        std::fs::write(o.stage().join("map.pgm"), "new").unwrap();
        std::fs::write(o.stage().join("metrics.json"), "new").unwrap();
        o.commit(&[]).unwrap();
        assert_eq!(
            names(&d),
            [".slam-run", "map.pgm", "metrics.json", "notes.txt"]
        );
        assert_eq!(
            std::fs::read_to_string(d.join("metrics.json")).unwrap(),
            "new"
        );
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn an_uncommitted_output_leaves_nothing() {
        let d = scratch("drop");
        let o = OutDir::prepare(&d, Owner::Sim, false, &[]).unwrap();
        std::fs::write(o.stage().join("sensor_data.dat"), "x").unwrap();
        drop(o);
        assert!(!d.exists());
        // In an existing folder: the earlier output stays as it was.
        std::fs::create_dir_all(&d).unwrap();
        std::fs::write(d.join(".slam-sim"), "a.log\n").unwrap();
        std::fs::write(d.join("a.log"), "old").unwrap();
        let o = OutDir::prepare(&d, Owner::Sim, false, &[]).unwrap();
        std::fs::write(o.stage().join("b.log"), "x").unwrap();
        drop(o);
        assert_eq!(names(&d), [".slam-sim", "a.log"]);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn foreign_folders_and_inputs_inside_are_refused() {
        let d = scratch("foreign");
        std::fs::create_dir_all(&d).unwrap();
        std::fs::write(d.join("gt.tum"), "x").unwrap();
        let e = OutDir::prepare(&d, Owner::Sim, true, &[]).unwrap_err();
        assert!(e.to_string().contains("never overwrites a dataset"), "{e}");
        let e = OutDir::prepare(&d, Owner::Run, false, &[]).unwrap_err();
        assert!(e.to_string().contains("--force"), "{e}");
        let gt = d.join("gt.tum");
        let e = OutDir::prepare(&d, Owner::Run, true, &[("--ground-truth", &gt)]).unwrap_err();
        assert!(e.to_string().contains("lies inside --out"), "{e}");
        // --force: slam run's own names are replaced, the user's file stays.
        std::fs::write(d.join("map.png"), "old").unwrap();
        let o = OutDir::prepare(&d, Owner::Run, true, &[]).unwrap();
        std::fs::write(o.stage().join("metrics.json"), "new").unwrap();
        o.commit(&[]).unwrap();
        assert_eq!(names(&d), [".slam-run", "gt.tum", "metrics.json"]);
        std::fs::remove_dir_all(&d).unwrap();
    }
}
