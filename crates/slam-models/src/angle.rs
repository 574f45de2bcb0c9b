//! Angle normalisation.

use std::f64::consts::PI;

/// Wraps an angle in radians to the half-open interval (−π, π].
///
/// Every angle *difference* in slam-rs (innovations, headings after motion, relative
/// poses) goes through this function. Non-finite input is returned unchanged (NaN stays NaN)
/// so that callers' finiteness checks still see it.
///
/// ```
/// use slam_models::normalize_angle;
/// use std::f64::consts::PI;
/// assert!((normalize_angle(3.0 * PI) - PI).abs() < 1e-12);
/// assert!((normalize_angle(-PI) - PI).abs() < 1e-12);
/// assert!((normalize_angle(0.5) - 0.5).abs() < 1e-15);
/// ```
#[inline]
pub fn normalize_angle(a: f64) -> f64 {
    if (-PI..=PI).contains(&a) && a != -PI {
        return a;
    }
    if !a.is_finite() {
        return a;
    }
    let mut r = a.rem_euclid(2.0 * PI); // [0, 2π)
    if r > PI {
        r -= 2.0 * PI;
    }
    r
}

/// Signed smallest difference `a − b`, normalised to (−π, π].
#[inline]
pub fn angle_diff(a: f64, b: f64) -> f64 {
    normalize_angle(a - b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]
        #[test]
        fn normalized_is_in_range_and_equivalent(a in -1e4f64..1e4) {
            let n = normalize_angle(a);
            prop_assert!(n > -PI && n <= PI);
            // Same direction: sin and cos agree.
            prop_assert!((n.sin() - a.sin()).abs() < 1e-9);
            prop_assert!((n.cos() - a.cos()).abs() < 1e-9);
        }
    }

    #[test]
    fn boundaries() {
        assert_eq!(normalize_angle(PI), PI);
        assert!((normalize_angle(-PI) - PI).abs() < 1e-15);
        assert!(normalize_angle(f64::NAN).is_nan());
        assert!((angle_diff(-3.1, 3.1) - (2.0 * PI - 6.2)).abs() < 1e-12);
    }
}
