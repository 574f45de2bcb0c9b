//! The checks of [`LaserGraphConfig`]: every field against its documented range, the error
//! naming the field, the value and the bound.

use super::*;

impl LaserGraphConfig {
    /// Checks every field against its documented range; the error names the field, the
    /// value and the bound.
    pub fn validate(&self) -> Result<(), GraphError> {
        let r = self.resolution;
        // From 0.1 mm (the finest map.yaml resolution slam-io reads back, as known-poses'
        // bound): finer cells put every end point at a cell index beyond the grid's.
        ensure(
            (1e-4..=10.0).contains(&r),
            "resolution",
            r,
            "in [1e-4, 10] m",
        )?;
        self.sensor_model.validate()?;
        self.likelihood.validate()?;
        let m = self.match_max_range;
        // At least one cell: a shorter limit matches no end point, and the run silently
        // kept its odometry (`match-max-range = 1e-300` with exit code 0).
        ensure(
            m >= r,
            "match-max-range",
            m,
            "at least resolution (one cell; a shorter limit matches no end point)",
        )?;
        let d = self.keyframe_distance;
        ensure(d >= 0.0, "keyframe-distance", d, ">= 0 m")?;
        let a = self.keyframe_angle;
        ensure(a >= 0.0, "keyframe-angle", a, ">= 0 rad")?;
        self.local_matcher.correlative.validate()?;
        self.local_matcher.refine.validate()?;
        let s = self.local_min_score;
        ensure((0.0..=1.0).contains(&s), "local-min-score", s, "in [0, 1]")?;
        self.local_recovery.validate()?;
        let k = self.match_covariance_scale;
        ensure(k > 0.0, "match-covariance-scale", k, "> 0")?;
        if let MatchCovariance::Response {
            linear_window,
            angular_window,
            temperature,
        } = self.match_covariance
        {
            let w = linear_window;
            ensure(
                w > 0.0 && w <= 2.0,
                "match-covariance.linear-window",
                w,
                "in (0, 2] m",
            )?;
            let a = angular_window;
            ensure(
                (0.0..=0.5).contains(&a),
                "match-covariance.angular-window",
                a,
                "in [0, 0.5] rad",
            )?;
            let t = temperature;
            ensure(t >= 1.0, "match-covariance.temperature", t, ">= 1")?;
        }
        for (i, &v) in self.match_min_std.iter().enumerate() {
            let f = ["match-min-std[0]", "match-min-std[1]"][i];
            ensure(v > 0.0, f, v, "> 0 (m, rad)")?;
        }
        let n = self.submap_scans;
        ensure(
            (2..=MAX_SUBMAP_SCANS).contains(&n),
            "submap-scans",
            n as f64,
            "in 2..=10000",
        )?;
        let o = &self.odometry_noise;
        for (f, v) in [
            (
                "odometry-noise.translation-per-metre",
                o.translation_per_metre,
            ),
            (
                "odometry-noise.translation-per-radian",
                o.translation_per_radian,
            ),
            ("odometry-noise.rotation-per-radian", o.rotation_per_radian),
            ("odometry-noise.rotation-per-metre", o.rotation_per_metre),
        ] {
            ensure(v >= 0.0, f, v, ">= 0")?;
        }
        ensure(
            o.min_translation > 0.0,
            "odometry-noise.min-translation",
            o.min_translation,
            "> 0 m",
        )?;
        ensure(
            o.min_rotation > 0.0,
            "odometry-noise.min-rotation",
            o.min_rotation,
            "> 0 rad",
        )?;
        let s = self.loop_min_score;
        ensure((0.0..=1.0).contains(&s), "loop-min-score", s, "in [0, 1]")?;
        ensure(
            self.loop_radius >= 0.0,
            "loop-radius",
            self.loop_radius,
            ">= 0 m",
        )?;
        let g = self.loop_radius_growth;
        ensure(g >= 0.0, "loop-radius-growth", g, ">= 0 m per m")?;
        ensure(
            self.loop_max_radius >= self.loop_radius && self.loop_max_radius <= 50.0,
            "loop-max-radius",
            self.loop_max_radius,
            "in [loop-radius, 50] m",
        )?;
        ensure(
            self.loop_angle >= 0.0,
            "loop-angle",
            self.loop_angle,
            ">= 0 rad",
        )?;
        let g = self.loop_angle_growth;
        ensure(g >= 0.0, "loop-angle-growth", g, ">= 0 rad per m")?;
        ensure(
            self.loop_max_angle >= self.loop_angle && self.loop_max_angle <= std::f64::consts::PI,
            "loop-max-angle",
            self.loop_max_angle,
            "in [loop-angle, π] rad",
        )?;
        let r = self.loop_ambiguity_ratio;
        ensure(r > 0.0 && r <= 1.0, "loop-ambiguity-ratio", r, "in (0, 1]")?;
        let a = self.degenerate_anisotropy;
        ensure(
            a == 0.0 || a >= 1.0,
            "degenerate-anisotropy",
            a,
            ">= 1, or 0 for never",
        )?;
        let a = self.loop_max_anisotropy;
        ensure(a >= 1.0, "loop-max-anisotropy", a, ">= 1")?;
        for (f, v) in [
            ("loop-group-span", self.loop_group_span),
            ("loop-group-gap", self.loop_group_gap),
            ("loop-group-min-size", self.loop_group_min_size),
            ("loop-wide-interval", self.loop_wide_interval),
        ] {
            ensure((1..=1000).contains(&v), f, v as f64, "in 1..=1000")?;
        }
        ensure(
            self.loop_wide_radius >= 0.0,
            "loop-wide-radius",
            self.loop_wide_radius,
            ">= 0 m",
        )?;
        ensure(
            self.loop_wide_angle >= 0.0,
            "loop-wide-angle",
            self.loop_wide_angle,
            ">= 0 rad",
        )?;
        let q = self.loop_group_min_ratio;
        ensure(q >= 1.0, "loop-group-min-ratio", q, ">= 1")?;
        for (i, &v) in self.loop_group_drift.iter().enumerate() {
            let f = ["loop-group-drift[0]", "loop-group-drift[1]"][i];
            ensure(v >= 0.0, f, v, ">= 0 (m/m, rad/m)")?;
        }
        ensure(
            (1..=slam_grid::matcher::MAX_PYRAMID_DEPTH).contains(&self.loop_depth),
            "loop-depth",
            self.loop_depth as f64,
            "in 1..=12",
        )?;
        ensure(
            self.loop_min_scan_gap >= self.submap_scans,
            "loop-min-scan-gap",
            self.loop_min_scan_gap as f64,
            ">= submap-scans (a submap still being built is no loop)",
        )?;
        ensure(
            self.loop_max_candidates <= 100,
            "loop-max-candidates",
            self.loop_max_candidates as f64,
            "in 0..=100 (0 switches loop closure off)",
        )?;
        let r = self.loop_sampling_ratio;
        ensure(r > 0.0 && r <= 1.0, "loop-sampling-ratio", r, "in (0, 1]")?;
        ensure(
            (1..=1000).contains(&self.loop_pyramid_cache),
            "loop-pyramid-cache",
            self.loop_pyramid_cache as f64,
            "in 1..=1000",
        )?;
        ensure(
            self.loop_pyramid_cache_bytes <= 1 << 40,
            "loop-pyramid-cache-bytes",
            self.loop_pyramid_cache_bytes as f64,
            "at most 2^40 (0 keeps one pyramid)",
        )?;
        self.optimizer.validate()?;
        self.smoother.validate()?;
        let c = self.smoother_max_closure_chi2;
        ensure(c > 0.0, "smoother-max-closure-chi2", c, "> 0")?;
        self.odometry_jump.validate()?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Defaults validate; each documented bound is enforced with the field's name.
    #[test]
    fn validation_names_the_field() {
        LaserGraphConfig::default().validate().unwrap();
        let cases: Vec<(LaserGraphConfig, &str)> = vec![
            (
                LaserGraphConfig {
                    resolution: 0.0,
                    ..Default::default()
                },
                "resolution",
            ),
            (
                LaserGraphConfig {
                    resolution: 1e-300,
                    ..Default::default()
                },
                "resolution",
            ),
            (
                LaserGraphConfig {
                    submap_scans: 1,
                    ..Default::default()
                },
                "submap-scans",
            ),
            // Below one cell no end point is matched (1e-300 ran with exit code 0).
            (
                LaserGraphConfig {
                    match_max_range: 1e-300,
                    ..Default::default()
                },
                "match-max-range",
            ),
            (
                LaserGraphConfig {
                    loop_min_score: 1.5,
                    ..Default::default()
                },
                "loop-min-score",
            ),
            (
                LaserGraphConfig {
                    loop_max_radius: 0.1,
                    ..Default::default()
                },
                "loop-max-radius",
            ),
            (
                LaserGraphConfig {
                    loop_min_scan_gap: 3,
                    ..Default::default()
                },
                "loop-min-scan-gap",
            ),
            (
                LaserGraphConfig {
                    loop_sampling_ratio: 0.0,
                    ..Default::default()
                },
                "loop-sampling-ratio",
            ),
            (
                LaserGraphConfig {
                    loop_sampling_ratio: f64::NAN,
                    ..Default::default()
                },
                "loop-sampling-ratio",
            ),
            (
                LaserGraphConfig {
                    match_min_std: [0.0, 0.01],
                    ..Default::default()
                },
                "match-min-std[0]",
            ),
            (
                LaserGraphConfig {
                    match_covariance: MatchCovariance::Response {
                        linear_window: 0.3,
                        angular_window: 0.03,
                        temperature: 0.5,
                    },
                    ..Default::default()
                },
                "match-covariance.temperature",
            ),
            (
                LaserGraphConfig {
                    odometry_noise: OdometryNoise {
                        min_rotation: 0.0,
                        ..Default::default()
                    },
                    ..Default::default()
                },
                "odometry-noise.min-rotation",
            ),
        ];
        for (c, field) in cases {
            let e = c.validate().unwrap_err();
            assert!(e.to_string().contains(field), "{e} should name {field}");
        }
    }

    /// Kebab-case keys in TOML-like JSON round trip; unknown keys are refused.
    #[test]
    fn serde_uses_kebab_case_and_refuses_unknown_keys() {
        let c: LaserGraphConfig =
            serde_json::from_str(r#"{"submap-scans": 10, "loop-min-score": 0.7}"#).unwrap();
        assert_eq!(c.submap_scans, 10);
        assert_eq!(c.loop_min_score, 0.7);
        assert_eq!(c.resolution, 0.05);
        assert!(serde_json::from_str::<LaserGraphConfig>(r#"{"submap_scans": 10}"#).is_err());
        let c: LaserGraphConfig = serde_json::from_str(
            r#"{"match-covariance": {"kind": "response", "linear-window": 0.5,
                "angular-window": 0.05, "temperature": 30.0}}"#,
        )
        .unwrap();
        assert_eq!(
            c.match_covariance,
            MatchCovariance::Response {
                linear_window: 0.5,
                angular_window: 0.05,
                temperature: 30.0
            }
        );
        let c: LaserGraphConfig =
            serde_json::from_str(r#"{"match-covariance": {"kind": "matcher"}}"#).unwrap();
        assert_eq!(c.match_covariance, MatchCovariance::Matcher);
    }
}
