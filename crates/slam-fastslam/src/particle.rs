//! One FastSLAM particle and everything that happens to it in one step: motion sampling,
//! data association, the FastSLAM 1.0 update, the FastSLAM 2.0 proposal, landmark updates
//! and negative evidence. Nothing here looks at another particle, which is what lets the
//! filter run the particles in parallel and still be deterministic.

use crate::config::{Association, FastSlamConfig};
use crate::landmark::{symmetrize, Landmark};
use crate::map::LandmarkMap;
use rand::Rng;
use rand_pcg::Pcg64Mcg;
use slam_models::gaussian::{log_likelihood, mahalanobis_squared};
use slam_models::particle::PathNode;
use slam_models::Vector3;
use slam_models::{normalize_angle, Control, LandmarkId, Matrix3, Pose2, RangeBearing, Vector2};
use std::sync::Arc;

/// A particle: a pose sample x_t⁽ᵏ⁾ with the path x_{0:t}⁽ᵏ⁾ that led to it, its log
/// importance weight and its landmark map (PR eq. 13.12: Y_t⁽ᵏ⁾ = ⟨x_t⁽ᵏ⁾, μ₁⁽ᵏ⁾, Σ₁⁽ᵏ⁾, …,
/// μ_N⁽ᵏ⁾, Σ_N⁽ᵏ⁾⟩; FastSLAM's particles are samples of the whole path, §13.3).
#[derive(Debug, Clone)]
pub struct Particle {
    /// The current pose sample.
    pub pose: Pose2,
    /// The latest node of this particle's path in the tree shared by all particles
    /// ([`PathNode`]): clones share it, so resampling copies a pointer, not the path.
    pub(crate) path: Arc<PathNode>,
    /// ln w, normalised over the particle set after every update (Σ exp = 1).
    pub log_weight: f64,
    /// This particle's landmarks; clones share every node (O(1) copy).
    pub map: LandmarkMap,
    /// Provisional landmarks (started by maximum-likelihood association, not yet
    /// confirmed): (key, index of the update that created it).
    pub(crate) provisional: Vec<(u32, u64)>,
}

/// What one update did to one particle.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct ParticleStats {
    pub associated: usize,
    pub new_landmarks: usize,
    pub rejected: usize,
    pub removed: usize,
    pub nis: f64,
}

/// The random stream of particle `index` at filter tick `tick`: a pure function of
/// (seed, tick, index), so the draws do not depend on which thread runs the particle
/// ([`slam_models::rng::particle_stream_wide`]).
pub(crate) fn stream(seed: u64, tick: u64, index: u64) -> Pcg64Mcg {
    slam_models::rng::particle_stream_wide(seed, tick, index)
}

/// Draws x ~ N(μ, Σ) for a 3×3 covariance that may be singular (a stationary robot has
/// zero motion noise), through its symmetric eigen-decomposition with negative rounding
/// residue clamped to zero.
pub(crate) fn sample_gaussian3<R: Rng + ?Sized>(
    mean: &Vector3,
    cov: &Matrix3,
    rng: &mut R,
) -> Vector3 {
    let eig = nalgebra::SymmetricEigen::new(symmetrize(cov));
    let mut e = Vector3::zeros();
    for i in 0..3 {
        let z: f64 = rng.sample(rand_distr::StandardNormal);
        e[i] = z * eig.eigenvalues[i].max(0.0).sqrt();
    }
    mean + eig.eigenvectors * e
}

/// A validated observation: z as a vector plus the original (for its id).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Obs {
    pub z: Vector2,
    pub raw: RangeBearing,
}

/// Where an observation goes in one particle's map.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Target {
    /// An existing landmark under this key.
    Existing(u32),
    /// A new landmark under this key (known id) or under a fresh key (`None`).
    New(Option<u32>),
    /// Nowhere (no id under known association, degenerate geometry).
    Reject,
}

/// Per-step context shared by every particle.
pub(crate) struct StepContext<'a> {
    pub config: &'a FastSlamConfig,
    pub ln_p0: f64,
    /// How many updates the filter ran before this one.
    pub update_index: u64,
}

impl Particle {
    /// This particle's path x_{0:t}: the initial pose, then its pose after each update, in
    /// order. O(t), iterative.
    pub fn path(&self) -> Vec<Pose2> {
        self.path.path()
    }

    /// The node of this particle's latest path pose (shared with the particles that
    /// descend from the same ancestor).
    pub fn path_node(&self) -> &Arc<PathNode> {
        &self.path
    }

    /// Appends the current pose to the path as the pose of update `step`: one allocation,
    /// the ancestry is shared.
    pub(crate) fn extend_path(&mut self, step: usize) {
        self.path = PathNode::child(Some(Arc::clone(&self.path)), self.pose, step);
    }

    /// x_t ~ p(x_t | u_t, x_{t−1}) (PR table 13.1 line 4).
    pub(crate) fn sample_motion<R: Rng + ?Sized>(
        &mut self,
        cfg: &FastSlamConfig,
        u: &Control,
        rng: &mut R,
    ) {
        self.pose = cfg.motion.sample(&self.pose, u, rng);
    }

    /// The key an observation with a known id maps to, if the association mode uses ids.
    fn known_key(cfg: &FastSlamConfig, z: &RangeBearing) -> Option<Option<u32>> {
        match (cfg.association, z.id) {
            (Association::MaximumLikelihood, _) => None,
            (Association::Known, id) => Some(id.map(|i| i.0)),
            (Association::Auto, Some(id)) => Some(Some(id.0)),
            (Association::Auto, None) => None,
        }
    }

    /// Chooses a target for `obs` seen from `pose`. With `pose_cov` the likelihood used for
    /// maximum likelihood is the marginal one with the pose uncertainty included
    /// (L = H_x Σ_x H_xᵀ + H_m Σ H_mᵀ + Q, FastSLAM 2.0); without it, S = H_m Σ H_mᵀ + Q.
    fn associate(
        &self,
        ctx: &StepContext<'_>,
        pose: &Pose2,
        pose_cov: Option<&Matrix3>,
        obs: &Obs,
        used: &[u32],
    ) -> Target {
        let cfg = ctx.config;
        if let Some(k) = Self::known_key(cfg, &obs.raw) {
            return match k {
                None => Target::Reject,
                Some(k) if self.map.get(k).is_some() => Target::Existing(k),
                Some(k) => Target::New(Some(k)),
            };
        }
        // Maximum likelihood over the landmarks near the inverse-mapped observation
        // (PR table 13.3 lines 8–13), each landmark used at most once per scan.
        let guess = cfg.sensor.inverse(pose, &obs.raw).landmark;
        let mut best: Option<(f64, u32)> = None;
        self.map
            .for_each_near(&guess, cfg.association_radius, |k, lm| {
                if used.contains(&k) {
                    return;
                }
                let Some(inn) = lm.innovation(&cfg.sensor, pose, &obs.z) else {
                    return;
                };
                let l = match pose_cov {
                    Some(p) => inn.s + inn.h_x * p * inn.h_x.transpose(),
                    None => inn.s,
                };
                if let Ok(ll) = log_likelihood(&inn.nu, &symmetrize(&l)) {
                    if best.is_none_or(|(b, _)| ll > b) {
                        best = Some((ll, k));
                    }
                }
            });
        match best {
            Some((ll, k)) if ll >= ctx.ln_p0 => Target::Existing(k),
            _ => Target::New(None),
        }
    }

    /// Inserts a landmark initialised from `obs` at the particle's pose.
    fn add_landmark(&mut self, ctx: &StepContext<'_>, key: Option<u32>, obs: &Obs) -> u32 {
        let cfg = ctx.config;
        let provisional = key.is_none() && cfg.provisional_steps > 0;
        let key = key.unwrap_or_else(|| self.map.fresh_key());
        if provisional {
            self.provisional.push((key, ctx.update_index));
        }
        let lm = Landmark::from_observation(
            &cfg.sensor,
            &self.pose,
            &obs.raw,
            LandmarkId(key),
            cfg.existence_initial,
        );
        self.map.insert(key, lm);
        key
    }

    /// EKF-updates landmark `key` with `obs` from the particle's pose; returns
    /// (ln N(ν; 0, S), νᵀS⁻¹ν) or `None` when the geometry is degenerate.
    fn update_landmark(&mut self, cfg: &FastSlamConfig, key: u32, obs: &Obs) -> Option<(f64, f64)> {
        let pose = self.pose;
        let sensor = cfg.sensor;
        let max = cfg.existence_max;
        self.map
            .update(key, |lm| {
                let inn = lm.innovation(&sensor, &pose, &obs.z)?;
                let ll = log_likelihood(&inn.nu, &inn.s).ok()?;
                let d2 = mahalanobis_squared(&inn.nu, &inn.s).ok()?;
                if !lm.ekf_update(&sensor, &inn) {
                    return None;
                }
                lm.existence = (lm.existence + 1).min(max);
                lm.observations = lm.observations.saturating_add(1);
                Some((ll, d2))
            })
            .flatten()
    }

    /// FastSLAM 1.0 measurement update at the already sampled pose (PR table 13.1 lines
    /// 5–21, with the maximum-likelihood association of table 13.3): each observation is
    /// associated, then updates its landmark's EKF and multiplies the weight by
    /// N(ν; 0, S), or starts a new landmark and multiplies it by p0.
    pub(crate) fn update_fastslam1(&mut self, ctx: &StepContext<'_>, obs: &[Obs]) -> ParticleStats {
        let cfg = ctx.config;
        let mut st = ParticleStats::default();
        let mut used: Vec<u32> = Vec::with_capacity(obs.len());
        let pose = self.pose;
        for o in obs {
            match self.associate(ctx, &pose, None, o, &used) {
                Target::Existing(k) => match self.update_landmark(cfg, k, o) {
                    Some((ll, d2)) => {
                        self.log_weight += ll;
                        st.associated += 1;
                        st.nis += d2;
                        used.push(k);
                    }
                    None => st.rejected += 1,
                },
                Target::New(k) => {
                    let k = self.add_landmark(ctx, k, o);
                    self.log_weight += ctx.ln_p0;
                    st.new_landmarks += 1;
                    used.push(k);
                }
                Target::Reject => st.rejected += 1,
            }
        }
        st.removed = self.negative_evidence(cfg, &used) + self.expire_provisional(ctx);
        st
    }

    /// FastSLAM 2.0 (Montemerlo et al. 2003 §3; PR table 13.3): the pose is drawn from the
    /// proposal p(x_t | x_{t−1}, u_t, z_t) linearised around the predicted pose, then the
    /// landmarks are updated at the drawn pose.
    ///
    /// The proposal is built observation by observation (the paper's sequential form for
    /// several measurements): starting from μ = g(u, x_{t−1}), Σ_x = R, each associated
    /// observation contributes
    ///
    /// ```text
    /// L = H_x Σ_x H_xᵀ + H_m Σ_n H_mᵀ + Q        (marginal innovation covariance)
    /// K = Σ_x H_xᵀ L⁻¹,   μ ← μ + K ν,   Σ_x ← (I − K H_x) Σ_x
    /// ln w += ln N(ν; 0, L)                      (PR table 13.3 line 20, the matching weight)
    /// ```
    ///
    /// which equals the information form Σ_x = (R⁻¹ + Σ H_xᵀ S⁻¹ H_x)⁻¹ but never inverts R
    /// (zero for a stationary robot). A new landmark contributes p0. With no associated
    /// observation the proposal is the motion model.
    pub(crate) fn update_fastslam2<R: Rng + ?Sized>(
        &mut self,
        ctx: &StepContext<'_>,
        control: Option<&Control>,
        obs: &[Obs],
        rng: &mut R,
    ) -> ParticleStats {
        let cfg = ctx.config;
        let sensor = &cfg.sensor;
        let (mut mu, mut sigma) = match control {
            Some(u) => (
                cfg.motion.predict(&self.pose, u).to_vector(),
                symmetrize(&cfg.motion.noise_covariance(&self.pose, u)),
            ),
            None => (self.pose.to_vector(), Matrix3::zeros()),
        };
        let mut st = ParticleStats::default();
        let mut used: Vec<u32> = Vec::with_capacity(obs.len());
        let mut targets: Vec<Target> = Vec::with_capacity(obs.len());
        for o in obs {
            let pose = Pose2::from_vector(&mu);
            let t = self.associate(ctx, &pose, Some(&sigma), o, &used);
            let t = match t {
                Target::Existing(k) => {
                    let lm = self.map.get(k);
                    match lm.and_then(|lm| lm.innovation(sensor, &pose, &o.z)) {
                        Some(inn) => {
                            let l = symmetrize(&(inn.s + inn.h_x * sigma * inn.h_x.transpose()));
                            match (log_likelihood(&inn.nu, &l), l.try_inverse()) {
                                (Ok(ll), Some(l_inv)) => {
                                    let k_gain = sigma * inn.h_x.transpose() * l_inv;
                                    mu += k_gain * inn.nu;
                                    mu[2] = normalize_angle(mu[2]);
                                    let a = Matrix3::identity() - k_gain * inn.h_x;
                                    sigma = symmetrize(
                                        &(a * sigma * a.transpose()
                                            + k_gain * inn.s * k_gain.transpose()),
                                    );
                                    self.log_weight += ll;
                                    used.push(k);
                                    Target::Existing(k)
                                }
                                _ => Target::Reject,
                            }
                        }
                        None => Target::Reject,
                    }
                }
                Target::New(k) => {
                    self.log_weight += ctx.ln_p0;
                    Target::New(k)
                }
                Target::Reject => Target::Reject,
            };
            targets.push(t);
        }
        // x_t ~ N(μ, Σ_x) (PR table 13.3 line 16).
        let x = sample_gaussian3(&mu, &sigma, rng);
        self.pose = Pose2::from_vector(&x);
        // Landmark updates at the drawn pose (PR table 13.3 lines 17–19, 21–25).
        let mut seen: Vec<u32> = Vec::with_capacity(obs.len());
        for (o, t) in obs.iter().zip(targets) {
            match t {
                Target::Existing(k) => match self.update_landmark(cfg, k, o) {
                    Some((_, d2)) => {
                        st.associated += 1;
                        st.nis += d2;
                        seen.push(k);
                    }
                    None => st.rejected += 1,
                },
                Target::New(Some(k)) if self.map.get(k).is_some() => {
                    // The same known id twice in one scan: the first created it.
                    if self.update_landmark(cfg, k, o).is_some() {
                        st.associated += 1;
                    }
                    seen.push(k);
                }
                Target::New(k) => {
                    let k = self.add_landmark(ctx, k, o);
                    st.new_landmarks += 1;
                    seen.push(k);
                }
                Target::Reject => st.rejected += 1,
            }
        }
        st.removed = self.negative_evidence(cfg, &seen) + self.expire_provisional(ctx);
        st
    }

    /// Drops confirmed landmarks from the provisional list and removes the provisional
    /// landmarks older than `provisional_steps` updates. Returns the number removed.
    fn expire_provisional(&mut self, ctx: &StepContext<'_>) -> usize {
        if self.provisional.is_empty() {
            return 0;
        }
        let cfg = ctx.config;
        let mut removed = 0;
        let map = &mut self.map;
        self.provisional.retain(|&(k, born)| {
            let Some(lm) = map.get(k) else {
                return false; // already removed by negative evidence
            };
            if lm.observations >= cfg.confirm_observations {
                return false;
            }
            if ctx.update_index.saturating_sub(born) >= cfg.provisional_steps as u64 {
                map.remove(k);
                removed += 1;
                return false;
            }
            true
        });
        removed
    }

    /// Negative evidence (Montemerlo et al. 2002 §4): every landmark predicted inside the
    /// (margin-shrunk) sensor range and field of view that was not among `seen` loses one
    /// unit of existence, and is removed when it falls below the threshold. Returns the
    /// number removed. A no-op when the configuration has no sensor range.
    fn negative_evidence(&mut self, cfg: &FastSlamConfig, seen: &[u32]) -> usize {
        let Some(max_range) = cfg.max_range else {
            return 0;
        };
        let keep = 1.0 - cfg.visibility_margin;
        let r_vis = keep * max_range;
        let half_fov = cfg.fov.map(|f| keep * f / 2.0);
        let pose = self.pose;
        let mut missed: Vec<u32> = Vec::new();
        self.map.for_each_near(&pose.translation(), r_vis, |k, lm| {
            if seen.contains(&k) {
                return;
            }
            let d = lm.mean - pose.translation();
            if d.norm() < cfg.sensor.min_range {
                return;
            }
            if let Some(h) = half_fov {
                if normalize_angle(d.y.atan2(d.x) - pose.theta).abs() > h {
                    return;
                }
            }
            missed.push(k);
        });
        let mut removed = 0;
        for k in missed {
            let gone = self
                .map
                .update(k, |lm| {
                    lm.existence -= 1;
                    lm.existence < cfg.existence_threshold
                })
                .unwrap_or(false);
            if gone {
                self.map.remove(k);
                removed += 1;
            }
        }
        removed
    }
}

/// The landmark estimates of one particle's map, as the trait reports them.
pub(crate) fn estimates(map: &LandmarkMap) -> Vec<slam_models::LandmarkEstimate> {
    map.iter()
        .map(|(_, lm)| slam_models::LandmarkEstimate {
            id: lm.id,
            mean: lm.mean,
            covariance: lm.cov,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let a: u64 = stream(7, 3, 11).random();
        let b: u64 = stream(7, 3, 11).random();
        assert_eq!(a, b);
        let others: Vec<u64> = [(8, 3, 11), (7, 4, 11), (7, 3, 12)]
            .iter()
            .map(|&(s, t, i)| stream(s, t, i).random())
            .collect();
        assert!(others.iter().all(|&o| o != a));
    }

    /// The FastSLAM 2.0 proposal against its information form (Montemerlo et al. 2003,
    /// eqs. 11–12; PR table 13.3 lines 13–15): Σ = (Hₓᵀ S⁻¹ Hₓ + R⁻¹)⁻¹,
    /// μ = Σ Hₓᵀ S⁻¹ (z − ẑ) + x̂, with S = H_m Σ_n H_mᵀ + Q. The sample mean and covariance
    /// of many draws must match; the importance weight must equal ln N(z − ẑ; 0, L) with
    /// L = Hₓ R Hₓᵀ + S (eq. 17), computed here independently.
    #[test]
    fn fastslam2_proposal_matches_the_information_form() {
        use crate::config::Variant;
        use slam_models::{Matrix2, OdometryControl, Point2};
        let cfg = FastSlamConfig {
            variant: Variant::FastSlam2,
            sensor: slam_models::measurement::RangeBearingModel::new(0.05, 0.01),
            motion: slam_models::motion::MotionModels {
                odometry: slam_models::motion::OdometryModel::new([0.05, 0.01, 0.05, 0.01]),
                ..Default::default()
            },
            ..Default::default()
        };
        let ctx = StepContext {
            config: &cfg,
            ln_p0: cfg.p0.ln(),
            update_index: 0,
        };
        let mut map = LandmarkMap::new(5.0);
        let lm = Landmark {
            id: LandmarkId(3),
            mean: Point2::new(4.0, 2.0),
            cov: Matrix2::new(0.02, 0.005, 0.005, 0.03),
            existence: 1,
            observations: 5,
            cell: 0,
        };
        map.insert(3, lm);
        let start = Particle {
            pose: Pose2::new(0.1, -0.2, 0.3),
            path: PathNode::child(None, Pose2::new(0.1, -0.2, 0.3), 0),
            log_weight: 0.0,
            map,
            provisional: vec![],
        };
        let u = Control::Odometry(OdometryControl {
            rot1: 0.1,
            trans: 1.0,
            rot2: -0.05,
        });
        let z = RangeBearing {
            range: 3.2,
            bearing: 0.05,
            id: Some(LandmarkId(3)),
        };
        let obs = [Obs {
            z: z.to_vector(),
            raw: z,
        }];
        // Independent computation of the proposal.
        let x_hat = cfg.motion.predict(&start.pose, &u);
        let r = cfg.motion.noise_covariance(&start.pose, &u);
        let pred = cfg.sensor.predict(&x_hat, &lm.mean).unwrap();
        let q = cfg.sensor.noise_covariance();
        let s = pred.h_landmark * lm.cov * pred.h_landmark.transpose() + q;
        let nu = slam_models::measurement::RangeBearingModel::innovation(&z.to_vector(), &pred.z);
        let hx = pred.h_pose;
        let sigma = (hx.transpose() * s.try_inverse().unwrap() * hx + r.try_inverse().unwrap())
            .try_inverse()
            .unwrap();
        let mu = sigma * hx.transpose() * s.try_inverse().unwrap() * nu + x_hat.to_vector();
        let l = hx * r * hx.transpose() + s;
        let w = log_likelihood(&nu, &l).unwrap();
        let n = 40_000;
        let mut xs = Vec::with_capacity(n);
        for k in 0..n {
            let mut p = start.clone();
            let mut rng = stream(1, 0, k as u64);
            p.update_fastslam2(&ctx, Some(&u), &obs, &mut rng);
            assert!(
                (p.log_weight - w).abs() < 1e-9,
                "weight {} vs {w}",
                p.log_weight
            );
            xs.push(p.pose.to_vector());
        }
        let m = xs.iter().fold(Vector3::zeros(), |a, x| a + x) / n as f64;
        let mut c = Matrix3::zeros();
        for x in &xs {
            c += (x - m) * (x - m).transpose();
        }
        c /= (n - 1) as f64;
        for i in 0..3 {
            let se = (sigma[(i, i)] / n as f64).sqrt();
            assert!((m[i] - mu[i]).abs() < 5.0 * se, "mean {m} vs {mu}");
        }
        assert!(
            (c - sigma).abs().max() < 0.05 * sigma.abs().max(),
            "cov {c} vs {sigma}"
        );
        // The proposal is much tighter than the motion model.
        assert!(sigma.determinant() < 0.1 * r.determinant());
    }

    fn one_landmark_particle(at: slam_models::Point2) -> Particle {
        let mut map = LandmarkMap::new(5.0);
        map.insert(
            0,
            Landmark {
                id: LandmarkId(0),
                mean: at,
                cov: slam_models::Matrix2::identity() * 0.04,
                existence: 1,
                observations: 1,
                cell: 0,
            },
        );
        Particle {
            pose: Pose2::IDENTITY,
            path: PathNode::child(None, Pose2::IDENTITY, 0),
            log_weight: 0.0,
            map,
            provisional: vec![],
        }
    }

    /// FastSLAM 1.0: the weight is ln N(ν; 0, H Σ Hᵀ + Q) at the particle's pose (PR table
    /// 13.1 line 17) for a known landmark, and ln p0 for a new one.
    #[test]
    fn fastslam1_weight_is_the_innovation_likelihood() {
        use slam_models::Point2;
        let cfg = FastSlamConfig::default();
        let ctx = StepContext {
            config: &cfg,
            ln_p0: cfg.p0.ln(),
            update_index: 0,
        };
        let mut p = one_landmark_particle(Point2::new(3.0, 1.0));
        let z0 = RangeBearing {
            range: 3.3,
            bearing: 0.28,
            id: Some(LandmarkId(0)),
        };
        let z1 = RangeBearing {
            range: 2.0,
            bearing: -1.0,
            id: Some(LandmarkId(9)),
        };
        let pred = cfg
            .sensor
            .predict(&Pose2::IDENTITY, &Point2::new(3.0, 1.0))
            .unwrap();
        let s =
            pred.h_landmark * 0.04 * pred.h_landmark.transpose() + cfg.sensor.noise_covariance();
        let nu = slam_models::measurement::RangeBearingModel::innovation(&z0.to_vector(), &pred.z);
        let expect = log_likelihood(&nu, &s).unwrap() + cfg.p0.ln();
        let obs: Vec<Obs> = [z0, z1]
            .iter()
            .map(|z| Obs {
                z: z.to_vector(),
                raw: *z,
            })
            .collect();
        let st = p.update_fastslam1(&ctx, &obs);
        assert!((p.log_weight - expect).abs() < 1e-12);
        assert_eq!((st.associated, st.new_landmarks), (1, 1));
        assert_eq!(p.map.len(), 2);
    }

    /// Negative evidence: a landmark inside the shrunk footprint that is not seen loses
    /// one existence per update and goes once below the threshold; one behind the robot
    /// (outside the field of view) is untouched.
    #[test]
    fn unseen_landmarks_in_view_are_removed() {
        use slam_models::Point2;
        let cfg = FastSlamConfig {
            max_range: Some(6.0),
            fov: Some(std::f64::consts::PI),
            ..Default::default()
        };
        let ctx = StepContext {
            config: &cfg,
            ln_p0: cfg.p0.ln(),
            update_index: 0,
        };
        let mut ahead = one_landmark_particle(Point2::new(3.0, 0.5));
        let mut behind = one_landmark_particle(Point2::new(-3.0, 0.5));
        let mut far = one_landmark_particle(Point2::new(5.9, 0.0)); // beyond 0.9·6 m
        for (p, survives) in [(&mut ahead, false), (&mut behind, true), (&mut far, true)] {
            // existence 1 → 0 (kept, threshold 0) → −1 (removed).
            let st = p.update_fastslam1(&ctx, &[]);
            assert_eq!((st.removed, p.map.len()), (0, 1));
            let st = p.update_fastslam1(&ctx, &[]);
            assert_eq!(p.map.len() == 1, survives);
            assert_eq!(st.removed, usize::from(!survives));
        }
    }

    #[test]
    fn gaussian_sampler_matches_covariance_even_when_singular() {
        let mut rng = stream(1, 2, 3);
        // Rank 2: no noise on the third axis.
        let c = Matrix3::new(0.04, 0.01, 0.0, 0.01, 0.09, 0.0, 0.0, 0.0, 0.0);
        let mu = Vector3::new(1.0, -1.0, 0.5);
        let n = 50_000;
        let xs: Vec<Vector3> = (0..n)
            .map(|_| sample_gaussian3(&mu, &c, &mut rng))
            .collect();
        let m = xs.iter().fold(Vector3::zeros(), |a, x| a + x) / n as f64;
        let mut s = Matrix3::zeros();
        for x in &xs {
            s += (x - m) * (x - m).transpose();
        }
        s /= (n - 1) as f64;
        assert!((m - mu).norm() < 0.005);
        assert!((s - c).abs().max() < 0.003, "{s}");
        assert!(xs.iter().all(|x| (x[2] - 0.5).abs() < 1e-9));
    }
}
