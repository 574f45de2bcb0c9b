//! The particle filter: Monte Carlo localization (PR table 8.2) with KLD-sampling
//! (table 8.4) and augmented MCL's random particles (table 8.3).

use crate::config::MclConfig;
use crate::error::MclError;
use crate::kld::{bin_of, kld_bound, theta_bins};
use crate::map::MclMap;
use crate::sensor::{log_likelihood, ScanBeams};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use serde::{Deserialize, Serialize};
use slam_models::motion::MotionModel;
use slam_models::particle::{effective_sample_size_log, normalize_log_weights, Resampler};
use slam_models::{sampling, Matrix3, Pose2, ScanRecord, TimedPose, WeightedPose};
use std::collections::{HashMap, HashSet};
use std::sync::Arc;

/// What the robot is believed to be at the start.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InitialBelief {
    /// Unknown: `max_particles` particles spread uniformly over the free space (global
    /// localization).
    Global,
    /// A Gaussian about `mean` (world frame) with standard deviations `sigma` = (σx, σy, σθ)
    /// (metres, metres, radians), independent.
    Gaussian {
        /// The mean pose.
        mean: Pose2,
        /// (σx, σy, σθ).
        sigma: [f64; 3],
    },
}

/// What one record did: non-fatal diagnostics, one per record (the metrics' rows).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StepInfo {
    /// The record's time, seconds.
    pub t: f64,
    /// True when the filter moved and weighed the particles at this record (a scan and
    /// enough motion since the last update, or the first scan).
    pub updated: bool,
    /// True when the particles were resampled.
    pub resampled: bool,
    /// Particles after this record.
    pub particles: usize,
    /// Effective sample size after the weighting, 1/Σw² (before any resampling).
    pub n_eff: f64,
    /// The weighted cloud's spread √(σx² + σy²), metres, after the weighting.
    pub spread: f64,
    /// Random particles drawn from the free space at this resampling (augmented MCL).
    pub injected: usize,
    /// Short- and long-term averages of the per-beam measurement likelihood (0 at a record
    /// without an update).
    pub w_fast: f64,
    /// See `w_fast`.
    pub w_slow: f64,
    /// The exponent the scan's likelihood was raised to (`weight_exponent`, or lower
    /// when adaptive tempering kept N_eff up; 0 without an update).
    pub exponent: f64,
    /// Modes after the weighting: clusters of particles (connected KLD bins) holding at
    /// least `kld.mode_min_mass` of the weight. More than one: the filter is unsure
    /// between places (0 without an update).
    pub modes: usize,
    /// True while a global start has not yet converged (`MclConfig::converge_min_travel`):
    /// the updates' evidence is then scaled by the translation since the previous update
    /// (`MclConfig::evidence_distance`).
    pub converging: bool,
    /// The estimate after this record.
    pub pose: Pose2,
}

/// Monte Carlo localization on a known map.
///
/// Feed every record of a log in order to [`Mcl::process`]; the estimate for each is the
/// mean of the heaviest cluster of particles (particles in touching KLD bins), carried
/// forward with the odometry between updates.
///
/// ```
/// use slam_mcl::{InitialBelief, Mcl, MclConfig, MclMap};
/// use slam_models::{GridMap, Point2, Pose2};
/// // A 4 m × 4 m free room with walls around it.
/// let mut m = GridMap::unknown(0.1, Point2::new(0.0, 0.0), 40, 40);
/// for iy in 0..40 { for ix in 0..40 {
///     let wall = ix == 0 || iy == 0 || ix == 39 || iy == 39;
///     m.cells[iy * 40 + ix] = if wall { 100 } else { 0 };
/// } }
/// let config = MclConfig::default();
/// let map = MclMap::new(m, &config)?;
/// let start = InitialBelief::Gaussian { mean: Pose2::new(2.0, 2.0, 0.0), sigma: [0.1, 0.1, 0.05] };
/// let mcl = Mcl::new(config, map, start, 7)?;
/// assert_eq!(mcl.particle_count(), config.kld.max_particles);
/// # Ok::<(), slam_mcl::MclError>(())
/// ```
#[derive(Debug, Clone)]
pub struct Mcl {
    config: MclConfig,
    map: Arc<MclMap>,
    poses: Vec<Pose2>,
    log_w: Vec<f64>,
    rng: Pcg64Mcg,
    /// Odometry at the last update (`None` before the first record).
    odom_at_update: Option<Pose2>,
    /// Estimate at the last update.
    estimate: Pose2,
    estimate_cov: Matrix3,
    w_slow: f64,
    w_fast: f64,
    trajectory: Vec<TimedPose>,
    updates: usize,
    /// True from a global start until it converged.
    converging: bool,
    /// Odometry translation (m) summed over the updates since the start.
    travelled: f64,
    /// Weight of the heaviest cluster at the last estimate.
    best_mass: f64,
}

impl Mcl {
    /// A filter on `map` with the initial belief `init`, its random draws from `seed`
    /// (same seed and records, same output bytes).
    ///
    /// Errors: an invalid configuration, a non-finite or negative initial pose or σ.
    pub fn new(
        config: MclConfig,
        map: impl Into<Arc<MclMap>>,
        init: InitialBelief,
        seed: u64,
    ) -> Result<Self, MclError> {
        config.validate()?;
        let map = map.into();
        let mut rng = Pcg64Mcg::seed_from_u64(seed);
        let n = config.kld.max_particles;
        let (poses, estimate) = match init {
            InitialBelief::Global => {
                let poses: Vec<Pose2> = (0..n).map(|_| map.sample_free(&mut rng)).collect();
                (poses, Pose2::IDENTITY)
            }
            InitialBelief::Gaussian { mean, sigma } => {
                if !mean.is_finite() || sigma.iter().any(|s| !(s.is_finite() && *s >= 0.0)) {
                    return Err(MclError::NonFinite {
                        what: "initial pose or its standard deviations",
                    });
                }
                let poses = (0..n)
                    .map(|_| {
                        Pose2::new(
                            mean.x + sigma[0] * sampling::standard_normal(&mut rng),
                            mean.y + sigma[1] * sampling::standard_normal(&mut rng),
                            mean.theta + sigma[2] * sampling::standard_normal(&mut rng),
                        )
                    })
                    .collect();
                (poses, mean)
            }
        };
        let converging = matches!(init, InitialBelief::Global);
        let log_w = vec![-(n as f64).ln(); n];
        let mut f = Self {
            config,
            map,
            poses,
            log_w,
            rng,
            odom_at_update: None,
            estimate,
            estimate_cov: Matrix3::zeros(),
            w_slow: 0.0,
            w_fast: 0.0,
            trajectory: Vec::new(),
            updates: 0,
            converging,
            travelled: 0.0,
            best_mass: 0.0,
        };
        let _ = f.refresh_estimate();
        Ok(f)
    }

    /// The configuration.
    pub fn config(&self) -> &MclConfig {
        &self.config
    }

    /// The map.
    pub fn map(&self) -> &MclMap {
        &self.map
    }

    /// Number of particles now.
    pub fn particle_count(&self) -> usize {
        self.poses.len()
    }

    /// Measurement updates made so far.
    pub fn updates(&self) -> usize {
        self.updates
    }

    /// The estimate after the last record: the last update's estimate composed with the
    /// odometry since.
    pub fn pose(&self) -> Pose2 {
        self.trajectory.last().map_or(self.estimate, |p| p.pose)
    }

    /// Covariance (m², rad²) of the heaviest cluster about its mean, at the last update.
    pub fn pose_covariance(&self) -> Matrix3 {
        self.estimate_cov
    }

    /// The particles with their normalised weights.
    pub fn particles(&self) -> Vec<WeightedPose> {
        self.poses
            .iter()
            .zip(&self.log_w)
            .map(|(p, l)| WeightedPose {
                pose: *p,
                weight: l.exp(),
            })
            .collect()
    }

    /// One pose per record processed, in the map frame.
    pub fn trajectory(&self) -> &[TimedPose] {
        &self.trajectory
    }

    /// Processes one record (every record of a log, in order): when it carries a scan and
    /// the odometry moved at least `update_min_d` or turned `update_min_a` since the last
    /// update (or it is the first scan), the particles are moved by the odometry motion
    /// model (PR table 5.6), weighed by the measurement model, and resampled when N_eff
    /// falls below `resample_ratio`·N or recovery asks for random particles.
    ///
    /// Errors: a non-finite odometry pose; weights that all vanished (cannot happen with
    /// z_rand > 0).
    pub fn process(&mut self, record: &ScanRecord) -> Result<StepInfo, MclError> {
        if !record.odometry.is_finite() || !record.t.is_finite() {
            return Err(MclError::NonFinite {
                what: "record odometry or time",
            });
        }
        let odom = record.odometry;
        let first = self.odom_at_update.is_none();
        let last = *self.odom_at_update.get_or_insert(odom);
        let delta = last.between(&odom);
        let moved = delta.x.hypot(delta.y) >= self.config.update_min_d
            || delta.theta.abs() >= self.config.update_min_a;
        let mut info = StepInfo {
            t: record.t,
            updated: false,
            resampled: false,
            particles: self.poses.len(),
            n_eff: effective_sample_size_log(&self.log_w),
            spread: self.spread(),
            injected: 0,
            w_fast: 0.0,
            w_slow: 0.0,
            exponent: 0.0,
            modes: 0,
            converging: self.converging,
            pose: Pose2::IDENTITY,
        };
        if let Some(scan) = record
            .scan
            .as_ref()
            .filter(|_| moved || (first && self.updates == 0))
        {
            let beams = ScanBeams::new(scan, &self.config.sensor);
            if !beams.is_empty() {
                self.motion_update(&last, &odom);
                self.odom_at_update = Some(odom);
                let d = delta.x.hypot(delta.y);
                self.travelled += d;
                self.measurement_update(&beams, d, &mut info)?;
            }
        }
        let since = self
            .odom_at_update
            .map_or(Pose2::IDENTITY, |o| o.between(&odom));
        let pose = self.estimate.compose(&since);
        info.pose = pose;
        info.particles = self.poses.len();
        self.trajectory.push(TimedPose { t: record.t, pose });
        Ok(info)
    }

    /// Samples x' ~ p(x' | u, x) for every particle, u the odometry from `from` to `to`.
    fn motion_update(&mut self, from: &Pose2, to: &Pose2) {
        let model = self.config.motion;
        let u = model.control_from_poses(from, to);
        for p in &mut self.poses {
            *p = model.sample(p, &u, &mut self.rng);
        }
    }

    /// Weighs the particles by the scan, updates w_slow/w_fast, resamples when due. `d` is
    /// the odometry translation (m) since the previous update.
    fn measurement_update(
        &mut self,
        beams: &ScanBeams,
        d: f64,
        info: &mut StepInfo,
    ) -> Result<(), MclError> {
        let mut k_max = self.config.sensor.weight_exponent;
        // Evidence from one place counted once while a global start converges: the
        // scan's exponent is scaled by the new ground covered since the previous update.
        let d_ref = self.config.evidence_distance;
        if self.converging && self.updates > 0 && d_ref > 0.0 {
            k_max *= (d / d_ref).min(1.0);
        }
        // The map prior p(x | m): a particle outside the free space is down-weighted.
        let ln_not_free = self.config.not_free_weight.ln();
        let free_max = self.config.free_max;
        // w_avg (PR table 8.3 line 8) over the prior weights, each likelihood taken as the
        // geometric mean per beam exp(ℓ / n) so that its scale does not depend on the beam
        // count (a product of 60 densities is far outside what α-averages can hold).
        let mut w_avg = 0.0;
        let mut lls = Vec::with_capacity(self.poses.len());
        for (p, lw) in self.poses.iter().zip(self.log_w.iter_mut()) {
            let (ll, used) = log_likelihood(&self.map, &self.config.sensor, beams, p);
            if !self.map.is_free(p.x, p.y, free_max) {
                *lw += ln_not_free;
            }
            if used > 0 {
                w_avg += (*lw + ll / used as f64).exp();
            }
            lls.push(ll);
        }
        let k = self.tempered_exponent(&lls, k_max);
        for (lw, ll) in self.log_w.iter_mut().zip(&lls) {
            *lw += k * ll;
        }
        info.exponent = k;
        normalize_log_weights(&mut self.log_w)?;
        self.updates += 1;
        let r = self.config.recovery;
        if self.w_slow == 0.0 && self.w_fast == 0.0 {
            // First update: start both averages at the first value (nav2 starts them at
            // 0, which makes the first updates look like a sudden improvement). After a
            // global start this value is low, so w_slow stays below w_fast, and recovery
            // does not fire, for about 1/α_slow updates. Reading both averages
            // bias-corrected from 0 instead (tried) let it fire, but on Acapulco the random
            // particles then kept w_fast low and the injection fed itself for 200 m.
            self.w_slow = w_avg;
            self.w_fast = w_avg;
        } else {
            self.w_slow += r.alpha_slow * (w_avg - self.w_slow);
            self.w_fast += r.alpha_fast * (w_avg - self.w_fast);
        }
        let (w_slow, w_fast) = (self.w_slow, self.w_fast);
        let p_inject = if r.alpha_slow > 0.0 && w_slow > 0.0 {
            (1.0 - w_fast / w_slow).max(0.0)
        } else {
            0.0
        };
        info.updated = true;
        info.n_eff = effective_sample_size_log(&self.log_w);
        info.spread = self.spread();
        info.w_fast = w_fast;
        info.w_slow = w_slow;
        info.modes = self.refresh_estimate();
        if self.converging
            && self.travelled >= self.config.converge_min_travel
            && self.best_mass >= self.config.converge_mode_mass
        {
            self.converging = false;
        }
        info.converging = self.converging;
        let n = self.poses.len() as f64;
        if info.n_eff < self.config.resample_ratio * n || p_inject > 0.0 {
            info.injected = self.resample(p_inject)?;
            info.resampled = true;
        }
        Ok(())
    }

    /// The exponent of this update's likelihood: `k_max` unless that leaves
    /// N_eff < `min_n_eff_ratio`·N, else the largest k in (0, k_max] that keeps N_eff at
    /// that floor (bisection to 1e-4 relative; N_eff falls as k grows from 0, where it is
    /// the prior's).
    fn tempered_exponent(&self, lls: &[f64], k_max: f64) -> f64 {
        let s = &self.config.sensor;
        let ratio = if self.converging {
            s.min_n_eff_ratio.max(s.global_min_n_eff_ratio)
        } else {
            s.min_n_eff_ratio
        };
        let floor = ratio * lls.len() as f64;
        let n_eff = |k: f64| -> f64 {
            let top = self
                .log_w
                .iter()
                .zip(lls)
                .map(|(w, l)| w + k * l)
                .fold(f64::NEG_INFINITY, f64::max);
            let (mut s1, mut s2) = (0.0, 0.0);
            for (w, l) in self.log_w.iter().zip(lls) {
                let e = (w + k * l - top).exp();
                s1 += e;
                s2 += e * e;
            }
            if s2 > 0.0 {
                s1 * s1 / s2
            } else {
                0.0
            }
        };
        if floor <= 0.0 || n_eff(k_max) >= floor || n_eff(0.0) < floor {
            return k_max;
        }
        let (mut lo, mut hi) = (0.0, k_max);
        while hi - lo > 1e-4 * k_max {
            let mid = 0.5 * (lo + hi);
            if n_eff(mid) >= floor {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo.max(1e-6 * k_max)
    }

    /// Low-variance (systematic) resampling of `max_particles` ancestors, visited in a
    /// seeded random order; each draw is replaced by a random free-space pose with
    /// probability `p_inject`; drawing stops once the count reaches KLD's bound for the
    /// bins occupied so far (and `min_particles`). Returns the number of random particles.
    fn resample(&mut self, p_inject: f64) -> Result<usize, MclError> {
        let kld = self.config.kld;
        let w: Vec<f64> = self.log_w.iter().map(|l| l.exp()).collect();
        // The cloud's weighted deviation per axis, for roughening.
        let (mut mx, mut my, mut ms, mut mc) = (0.0, 0.0, 0.0, 0.0);
        for (p, wi) in self.poses.iter().zip(&w) {
            mx += wi * p.x;
            my += wi * p.y;
            ms += wi * p.theta.sin();
            mc += wi * p.theta.cos();
        }
        let (mut vx, mut vy) = (0.0, 0.0);
        for (p, wi) in self.poses.iter().zip(&w) {
            vx += wi * (p.x - mx).powi(2);
            vy += wi * (p.y - my).powi(2);
        }
        let r_len = ms.hypot(mc).clamp(1e-12, 1.0);
        let spread = [vx.sqrt(), vy.sqrt(), (-2.0 * r_len.ln()).sqrt()];
        let mut ancestors = Vec::with_capacity(kld.max_particles);
        Resampler::Systematic.resample_into(
            &w,
            kld.max_particles,
            &mut self.rng,
            &mut ancestors,
        )?;
        // Fisher–Yates: any prefix is then an unbiased subsample of the systematic draw.
        for i in (1..ancestors.len()).rev() {
            let j = self.rng.random_range(0..=i);
            ancestors.swap(i, j);
        }
        let (cluster, mass) = self.clusters();
        let mut bins = HashSet::new();
        let mut out = Vec::with_capacity(kld.max_particles);
        // The cluster of each new particle's ancestor (usize::MAX: a random particle).
        let mut out_cluster = Vec::with_capacity(kld.max_particles);
        let mut injected = 0;
        let mut needed = kld.min_particles as f64;
        for a in ancestors {
            let pose = if p_inject > 0.0 && self.rng.random::<f64>() < p_inject {
                injected += 1;
                out_cluster.push(usize::MAX);
                self.map.sample_free(&mut self.rng)
            } else {
                out_cluster.push(cluster[a]);
                self.poses[a]
            };
            if bins.insert(bin_of(&pose, &kld)) {
                needed = kld_bound(bins.len(), kld.epsilon, kld.z_quantile)
                    .max(kld.min_particles as f64);
            }
            out.push(pose);
            if out.len() as f64 >= needed {
                break;
            }
        }
        let n_base = out.len();
        // Modes (Milstein et al. 2002, clustered particle filtering): every cluster of at
        // least `mode_min_mass` (the `max_modes` heaviest) keeps `mode_particles`
        // particles, drawn from its own in proportion to their weights, so that a
        // second place that explains the scans as well (a symmetric building) is not lost
        // to resampling noise before the data can tell the two apart.
        let mut modes: Vec<usize> = (0..mass.len())
            .filter(|&c| mass[c] >= kld.mode_min_mass)
            .collect();
        modes.sort_by(|a, b| mass[*b].total_cmp(&mass[*a]).then(a.cmp(b)));
        modes.truncate(kld.max_modes);
        let mut count = vec![0usize; mass.len()];
        for &c in out_cluster.iter().filter(|&&c| c != usize::MAX) {
            count[c] += 1;
        }
        for &c in &modes {
            // Never past `max_particles`: the top-up takes what the KLD draw left.
            let room = kld.max_particles.saturating_sub(out.len());
            let missing = kld.mode_particles.saturating_sub(count[c]).min(room);
            if missing == 0 {
                continue;
            }
            let members: Vec<usize> = (0..self.poses.len()).filter(|&i| cluster[i] == c).collect();
            let mw: Vec<f64> = members.iter().map(|&i| w[i]).collect();
            let mut picks = Vec::with_capacity(missing);
            Resampler::Systematic.resample_into(&mw, missing, &mut self.rng, &mut picks)?;
            for j in picks {
                out.push(self.poses[members[j]]);
                out_cluster.push(c);
            }
            count[c] += missing;
        }
        // Weights: each cluster keeps its mass (renormalised over the clusters still
        // present) shared evenly by its particles; random particles weigh 1/n_base each.
        let f_inj = injected as f64 / n_base.max(1) as f64;
        let present: f64 = (0..mass.len())
            .filter(|&c| count[c] > 0)
            .map(|c| mass[c])
            .sum();
        let log_w: Vec<f64> = out_cluster
            .iter()
            .map(|&c| {
                if c == usize::MAX || present <= 0.0 {
                    -(n_base as f64).ln()
                } else {
                    ((1.0 - f_inj) * mass[c] / present / count[c] as f64).ln()
                }
            })
            .collect();
        let n = out.len();
        let k = self.config.roughening * (n as f64).powf(-1.0 / 3.0);
        if k > 0.0 {
            for p in &mut out {
                p.x += k * spread[0] * sampling::standard_normal(&mut self.rng);
                p.y += k * spread[1] * sampling::standard_normal(&mut self.rng);
                p.theta = slam_models::normalize_angle(
                    p.theta + k * spread[2] * sampling::standard_normal(&mut self.rng),
                );
            }
        }
        self.poses = out;
        self.log_w = log_w;
        normalize_log_weights(&mut self.log_w)?;
        Ok(injected)
    }

    /// √(σx² + σy²) of the weighted cloud.
    fn spread(&self) -> f64 {
        let (mut mx, mut my) = (0.0, 0.0);
        for (p, l) in self.poses.iter().zip(&self.log_w) {
            let w = l.exp();
            mx += w * p.x;
            my += w * p.y;
        }
        let mut v = 0.0;
        for (p, l) in self.poses.iter().zip(&self.log_w) {
            v += l.exp() * ((p.x - mx).powi(2) + (p.y - my).powi(2));
        }
        v.max(0.0).sqrt()
    }

    /// The particles' clusters: connected sets of occupied KLD bins (26-neighbourhood,
    /// headings wrapping), numbered in order of first appearance (deterministic). Returns
    /// each particle's cluster and each cluster's weight mass.
    fn clusters(&self) -> (Vec<usize>, Vec<f64>) {
        let kld = self.config.kld;
        let nt = theta_bins(&kld);
        let mut bin_ids: HashMap<(i32, i32, i32), usize> = HashMap::new();
        let mut of = Vec::with_capacity(self.poses.len());
        let mut keys = Vec::new();
        for p in &self.poses {
            let b = bin_of(p, &kld);
            let next = bin_ids.len();
            let id = *bin_ids.entry(b).or_insert_with(|| {
                keys.push(b);
                next
            });
            of.push(id);
        }
        let mut cluster = vec![usize::MAX; keys.len()];
        let mut n_clusters = 0;
        let mut stack = Vec::new();
        for start in 0..keys.len() {
            if cluster[start] != usize::MAX {
                continue;
            }
            cluster[start] = n_clusters;
            stack.push(start);
            while let Some(b) = stack.pop() {
                let (x, y, t) = keys[b];
                for dx in -1..=1 {
                    for dy in -1..=1 {
                        for dt in -1..=1 {
                            let key = (x + dx, y + dy, (t + dt).rem_euclid(nt));
                            if let Some(&nb) = bin_ids.get(&key) {
                                if cluster[nb] == usize::MAX {
                                    cluster[nb] = n_clusters;
                                    stack.push(nb);
                                }
                            }
                        }
                    }
                }
            }
            n_clusters += 1;
        }
        let mut mass = vec![0.0; n_clusters];
        let per_particle: Vec<usize> = of.iter().map(|&b| cluster[b]).collect();
        for (c, l) in per_particle.iter().zip(&self.log_w) {
            mass[*c] += l.exp();
        }
        (per_particle, mass)
    }

    /// The estimate: the weighted mean (circular in θ) of the heaviest cluster of
    /// particles, a cluster being a connected set of occupied KLD bins (26-neighbourhood,
    /// headings wrapping), as nav2 AMCL reports its pose.
    /// Returns the number of clusters of at least `kld.mode_min_mass` (the modes).
    fn refresh_estimate(&mut self) -> usize {
        let (cluster, mass) = self.clusters();
        let n_clusters = mass.len();
        let modes = mass
            .iter()
            .filter(|m| **m >= self.config.kld.mode_min_mass)
            .count();
        let best = (0..n_clusters)
            .max_by(|a, b| mass[*a].total_cmp(&mass[*b]).then(b.cmp(a)))
            .unwrap_or(0);
        let (mut sw, mut mx, mut my, mut ms, mut mc) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (i, p) in self.poses.iter().enumerate() {
            if cluster[i] != best {
                continue;
            }
            let w = self.log_w[i].exp();
            sw += w;
            mx += w * p.x;
            my += w * p.y;
            ms += w * p.theta.sin();
            mc += w * p.theta.cos();
        }
        self.best_mass = sw;
        if sw <= 0.0 {
            return modes;
        }
        let mean = Pose2::new(mx / sw, my / sw, ms.atan2(mc));
        let mut cov = Matrix3::zeros();
        for (i, p) in self.poses.iter().enumerate() {
            if cluster[i] != best {
                continue;
            }
            let w = self.log_w[i].exp() / sw;
            let e = slam_models::Vector3::new(
                p.x - mean.x,
                p.y - mean.y,
                slam_models::normalize_angle(p.theta - mean.theta),
            );
            cov += w * e * e.transpose();
        }
        self.estimate = mean;
        self.estimate_cov = cov;
        modes
    }
}
