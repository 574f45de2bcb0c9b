//! Laser odometry over a whole recording, and the rotation prior from a yaw-rate stream.

use super::hypotheses::Branches;
use super::{LaserOdometry, LaserOdometryConfig};
use crate::error::GridError;
use slam_models::{normalize_angle, LaserScan, Pose2, ScanRecord, YawRate};

/// Longest gap between yaw-rate samples (and between an interval's ends and the samples
/// nearest them) that [`integrate_yaw_rate`] bridges, seconds.
pub const MAX_RATE_GAP: f64 = 0.5;

/// The heading change ∫ω dt over [`t0`, `t1`] (radians) from yaw-rate samples sorted by
/// time, ω linear between samples (the trapezoidal rule) and held constant beyond the
/// first and last; `None` when `t1 ≤ t0`, a rate is not finite, or the samples leave a
/// gap longer than [`MAX_RATE_GAP`] in the interval (no prior then).
pub fn integrate_yaw_rate(rates: &[YawRate], t0: f64, t1: f64) -> Option<f64> {
    if t1.partial_cmp(&t0) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    // The samples in [t0 − gap, t1 + gap], and the rate at any time by interpolation.
    let lo = rates.partition_point(|r| r.t < t0 - MAX_RATE_GAP);
    let hi = rates.partition_point(|r| r.t <= t1 + MAX_RATE_GAP);
    let s = &rates[lo..hi];
    if s.is_empty() || s.iter().any(|r| !r.rate.is_finite() || !r.t.is_finite()) {
        return None;
    }
    let at = |t: f64| -> f64 {
        let k = s.partition_point(|r| r.t <= t);
        match k {
            0 => s[0].rate,
            k if k == s.len() => s[k - 1].rate,
            k => {
                let (a, b) = (s[k - 1], s[k]);
                if b.t > a.t {
                    a.rate + (b.rate - a.rate) * (t - a.t) / (b.t - a.t)
                } else {
                    b.rate
                }
            }
        }
    };
    // Knots: t0, every sample inside, t1; the rate is linear between knots.
    let mut knots = vec![t0];
    knots.extend(s.iter().map(|r| r.t).filter(|&t| t > t0 && t < t1));
    knots.push(t1);
    let covered = s[0].t <= t0 + MAX_RATE_GAP && s[s.len() - 1].t >= t1 - MAX_RATE_GAP;
    if !covered || knots.windows(2).any(|w| w[1] - w[0] > MAX_RATE_GAP) {
        return None;
    }
    Some(
        knots
            .windows(2)
            .map(|w| 0.5 * (at(w[0]) + at(w[1])) * (w[1] - w[0]))
            .sum(),
    )
}

/// Laser odometry over a stream of scans, as [`laser_odometry`] makes it for a whole
/// recording: with [`LaserOdometryConfig::branch_lag`] above 0 an ambiguous step is
/// followed as branches and decided that many scans later, so a scan's pose comes out
/// when it is decided, up to `branch-lag` scans after the scan went in, always in scan
/// order; with 0 every scan's pose comes out at once and is
/// [`LaserOdometry::process`]'s. Fed the same scans (and rotation priors), it gives the
/// poses [`laser_odometry`] gives at the scan records, to the bit: a live node that steps
/// its filter with each pose as it comes out makes the estimates `slam run` makes.
#[derive(Debug, Clone)]
pub struct LaserOdometryStream {
    branches: Branches,
}

impl LaserOdometryStream {
    /// A stream with `config` (rejected when invalid, by key).
    pub fn new(config: LaserOdometryConfig) -> Result<Self, GridError> {
        let (lag, max) = (config.branch_lag, config.max_branches);
        Ok(Self {
            branches: Branches::new(LaserOdometry::new(config)?, lag, max),
        })
    }

    /// Matches the next scan (`turn`: the rotation prior since the previous scan, radians,
    /// as in [`LaserOdometry::process`]) and returns the poses decided by it, in scan
    /// order: none while a split is open, then every scan's since the split. Poses are in
    /// the frame of the first scan.
    pub fn push(&mut self, scan: &LaserScan, turn: Option<f64>) -> Result<Vec<Pose2>, GridError> {
        self.branches.push(scan, turn)?;
        Ok(self.branches.take_decided())
    }

    /// Decides an open split now (the branch that fits best so far, as at the end of a
    /// recording) and returns the poses it decided: after this every scan pushed has had
    /// its pose. Pushing more scans afterwards continues the stream.
    pub fn finish(&mut self) -> Vec<Pose2> {
        self.branches.close();
        self.branches.take_decided()
    }

    /// Scans pushed whose pose has not come out yet (at most `branch-lag`).
    pub fn pending(&self) -> usize {
        self.branches.pending()
    }

    /// Ambiguous steps that started a branch so far.
    pub fn splits(&self) -> usize {
        self.branches.splits_and_switches().0
    }

    /// Decisions that kept a branch other than the one [`LaserOdometry::process`] would
    /// have followed.
    pub fn switches(&self) -> usize {
        self.branches.splits_and_switches().1
    }
}

/// The laser odometry of a whole recording ([`laser_odometry`]).
#[derive(Debug, Clone, PartialEq)]
pub struct LaserOdometryRun {
    /// One pose per record, in the frame of the first scan: at a scan record its matched
    /// pose; between two scan records the linear interpolation in time of theirs (x, y and
    /// the wrapped heading difference, the time fraction clamped to [0, 1]); before the
    /// first scan the identity, after the last scan its pose.
    pub odometry: Vec<Pose2>,
    /// Scans matched.
    pub scans: usize,
    /// Scans no hypothesis matched (the prediction kept).
    pub failures: usize,
    /// Submaps started (the local maps matched against).
    pub submaps: usize,
    /// Scans whose prediction had a rotation prior.
    pub with_prior: usize,
    /// Scans that needed the wide search (the narrow search's fit was poor).
    pub wide_searches: usize,
    /// Branches started at ambiguous steps (multi-hypothesis laser odometry,
    /// [`LaserOdometryConfig::branch_lag`]; 0 with it off).
    pub splits: usize,
    /// Decisions that kept a branch other than the one [`LaserOdometry::process`] would
    /// have followed.
    pub switches: usize,
}

/// Runs [`LaserOdometry`] over `records` in file order (their own odometry is ignored),
/// with the rotation prior from `rates` (sorted by time here) when given; with
/// `branch-lag` above 0 ambiguous steps are followed as branches and decided that many
/// scans later (the module documentation, step 4), otherwise each scan's pose is
/// [`LaserOdometry::process`]'s.
pub fn laser_odometry(
    records: &[ScanRecord],
    rates: Option<&[YawRate]>,
    config: LaserOdometryConfig,
) -> Result<LaserOdometryRun, GridError> {
    let mut rates: Vec<YawRate> = rates.map(<[YawRate]>::to_vec).unwrap_or_default();
    rates.sort_by(|a, b| a.t.total_cmp(&b.t));
    let mut stream = LaserOdometryStream::new(config)?;
    let mut at_scans: Vec<usize> = Vec::new();
    let mut poses: Vec<Pose2> = Vec::new();
    let mut with_prior = 0;
    let mut last_t: Option<f64> = None;
    for (k, r) in records.iter().enumerate() {
        let Some(scan) = &r.scan else { continue };
        let turn = last_t.and_then(|t0| integrate_yaw_rate(&rates, t0, r.t));
        with_prior += usize::from(turn.is_some());
        poses.extend(stream.push(scan, turn)?);
        at_scans.push(k);
        last_t = Some(r.t);
    }
    poses.extend(stream.finish());
    let (splits, switches) = stream.branches.splits_and_switches();
    let lo = stream.branches.odometry();
    let at_scans: Vec<(usize, Pose2)> = at_scans.into_iter().zip(poses).collect();
    let mut odometry = Vec::with_capacity(records.len());
    let mut next = 0;
    for (k, r) in records.iter().enumerate() {
        while next < at_scans.len() && at_scans[next].0 < k {
            next += 1;
        }
        let pose = match (next.checked_sub(1).map(|i| at_scans[i]), at_scans.get(next)) {
            (_, Some(&(j, p))) if j == k => p,
            (Some((i, a)), Some(&(j, b))) => {
                let (ta, tb) = (records[i].t, records[j].t);
                let s = if tb > ta {
                    ((r.t - ta) / (tb - ta)).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                Pose2::new(
                    a.x + s * (b.x - a.x),
                    a.y + s * (b.y - a.y),
                    normalize_angle(a.theta + s * normalize_angle(b.theta - a.theta)),
                )
            }
            (Some((_, a)), None) => a,
            (None, _) => Pose2::IDENTITY,
        };
        odometry.push(pose);
    }
    Ok(LaserOdometryRun {
        odometry,
        scans: at_scans.len(),
        failures: lo.failures(),
        submaps: lo.submaps(),
        with_prior,
        wide_searches: lo.wide_searches(),
        splits,
        switches,
    })
}
