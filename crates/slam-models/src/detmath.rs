//! Deterministic transcendental functions: the same bits on every machine.
//!
//! Rust's `f64::sin`, `exp`, `atan2`, … defer to the platform's math library, whose results
//! may differ in the last bit between systems (glibc even picks FMA or non-FMA code paths per
//! CPU at run time). IEEE-754 arithmetic and `sqrt` are exact everywhere, so a computation
//! built from them plus these wrappers gives bit-identical results on any machine.
//!
//! Every wrapper forwards to the pure-Rust [`libm`] crate (a port of musl's libm, pinned to
//! one version in the workspace), whose algorithms use plain IEEE arithmetic only. Its errors
//! are below one ulp, like the system library's; the point is not accuracy but that the
//! result no longer depends on the machine.
//!
//! slam-models and slam-sim use these for every transcendental function outside their tests
//! (`cargo xtask test-all` checks this in its tidy step). Other crates may keep `std`.
//!
//! Also deterministic and fine to use directly: `+ − × ÷`, `sqrt`, `mul_add`, `%`,
//! `rem_euclid`, `floor`/`ceil`/`round`, `abs`, `to_radians` (one multiplication by π/180).
//! Not deterministic: `powi` (LLVM leaves the order of its multiplications unspecified), so
//! write the product out.

/// sin x (x in radians).
#[inline]
pub fn sin(x: f64) -> f64 {
    libm::sin(x)
}

/// cos x (x in radians).
#[inline]
pub fn cos(x: f64) -> f64 {
    libm::cos(x)
}

/// (sin x, cos x), computed together (x in radians).
#[inline]
pub fn sin_cos(x: f64) -> (f64, f64) {
    libm::sincos(x)
}

/// tan x (x in radians).
#[inline]
pub fn tan(x: f64) -> f64 {
    libm::tan(x)
}

/// The four-quadrant arctangent of y/x, in [−π, π]; the angle of the vector (x, y).
/// Argument order as `f64::atan2`: `atan2(y, x)`.
#[inline]
pub fn atan2(y: f64, x: f64) -> f64 {
    libm::atan2(y, x)
}

/// eˣ.
#[inline]
pub fn exp(x: f64) -> f64 {
    libm::exp(x)
}

/// The natural logarithm ln x.
#[inline]
pub fn ln(x: f64) -> f64 {
    libm::log(x)
}

/// √(x² + y²) without undue overflow or underflow.
#[inline]
pub fn hypot(x: f64, y: f64) -> f64 {
    libm::hypot(x, y)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance in units in the last place between two finite doubles of the same sign.
    fn ulps(a: f64, b: f64) -> u64 {
        if a == b {
            return 0;
        }
        assert!(a.is_finite() && b.is_finite(), "{a} vs {b}");
        // Map the sign-magnitude bit patterns onto a monotone integer line.
        let key = |x: f64| {
            let i = x.to_bits() as i64;
            if i < 0 {
                i64::MIN - i
            } else {
                i
            }
        };
        key(a).abs_diff(key(b))
    }

    /// A sweep of arguments: a fine grid over a few periods plus large and tiny magnitudes.
    fn sweep() -> Vec<f64> {
        let mut xs: Vec<f64> = (-20_000..=20_000).map(|k| k as f64 * 1.0e-3).collect();
        xs.extend((-300..=300).map(|k| (k as f64 * 0.37).exp()));
        xs.extend((-300..=300).map(|k| -(k as f64 * 0.37).exp()));
        xs.extend([1e-300, -1e-300, 1e6 + 0.1, 1e15 + 0.3]);
        xs
    }

    // Both libm and the system library are accurate to within one ulp of the true value,
    // so they can disagree by at most two (the system one is the reference here, not an
    // oracle).
    const MAX_ULPS: u64 = 2;

    #[test]
    fn trig_agrees_with_std() {
        for x in sweep() {
            let (s, c) = sin_cos(x);
            assert!(ulps(s, x.sin()) <= MAX_ULPS, "sin({x}): {s} vs {}", x.sin());
            assert!(ulps(c, x.cos()) <= MAX_ULPS, "cos({x}): {c} vs {}", x.cos());
            assert_eq!(s.to_bits(), sin(x).to_bits(), "sin_cos vs sin at {x}");
            assert_eq!(c.to_bits(), cos(x).to_bits(), "sin_cos vs cos at {x}");
            assert!(ulps(tan(x), x.tan()) <= MAX_ULPS, "tan({x})");
        }
    }

    #[test]
    fn atan2_and_hypot_agree_with_std() {
        let vals: Vec<f64> = (-60..=60).map(|k| k as f64 * 0.173 - 0.05).collect();
        for &y in &vals {
            for &x in &vals {
                assert!(ulps(atan2(y, x), y.atan2(x)) <= MAX_ULPS, "atan2({y}, {x})");
                assert!(ulps(hypot(x, y), x.hypot(y)) <= MAX_ULPS, "hypot({x}, {y})");
            }
        }
        assert_eq!(atan2(0.0, -1.0), std::f64::consts::PI);
        assert_eq!(hypot(3.0, 4.0), 5.0);
    }

    #[test]
    fn exp_and_ln_agree_with_std() {
        for k in -70_000..=70_000 {
            let x = k as f64 * 1.0e-2; // −700 … 700, inside exp's finite range
            assert!(ulps(exp(x), x.exp()) <= MAX_ULPS, "exp({x})");
        }
        for x in sweep().into_iter().filter(|x| *x > 0.0) {
            assert!(ulps(ln(x), x.ln()) <= MAX_ULPS, "ln({x})");
        }
        assert_eq!(ln(1.0), 0.0);
        assert_eq!(exp(0.0), 1.0);
        assert!(ln(0.0) == f64::NEG_INFINITY && ln(-1.0).is_nan());
    }
}
