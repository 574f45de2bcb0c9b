//! Reference paths and the waypoint follower that drives the simulated robot.
//!
//! A [`Path`] is a polyline (open or closed) parametrised by arc length s. The
//! [`Follower`] is a pure-pursuit controller (Coulter 1992) chasing a "carrot" that moves
//! along the path at the nominal speed: each step it commands a velocity control (v, ω) that
//! steers the *true* robot towards the point `lookahead` metres ahead of the carrot. The true
//! robot then moves with noise, and the controller corrects it on the next step, so the true
//! trajectory stays close to the path however long the run.

use crate::error::{check_range, SimError};
use serde::{Deserialize, Serialize};
use slam_models::detmath;
use slam_models::{normalize_angle, Point2, Pose2, VelocityControl};

/// A polyline in the world frame (metres), parametrised by arc length.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Path {
    points: Vec<Point2>,
    /// Cumulative arc length at each point (`cum[0] = 0`); for a closed path one more entry,
    /// the length back to the first point.
    cum: Vec<f64>,
    closed: bool,
}

impl Path {
    /// A path through `points`; when `closed`, it returns from the last point to the first.
    /// Consecutive duplicates are dropped. Needs at least two distinct finite points.
    pub fn new(points: Vec<Point2>, closed: bool) -> Result<Self, SimError> {
        let mut pts: Vec<Point2> = Vec::with_capacity(points.len());
        for p in points {
            if !(p.x.is_finite() && p.y.is_finite()) {
                return Err(SimError::InvalidPath(format!(
                    "path point ({}, {}) is not finite",
                    p.x, p.y
                )));
            }
            if pts.last().is_none_or(|q| (q - p).norm() > 1e-9) {
                pts.push(p);
            }
        }
        if closed && pts.len() > 2 && (pts[0] - pts[pts.len() - 1]).norm() <= 1e-9 {
            pts.pop();
        }
        if pts.len() < 2 {
            return Err(SimError::InvalidPath(
                "a path needs at least two distinct points".into(),
            ));
        }
        let mut cum = vec![0.0];
        let n = pts.len();
        let segs = if closed { n } else { n - 1 };
        for i in 0..segs {
            let d = (pts[(i + 1) % n] - pts[i]).norm();
            cum.push(cum[i] + d);
        }
        Ok(Self {
            points: pts,
            cum,
            closed,
        })
    }

    /// The vertices.
    pub fn points(&self) -> &[Point2] {
        &self.points
    }

    /// True for a closed loop.
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// Total length, metres (including the closing segment of a closed path).
    pub fn length(&self) -> f64 {
        self.cum[self.cum.len() - 1]
    }

    /// Segment index and fraction for arc length `s` (wrapped for closed paths, clamped to
    /// the ends for open ones).
    fn locate(&self, s: f64) -> (usize, f64) {
        let len = self.length();
        let s = if self.closed {
            s.rem_euclid(len)
        } else {
            s.clamp(0.0, len)
        };
        // partition_point: first index with cum > s.
        let i = self
            .cum
            .partition_point(|&c| c <= s)
            .clamp(1, self.cum.len() - 1)
            - 1;
        let seg = self.cum[i + 1] - self.cum[i];
        let f = if seg > 0.0 {
            (s - self.cum[i]) / seg
        } else {
            0.0
        };
        (i, f.clamp(0.0, 1.0))
    }

    /// The point at arc length `s`.
    pub fn point_at(&self, s: f64) -> Point2 {
        let (i, f) = self.locate(s);
        let a = self.points[i];
        let b = self.points[(i + 1) % self.points.len()];
        a + (b - a) * f
    }

    /// The direction (radians, CCW from x) of the segment at arc length `s`.
    pub fn heading_at(&self, s: f64) -> f64 {
        let (i, _) = self.locate(s);
        let a = self.points[i];
        let b = self.points[(i + 1) % self.points.len()];
        detmath::atan2(b.y - a.y, b.x - a.x)
    }

    /// The pose at arc length `s` (closed paths wrap), heading along its segment.
    pub fn pose_at(&self, s: f64) -> Pose2 {
        let p = self.point_at(s);
        Pose2::new(p.x, p.y, self.heading_at(s))
    }

    /// The pose at the start of the path, heading along the first segment.
    pub fn start_pose(&self) -> Pose2 {
        let p = self.points[0];
        Pose2::new(p.x, p.y, self.heading_at(0.0))
    }

    /// A smooth closed or open path: each corner of the polyline replaced by a circular arc
    /// of radius `radius` sampled every `step` metres (a rounded polygon), so that a
    /// unicycle can follow it without stopping.
    pub fn rounded(
        points: &[Point2],
        closed: bool,
        radius: f64,
        step: f64,
    ) -> Result<Self, SimError> {
        let raw = Path::new(points.to_vec(), closed)?;
        let p = &raw.points;
        let n = p.len();
        let mut out = Vec::new();
        for i in 0..n {
            let has_corner = closed || (i > 0 && i + 1 < n);
            if !has_corner {
                out.push(p[i]);
                continue;
            }
            let prev = p[(i + n - 1) % n];
            let next = p[(i + 1) % n];
            let d_in = (p[i] - prev).normalize();
            let d_out = (next - p[i]).normalize();
            let turn =
                normalize_angle(detmath::atan2(d_out.y, d_out.x) - detmath::atan2(d_in.y, d_in.x));
            if turn.abs() < 1e-6 {
                out.push(p[i]);
                continue;
            }
            // Tangent length limited to half of each adjacent segment.
            let max_t = 0.5 * (p[i] - prev).norm().min((next - p[i]).norm());
            let tan_half = detmath::tan(turn.abs() / 2.0);
            let t = (radius * tan_half).min(max_t);
            let r = t / tan_half;
            let a = p[i] - d_in * t;
            // Centre on the inside of the turn.
            let normal = if turn > 0.0 {
                nalgebra::Vector2::new(-d_in.y, d_in.x)
            } else {
                nalgebra::Vector2::new(d_in.y, -d_in.x)
            };
            let c = a + normal * r;
            let arc = r * turn.abs();
            let k = (arc / step).ceil().max(1.0) as usize;
            let a0 = detmath::atan2((a - c).y, (a - c).x);
            for j in 0..=k {
                let ang = a0 + turn * j as f64 / k as f64;
                out.push(c + nalgebra::Vector2::new(r * detmath::cos(ang), r * detmath::sin(ang)));
            }
        }
        Path::new(out, closed)
    }
}

/// Settings of the pure-pursuit follower.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct FollowerConfig {
    /// Nominal forward speed, m/s.
    pub speed: f64,
    /// Control period Δt, s (one simulation step).
    pub dt: f64,
    /// Pure-pursuit look-ahead distance ahead of the carrot, metres.
    pub lookahead: f64,
    /// Largest commanded turn rate, rad/s.
    pub max_turn_rate: f64,
}

impl Default for FollowerConfig {
    /// 1 m/s, Δt = 0.2 s (0.2 m per step), look-ahead 1 m, |ω| ≤ 1.5 rad/s.
    fn default() -> Self {
        Self {
            speed: 1.0,
            dt: 0.2,
            lookahead: 1.0,
            max_turn_rate: 1.5,
        }
    }
}

impl FollowerConfig {
    /// Rejects non-finite or non-positive settings.
    pub fn validate(&self) -> Result<(), SimError> {
        check_range("speed", self.speed, 1e-6, 100.0, "0 < speed <= 100 m/s")?;
        check_range("dt", self.dt, 1e-6, 100.0, "0 < dt <= 100 s")?;
        check_range(
            "lookahead",
            self.lookahead,
            1e-3,
            1e3,
            "0 < lookahead <= 1000 m",
        )?;
        check_range(
            "max_turn_rate",
            self.max_turn_rate,
            1e-3,
            100.0,
            "0 < max_turn_rate <= 100 rad/s",
        )?;
        Ok(())
    }
}

/// Pure-pursuit waypoint follower along a [`Path`].
#[derive(Debug, Clone)]
pub struct Follower<'a> {
    path: &'a Path,
    cfg: FollowerConfig,
    /// Arc length of the carrot.
    s: f64,
    /// True while turning on the spot.
    spinning: bool,
}

impl<'a> Follower<'a> {
    /// A follower whose carrot starts at the beginning of `path`.
    pub fn new(path: &'a Path, cfg: FollowerConfig) -> Result<Self, SimError> {
        cfg.validate()?;
        Ok(Self {
            path,
            cfg,
            s: 0.0,
            spinning: false,
        })
    }

    /// Arc length the carrot has travelled, metres.
    pub fn progress(&self) -> f64 {
        self.s
    }

    /// Moves the carrot to arc length `s` (clamped to an open path's length), e.g. after
    /// the simulator carried the robot there (a kidnapping). Stops any turn on the spot.
    pub fn jump_to(&mut self, s: f64) {
        self.s = if self.path.is_closed() {
            s
        } else {
            s.clamp(0.0, self.path.length())
        };
        self.spinning = false;
    }

    /// True when an open path's end has been reached by the carrot.
    pub fn finished(&self) -> bool {
        !self.path.is_closed() && self.s >= self.path.length() - 1e-9
    }

    /// The velocity command for the next step from the robot's true pose.
    ///
    /// Pure pursuit: with α the bearing of the target point (carrot + look-ahead) in the
    /// robot frame and d its distance, the arc through it has curvature κ = 2·sin α / d;
    /// ω = v·κ, clamped to ±`max_turn_rate`. The speed is scaled by the carrot distance
    /// (between 0.5 and 1.5 times nominal) so that the robot neither falls behind nor
    /// overtakes the carrot, and slowed in sharp turns so that the clamp rarely binds.
    /// When the target is far to the side or behind (|α| > 60°, e.g. at a U-turn of the
    /// path), pure pursuit would swing wide or drive straight on; the robot turns on the
    /// spot instead (v = 0) until the target is within 10° of its heading. The
    /// carrot waits while the robot is more than two look-ahead distances behind it.
    pub fn command(&mut self, pose: &Pose2) -> VelocityControl {
        let cfg = &self.cfg;
        let target = self.path.point_at(self.s + cfg.lookahead);
        let local = pose.inverse_transform_point(&target);
        let d = local.coords.norm().max(1e-6);
        let alpha = detmath::atan2(local.y, local.x);
        let carrot = self.path.point_at(self.s);
        let lag = (carrot - pose.translation()).norm();
        if alpha.abs() > std::f64::consts::FRAC_PI_3 {
            self.spinning = true;
        } else if alpha.abs() < 10f64.to_radians() {
            self.spinning = false;
        }
        let (v, omega) = if self.spinning {
            let w = (alpha.abs() / cfg.dt).min(cfg.max_turn_rate);
            (0.0, w.copysign(alpha))
        } else {
            // Positive when the carrot is ahead of the robot.
            let ahead = pose.inverse_transform_point(&carrot).x;
            let factor = if ahead >= 0.0 {
                (1.0 + lag / cfg.lookahead).min(1.5)
            } else {
                (1.0 - lag / cfg.lookahead).max(0.5)
            };
            let kappa = 2.0 * detmath::sin(alpha) / d;
            let mut v = cfg.speed * factor;
            // Slow down so that v·κ stays within the turn-rate limit.
            if v * kappa.abs() > cfg.max_turn_rate {
                v = (cfg.max_turn_rate / kappa.abs()).max(0.1 * cfg.speed);
            }
            (v, (v * kappa).clamp(-cfg.max_turn_rate, cfg.max_turn_rate))
        };
        if lag < 2.0 * cfg.lookahead {
            self.s += cfg.speed * cfg.dt;
        }
        if !self.path.is_closed() {
            self.s = self.s.min(self.path.length());
        }
        VelocityControl {
            v,
            omega,
            dt: cfg.dt,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_models::motion::{MotionModel, VelocityModel};

    fn square() -> Vec<Point2> {
        vec![
            Point2::new(0.0, 0.0),
            Point2::new(10.0, 0.0),
            Point2::new(10.0, 10.0),
            Point2::new(0.0, 10.0),
        ]
    }

    #[test]
    fn arc_length_and_wrapping() {
        let p = Path::new(square(), true).unwrap();
        assert!((p.length() - 40.0).abs() < 1e-12);
        assert!((p.point_at(15.0) - Point2::new(10.0, 5.0)).norm() < 1e-12);
        assert!((p.point_at(55.0) - Point2::new(10.0, 5.0)).norm() < 1e-12);
        assert!((p.point_at(-5.0) - Point2::new(0.0, 5.0)).norm() < 1e-12);
        let open = Path::new(square(), false).unwrap();
        assert!((open.length() - 30.0).abs() < 1e-12);
        assert!((open.point_at(100.0) - Point2::new(0.0, 10.0)).norm() < 1e-12);
        assert!(Path::new(vec![Point2::new(1.0, 1.0); 3], false).is_err());
        assert!(Path::new(
            vec![Point2::new(f64::NAN, 1.0), Point2::new(0.0, 0.0)],
            false
        )
        .is_err());
    }

    #[test]
    fn rounded_square_is_shorter_and_smooth() {
        let r = 2.0;
        let p = Path::rounded(&square(), true, r, 0.1).unwrap();
        // Four quarter circles replace four corners: length = 40 − 8r + 2πr.
        let expect = 40.0 - 8.0 * r + 2.0 * std::f64::consts::PI * r;
        assert!(
            (p.length() - expect).abs() < 0.01,
            "{} vs {expect}",
            p.length()
        );
    }

    #[test]
    fn u_turn_is_taken_on_the_spot() {
        // Out and back along the x axis: the robot must not overshoot the turning point
        // by more than the look-ahead, nor leave the line by more than a few centimetres.
        let path = Path::new(
            vec![
                Point2::new(0.0, 0.0),
                Point2::new(5.0, 0.0),
                Point2::new(0.0, 0.0),
            ],
            false,
        )
        .unwrap();
        let cfg = FollowerConfig {
            lookahead: 0.5,
            ..Default::default()
        };
        let mut f = Follower::new(&path, cfg).unwrap();
        let m = VelocityModel::default();
        let mut pose = path.start_pose();
        let (mut max_x, mut max_y): (f64, f64) = (0.0, 0.0);
        for _ in 0..200 {
            let u = f.command(&pose);
            pose = m.predict(&pose, &u);
            max_x = max_x.max(pose.x);
            max_y = max_y.max(pose.y.abs());
        }
        assert!(max_x < 5.5, "overshot to x = {max_x}");
        assert!(max_y < 0.3, "left the line by {max_y}");
        assert!(pose.x < 1.0, "did not come back: {pose:?}");
    }

    #[test]
    fn noise_free_follower_tracks_the_path() {
        let path = Path::rounded(&square(), true, 2.0, 0.1).unwrap();
        let mut f = Follower::new(&path, FollowerConfig::default()).unwrap();
        let m = VelocityModel::default();
        let mut pose = path.start_pose();
        let mut worst: f64 = 0.0;
        for _ in 0..400 {
            let u = f.command(&pose);
            pose = m.predict(&pose, &u);
            // Distance to the path: sample the path finely.
            let d = (0..2000)
                .map(|k| {
                    (path.point_at(k as f64 * path.length() / 2000.0) - pose.translation()).norm()
                })
                .fold(f64::INFINITY, f64::min);
            worst = worst.max(d);
        }
        assert!(worst < 0.3, "robot strayed {worst} m from the path");
    }
}
