//! `metrics.json`: the numbers every `slam run` writes, a contract other tools read.
//!
//! The keys are exactly the fields of [`Metrics`], in this order; a figure that cannot be
//! computed for a run (no ground truth, no clock, no landmarks, …) is `null`, never a
//! made-up number. Non-finite values are written as `null` too (JSON has no NaN).

use serde::{Deserialize, Serialize};
use std::path::Path;

/// The metrics of one `slam run`.
///
/// Units: metres, seconds, degrees, MiB. "As is" figures compare estimate and ground truth
/// in the frame they share at the start; "aligned" figures first apply the least-squares
/// SE(2) alignment (Umeyama without scale).
///
/// Which trajectory each figure is about: the `ate_*`, `rpe_*` and `relations_*` figures
/// are always those of the run's `trajectory.tum`, the filter's final answer: for FastSLAM
/// the full-SLAM estimate (the path of the particle with the highest weight at the end),
/// for the EKF the online estimates, for laser filters the filter's own trajectory. The
/// `online_*` figures are those of the online estimates (the pose the filter reported
/// after each step; `trajectory-online.tum` when it differs from `trajectory.tum`) of
/// landmark filters; for the EKF they equal the `ate_*`/`rpe_*` ones.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Metrics {
    /// Filter name, e.g. `"fastslam2"`.
    pub filter: String,
    /// Dataset name (a scenario name for simulated runs).
    pub dataset: String,
    /// Steps processed: landmark steps, or laser-log records.
    pub steps: usize,
    /// Wall-clock time of the filter loop, seconds (reading and writing files excluded).
    pub wall_s: f64,
    /// `steps / wall_s`.
    pub steps_per_s: Option<f64>,
    /// Time span covered by the data (last step time − first), seconds; null when the data
    /// has no clock (Freiburg course data).
    pub data_duration_s: Option<f64>,
    /// `data_duration_s / wall_s`: above 1 means faster than real time.
    pub real_time_factor: Option<f64>,
    /// Absolute trajectory error, RMSE of the position error as is, metres.
    pub ate_rmse_m: Option<f64>,
    /// Absolute trajectory error after SE(2) alignment, metres.
    pub ate_rmse_aligned_m: Option<f64>,
    /// Relative pose error between consecutive poses: mean translational error, metres.
    pub rpe_trans_mean_m: Option<f64>,
    /// Relative pose error between consecutive poses: mean rotational error, degrees.
    pub rpe_rot_mean_deg: Option<f64>,
    /// ATE as is of the online estimates, metres (landmark filters).
    pub online_ate_rmse_m: Option<f64>,
    /// ATE after SE(2) alignment of the online estimates, metres (landmark filters).
    pub online_ate_rmse_aligned_m: Option<f64>,
    /// RPE translational mean of the online estimates, metres (landmark filters).
    pub online_rpe_trans_mean_m: Option<f64>,
    /// RPE rotational mean of the online estimates, degrees (landmark filters).
    pub online_rpe_rot_mean_deg: Option<f64>,
    /// Landmark map error, RMSE as is, metres.
    pub landmark_rmse_m: Option<f64>,
    /// Landmark map error after SE(2) alignment, metres.
    pub landmark_rmse_aligned_m: Option<f64>,
    /// Kümmerle et al. relations metric: mean absolute translational error, metres.
    pub relations_trans_mean_m: Option<f64>,
    /// Kümmerle et al. relations metric: mean absolute rotational error, degrees.
    pub relations_rot_mean_deg: Option<f64>,
    /// Relations metric: relations with an end read at a time at which the trajectory holds
    /// several different poses (a repeating clock); the tie rule, not the data, picks which
    /// ([`crate::metrics::RelationsResult::ambiguous`]).
    pub relations_ambiguous: Option<usize>,
    /// Relations metric over the relations that are not ambiguous: mean absolute
    /// translational error, metres.
    pub relations_unambiguous_trans_mean_m: Option<f64>,
    /// Relations metric over the relations that are not ambiguous: mean absolute rotational
    /// error, degrees.
    pub relations_unambiguous_rot_mean_deg: Option<f64>,
    /// Fraction of steps whose pose NEES (3 dof, the filter's Gaussian summary of the
    /// pose against the true pose) lies inside the two-sided 95 % χ²(3) band
    /// [0.216, 9.348]: ≈ 0.95 for a consistent filter. The headline consistency figure;
    /// needs a ground-truth pose at every step. Per-step values are in `estimates.csv`.
    pub nees_pose_in_band_fraction: Option<f64>,
    /// Median pose NEES over all steps (consistent filter: ≈ 2.366, the χ²(3) median).
    pub nees_pose_median: Option<f64>,
    /// Mean pose NEES over the steps where it is finite (consistent filter: ≈ 3); a few
    /// steps where a particle cloud collapses can dominate it.
    pub nees_pose_mean: Option<f64>,
    /// Peak resident memory of the process (VmHWM) at the end of the filter run, before
    /// outputs are written (a `--map-resolution` re-rendering is not counted), MiB; null
    /// where /proc is unavailable.
    pub peak_rss_mb: Option<f64>,
    /// Laser filters: scan matches that failed and fell back to the motion model, summed
    /// over particles and processed scans (`ScanUpdateInfo::match_failures`); null for
    /// landmark filters.
    pub match_failed: Option<usize>,
    /// Laser filters: poor scan matches that a wider search recovered, summed over
    /// particles and processed scans (`ScanUpdateInfo::match_recoveries`); null for
    /// landmark filters.
    pub match_recovered: Option<usize>,
    /// Laser filters: the fraction of scans that contradict the run's own map, at the
    /// poses the run estimated for them (more than 25 % of a scan's beams pass through
    /// cells where at least 3 other scans ended beams: a wall the others saw;
    /// [`crate::metrics::map_contradictions`]); needs no ground truth. Null for landmark
    /// filters.
    pub map_contradicting_fraction: Option<f64>,
    /// Laser filters: whether `map_contradicting_fraction` exceeds 15 %: the map
    /// contradicts itself (bent, doubled walls). Null for landmark filters.
    pub map_inconsistent: Option<bool>,
}

impl Metrics {
    /// Metrics with only the identity fields set, everything else null.
    pub fn new(filter: &str, dataset: &str, steps: usize) -> Self {
        Self {
            filter: filter.to_string(),
            dataset: dataset.to_string(),
            steps,
            wall_s: 0.0,
            steps_per_s: None,
            data_duration_s: None,
            real_time_factor: None,
            ate_rmse_m: None,
            ate_rmse_aligned_m: None,
            rpe_trans_mean_m: None,
            rpe_rot_mean_deg: None,
            online_ate_rmse_m: None,
            online_ate_rmse_aligned_m: None,
            online_rpe_trans_mean_m: None,
            online_rpe_rot_mean_deg: None,
            landmark_rmse_m: None,
            landmark_rmse_aligned_m: None,
            relations_trans_mean_m: None,
            relations_rot_mean_deg: None,
            relations_ambiguous: None,
            relations_unambiguous_trans_mean_m: None,
            relations_unambiguous_rot_mean_deg: None,
            nees_pose_in_band_fraction: None,
            nees_pose_median: None,
            nees_pose_mean: None,
            peak_rss_mb: None,
            match_failed: None,
            match_recovered: None,
            map_contradicting_fraction: None,
            map_inconsistent: None,
        }
    }

    /// Sets `wall_s`, `data_duration_s` and the two rates derived from them.
    pub fn set_timing(&mut self, wall_s: f64, data_duration_s: Option<f64>) {
        self.wall_s = wall_s;
        self.steps_per_s = finite((wall_s > 0.0).then(|| self.steps as f64 / wall_s));
        self.data_duration_s = finite(data_duration_s);
        self.real_time_factor = finite(
            self.data_duration_s
                .and_then(|d| (wall_s > 0.0).then(|| d / wall_s)),
        );
    }

    /// Replaces every non-finite figure by `None` (JSON null).
    pub fn sanitise(&mut self) {
        for v in [
            &mut self.steps_per_s,
            &mut self.data_duration_s,
            &mut self.real_time_factor,
            &mut self.ate_rmse_m,
            &mut self.ate_rmse_aligned_m,
            &mut self.rpe_trans_mean_m,
            &mut self.rpe_rot_mean_deg,
            &mut self.online_ate_rmse_m,
            &mut self.online_ate_rmse_aligned_m,
            &mut self.online_rpe_trans_mean_m,
            &mut self.online_rpe_rot_mean_deg,
            &mut self.landmark_rmse_m,
            &mut self.landmark_rmse_aligned_m,
            &mut self.relations_trans_mean_m,
            &mut self.relations_rot_mean_deg,
            &mut self.relations_unambiguous_trans_mean_m,
            &mut self.relations_unambiguous_rot_mean_deg,
            &mut self.nees_pose_in_band_fraction,
            &mut self.nees_pose_median,
            &mut self.nees_pose_mean,
            &mut self.peak_rss_mb,
            &mut self.map_contradicting_fraction,
        ] {
            *v = finite(*v);
        }
        if !self.wall_s.is_finite() {
            self.wall_s = 0.0;
        }
    }

    /// Pretty JSON text.
    pub fn to_json(&self) -> String {
        let mut m = self.clone();
        m.sanitise();
        // Serialising a struct of strings, integers and options cannot fail.
        serde_json::to_string_pretty(&m).unwrap_or_default()
    }

    /// The figures for a person: one line of speed and memory, then one indented line each
    /// for ATE/RPE, the online estimates (when they differ), the landmark map and pose NEES,
    /// where computed (what `slam run` prints).
    pub fn summary(&self) -> Vec<String> {
        let mut lines = Vec::new();
        let rtf = self
            .real_time_factor
            .map(|r| format!(", {r:.1}x real time"))
            .unwrap_or_default();
        lines.push(format!(
            "{} on {}: {} steps in {} s ({:.0} steps/s{rtf}), peak memory {}",
            self.filter,
            self.dataset,
            self.steps,
            if self.wall_s < 1.0 {
                format!("{:.3}", self.wall_s)
            } else {
                format!("{:.1}", self.wall_s)
            },
            self.steps_per_s.unwrap_or(0.0),
            fmt_opt(self.peak_rss_mb, " MB"),
        ));
        if self.ate_rmse_m.is_some() {
            lines.push(format!(
                "  ATE {} (aligned {}), RPE {} / {}",
                fmt_opt(self.ate_rmse_m, " m"),
                fmt_opt(self.ate_rmse_aligned_m, " m"),
                fmt_opt(self.rpe_trans_mean_m, " m"),
                fmt_opt(self.rpe_rot_mean_deg, " deg"),
            ));
        }
        if self.online_ate_rmse_m.is_some() && self.online_ate_rmse_m != self.ate_rmse_m {
            lines.push(format!(
                "  online estimates: ATE {} (aligned {}), RPE {} / {}",
                fmt_opt(self.online_ate_rmse_m, " m"),
                fmt_opt(self.online_ate_rmse_aligned_m, " m"),
                fmt_opt(self.online_rpe_trans_mean_m, " m"),
                fmt_opt(self.online_rpe_rot_mean_deg, " deg"),
            ));
        }
        if self.landmark_rmse_m.is_some() {
            lines.push(format!(
                "  landmarks RMSE {} (aligned {})",
                fmt_opt(self.landmark_rmse_m, " m"),
                fmt_opt(self.landmark_rmse_aligned_m, " m"),
            ));
        }
        if let (Some(f), Some(bad)) = (self.map_contradicting_fraction, self.map_inconsistent) {
            lines.push(format!(
                "  map check: {:.1} % of the scans look through walls other scans saw ({})",
                100.0 * f,
                if bad {
                    "the map contradicts itself: bent or doubled"
                } else {
                    "consistent: at most 15 %"
                }
            ));
        }
        if let Some(f) = self.nees_pose_in_band_fraction {
            lines.push(format!(
            "  pose NEES: {:.1} % of steps in the 95 % χ²(3) band, median {}, mean {} (consistent: 95 %, 2.366, 3)",
            100.0 * f,
            fmt_opt(self.nees_pose_median, ""),
            fmt_opt(self.nees_pose_mean, ""),
        ));
        }
        lines
    }

    /// Writes the metrics as pretty JSON to `path`.
    pub fn write(&self, path: &Path) -> std::io::Result<()> {
        std::fs::write(path, self.to_json() + "\n")
    }
}

/// `Some(v)` only when `v` is finite (JSON has no NaN or ∞: such a figure is written as null).
pub fn finite(v: Option<f64>) -> Option<f64> {
    v.filter(|x| x.is_finite())
}

/// Peak resident set size of this process in MiB, from `VmHWM` in `/proc/self/status`
/// (kB there); `None` where that file does not exist (not Linux).
pub fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    parse_vm_hwm(&status)
}

fn parse_vm_hwm(status: &str) -> Option<f64> {
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// `x` with 3 decimals, or in scientific notation when huge (a diverged NEES).
fn fmt_num(x: f64) -> String {
    if x.abs() >= 1e5 {
        format!("{x:.3e}")
    } else {
        format!("{x:.3}")
    }
}

fn fmt_opt(v: Option<f64>, unit: &str) -> String {
    match v {
        Some(x) => format!("{}{unit}", fmt_num(x)),
        None => "n/a".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_are_exactly_the_contract_and_null_when_missing() {
        let mut m = Metrics::new("ekf", "loop", 10);
        m.set_timing(2.0, Some(f64::NAN));
        let v: serde_json::Value = serde_json::from_str(&m.to_json()).unwrap();
        let keys: Vec<&str> = v.as_object().unwrap().keys().map(|k| k.as_str()).collect();
        let expected = [
            "filter",
            "dataset",
            "steps",
            "wall_s",
            "steps_per_s",
            "data_duration_s",
            "real_time_factor",
            "ate_rmse_m",
            "ate_rmse_aligned_m",
            "rpe_trans_mean_m",
            "rpe_rot_mean_deg",
            "online_ate_rmse_m",
            "online_ate_rmse_aligned_m",
            "online_rpe_trans_mean_m",
            "online_rpe_rot_mean_deg",
            "landmark_rmse_m",
            "landmark_rmse_aligned_m",
            "relations_trans_mean_m",
            "relations_rot_mean_deg",
            "relations_ambiguous",
            "relations_unambiguous_trans_mean_m",
            "relations_unambiguous_rot_mean_deg",
            "nees_pose_in_band_fraction",
            "nees_pose_median",
            "nees_pose_mean",
            "peak_rss_mb",
            "match_failed",
            "match_recovered",
            "map_contradicting_fraction",
            "map_inconsistent",
        ];
        let mut sorted_keys = keys.clone();
        sorted_keys.sort_unstable();
        let mut sorted_expected = expected.to_vec();
        sorted_expected.sort_unstable();
        assert_eq!(sorted_keys, sorted_expected);
        assert_eq!(v["steps_per_s"], serde_json::json!(5.0));
        assert!(v["data_duration_s"].is_null());
        assert!(v["real_time_factor"].is_null());
        assert!(v["ate_rmse_m"].is_null());
    }

    #[test]
    fn real_time_factor_is_data_over_wall() {
        let mut m = Metrics::new("ekf", "x", 100);
        m.set_timing(4.0, Some(10.0));
        assert_eq!(m.real_time_factor, Some(2.5));
        assert_eq!(m.steps_per_s, Some(25.0));
        m.set_timing(0.0, Some(10.0));
        assert_eq!(m.real_time_factor, None);
    }

    #[test]
    fn vm_hwm_is_parsed_in_mib() {
        let status = "Name:\tslam\nVmPeak:\t  9000 kB\nVmHWM:\t    2048 kB\nVmRSS:\t 1000 kB\n";
        assert_eq!(parse_vm_hwm(status), Some(2.0));
        assert_eq!(parse_vm_hwm("Name: x\n"), None);
    }
}
