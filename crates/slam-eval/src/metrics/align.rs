//! Least-squares rigid alignment in the plane (Umeyama 1991 without scale; Horn 1987).

use slam_models::{Point2, Pose2};

/// The rigid motion T = (R(θ), t) minimising Σᵢ ‖bᵢ − (R·aᵢ + t)‖² over pairs (aᵢ, bᵢ).
///
/// With centroids ā, b̄ and centred points a′ = a − ā, b′ = b − b̄ (Umeyama 1991, eq. 40–42,
/// scale fixed to 1; in 2-D the SVD reduces to an angle):
/// θ = atan2(Σ a′ₓb′ᵧ − a′ᵧb′ₓ, Σ a′ₓb′ₓ + a′ᵧb′ᵧ), t = b̄ − R(θ)·ā.
/// The result is returned as a [`Pose2`], so `T.transform_point(a)` maps `a` onto `b`.
/// With fewer than two distinct points θ = 0 (a pure translation); with no points, the
/// identity.
pub fn align_se2(a: &[Point2], b: &[Point2]) -> Pose2 {
    let n = a.len().min(b.len());
    if n == 0 {
        return Pose2::IDENTITY;
    }
    let nf = n as f64;
    let ca = a[..n]
        .iter()
        .fold(nalgebra::Vector2::zeros(), |s, p| s + p.coords)
        / nf;
    let cb = b[..n]
        .iter()
        .fold(nalgebra::Vector2::zeros(), |s, p| s + p.coords)
        / nf;
    let (mut sin, mut cos) = (0.0, 0.0);
    for (p, q) in a[..n].iter().zip(&b[..n]) {
        let u = p.coords - ca;
        let v = q.coords - cb;
        sin += u.x * v.y - u.y * v.x;
        cos += u.x * v.x + u.y * v.y;
    }
    let theta = if sin == 0.0 && cos == 0.0 {
        0.0
    } else {
        sin.atan2(cos)
    };
    let (s, c) = theta.sin_cos();
    let t = cb - nalgebra::Vector2::new(c * ca.x - s * ca.y, s * ca.x + c * ca.y);
    Pose2::new(t.x, t.y, theta)
}

/// Position errors of paired points (estimate aᵢ, truth bᵢ), as is (‖aᵢ − bᵢ‖) and after
/// [`align_se2`] of a onto b (‖T·aᵢ − bᵢ‖), with that alignment T: the two figures every
/// map and trajectory metric reports.
pub(crate) fn errors_as_is_and_aligned(a: &[Point2], b: &[Point2]) -> (Vec<f64>, Vec<f64>, Pose2) {
    let t = align_se2(a, b);
    let (as_is, aligned) = a
        .iter()
        .zip(b)
        .map(|(p, q)| ((p - q).norm(), (t.transform_point(p) - q).norm()))
        .unzip();
    (as_is, aligned, t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_known_motion_exactly() {
        let a: Vec<Point2> = [(0.0, 0.0), (2.0, 0.0), (2.0, 1.0), (-1.0, 3.0)]
            .iter()
            .map(|&(x, y)| Point2::new(x, y))
            .collect();
        let t = Pose2::new(1.5, -2.0, 0.7);
        let b: Vec<Point2> = a.iter().map(|p| t.transform_point(p)).collect();
        assert!(align_se2(&a, &b).approx_eq(&t, 1e-12));
    }

    #[test]
    fn hand_computed_two_points() {
        // a = (0,0), (1,0); b = (0,0), (0,2): centroids (0.5,0) and (0,1); the best rotation
        // turns the x axis onto the y axis (θ = 90°), t = b̄ − R·ā = (0,1) − (0,0.5) = (0, 0.5).
        let a = [Point2::new(0.0, 0.0), Point2::new(1.0, 0.0)];
        let b = [Point2::new(0.0, 0.0), Point2::new(0.0, 2.0)];
        let t = align_se2(&a, &b);
        assert!(t.approx_eq(&Pose2::new(0.0, 0.5, std::f64::consts::FRAC_PI_2), 1e-12));
        assert_eq!(align_se2(&[], &[]), Pose2::IDENTITY);
        let one = align_se2(&[Point2::new(1.0, 1.0)], &[Point2::new(3.0, 0.0)]);
        assert!(one.approx_eq(&Pose2::new(2.0, -1.0, 0.0), 1e-12));
    }
}
