//! The rotation of a deformed tetrahedron, for corotational elasticity.
//!
//! Given the deformation gradient `F` of an element, the corotational model needs the
//! rotation `R` of its polar decomposition `F = R S` (`S` symmetric): the rotation for
//! which `Rᵀ F` is symmetric. This is the rotation that maximises `tr(Rᵀ F)` over all
//! proper rotations, and it is found here by the iteration of Müller, Bender, Chentanez
//! and Macklin, "A Robust Method to Extract the Rotational Part of Deformations"
//! (MIG 2016):
//!
//! `ω = Σ_k r_k × f_k / (|Σ_k r_k · f_k| + ε)`,  `R ← exp([ω]×) R`,
//!
//! where `r_k`, `f_k` are the columns of `R` and `F`. `Σ_k r_k × f_k = 0` is exactly
//! the condition that `Rᵀ F` be symmetric, and each update turns `R` towards it.
//!
//! Why this extraction and not another:
//! - it is warm-started from the previous tick's rotation, so once a motion is under
//!   way one or two iterations (a few dozen flops, no `sin`/`cos`, see
//!   [`polar`]) reach round-off; a 3×3 SVD costs several times more for every
//!   element of every tick;
//! - it always returns a proper rotation (`det R = +1`), also for an inverted element
//!   (`det F < 0`), where it converges to `U diag(1, 1, −1) Vᵀ` (`F = U Σ Vᵀ`): the
//!   rotation that maximises `tr(Rᵀ F)`, the choice of Irving, Teran and Fedkiw
//!   (2004) for inverted elements. The elastic force `R K (Rᵀ x − X)` then pushes the
//!   element back through its flat state instead of letting it stay inverted, which a
//!   polar factor with a reflection (Higham's iteration, `det R = −1`) would not;
//! - a degenerate element (`F` of rank 1 or 2: flattened onto a plane or a line)
//!   still gives a well-defined rotation (any maximiser of `tr(Rᵀ F)` is a rotation),
//!   and `F = 0` (collapsed to a point) leaves the warm start unchanged: no division
//!   by zero, no NaN;
//! - a QR or edge-based frame depends on the vertex numbering and is not the polar
//!   rotation, so it would not give forces that derive from an energy (see
//!   [`corotational`](super::corotational)).

use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3};

/// Stop when the correction angle is below this, rad (or after a Newton step below
/// [`LAST_STEP`], which leaves about as little). The rotation then leaves `Rᵀ F`
/// symmetric to about this relative accuracy: well under the 1e-9 relative accuracy
/// of the forces the tests demand, a few hundred ulps above round-off.
pub const ANGLE_TOLERANCE: f64 = 1e-13;

/// Iterations allowed when warm-started from the last tick's rotation. A tick
/// rotates an element by far less than a radian, and from there the Newton steps
/// below reach round-off in two or three; the cap only bounds the worst case (a
/// rotation that is not yet exact is still a rotation, and the next tick goes on).
pub const WARM_ITERATIONS: u32 = 12;

/// Iterations allowed from no prior estimate (a rotation of up to 180°).
pub const COLD_ITERATIONS: u32 = 100;

/// Below this step angle (rad), the Newton step replaces Müller's.
const NEWTON_RANGE: f64 = 0.3;

/// A Newton step below this angle (rad) is the last: it is applied and the
/// iteration ends without measuring what is left. Near the answer a Newton step of
/// size `|ω|` leaves an error of about `|ω|³/4` (the convergence is cubic, see
/// [`polar`]; the factor was measured over stretches from 0.5 to 2), so after a last
/// step under 2e-5 rad the rotation is within 2e-15 rad of the polar one, at
/// round-off and under [`ANGLE_TOLERANCE`], and the evaluation that would only
/// confirm it is saved. A tick turns an element by up to about 1e-3 rad, which one
/// Newton step brings to 1e-10 and a second, the last, to round-off: two evaluations
/// instead of three.
pub const LAST_STEP: f64 = 2e-5;

/// Turns `q` towards the rotation of the polar decomposition of `f`, in at most
/// `max_iterations` steps, starting from `q` (the warm start). Returns the
/// iterations taken.
pub fn extract_rotation(f: &Matrix3<f64>, q: &mut UnitQuaternion<f64>, max_iterations: u32) -> u32 {
    polar(f, q, max_iterations).iterations
}

/// The rotation of the polar decomposition of `f`, extracted cold: from the
/// identity, in at most [`COLD_ITERATIONS`] steps. What a force or a strain needs
/// that must not depend on the rotations a solver carried.
pub fn cold_rotation(f: &Matrix3<f64>) -> Matrix3<f64> {
    let mut q = UnitQuaternion::identity();
    extract_rotation(f, &mut q, COLD_ITERATIONS);
    *q.to_rotation_matrix().matrix()
}

/// What [`polar`] found: the rotation and what the forces need of it.
#[derive(Clone, Copy, Debug)]
pub struct Polar {
    /// The rotation `R` (the matrix of the updated `q`).
    pub r: Matrix3<f64>,
    /// `A = Rᵀ F`, whose symmetric part is the stretch `S` once `R` has converged: the
    /// strain `ε = sym(A) − I` comes without another product.
    pub a: Matrix3<f64>,
    /// Steps taken.
    pub iterations: u32,
}

/// Turns `q` towards the rotation of the polar decomposition of `f`, in at most
/// `max_iterations` steps, starting from `q` (the warm start), and returns the
/// rotation with `Rᵀ F` for it.
///
/// Müller et al.'s step `ω = τ / |tr(Rᵀ F)|` (`τ = Σ_k r_k × f_k`) converges from any
/// start but only linearly near the answer (the error shrinks by about 1/3 a step,
/// since it replaces the Jacobian `tr(A) I − A` of `τ`, `A = sym(Rᵀ F)`, by
/// `tr(A) I`). Once its step is below [`NEWTON_RANGE`] and that Jacobian is
/// positive definite (true near a non-inverted polar rotation, whose pairwise sums
/// of stretches `s_i + s_j` are its eigenvalues), the exact Newton step
/// `ω = (tr(A) I − A)⁻¹ τ` (in the element frame) is taken instead: quadratic
/// convergence, and better. (At the polar rotation `A = S`; an error `e` gives
/// `A = exp([e]×) S`, whose `τ` is `(tr(S) I − S) e − ½ e × S e + O(|e|³)`, and the
/// Jacobian read at `A` rather than at `S` is `tr(S) I − S − ½ [e]× S + ½ S [e]×`,
/// whose product with `e` carries the same `−½ e × S e`: the second-order terms
/// cancel and the step leaves an error of order `|e|³`.)
///
/// Cost, which every element pays every tick: the loop's test comes before any
/// update, so a warm start that is already exact costs one quaternion to matrix
/// conversion, one `Rᵀ F` and one 3×3 solve, and `Rᵀ F` is handed back for the
/// stress. The Newton step is solved by the adjugate (no square root; the test for
/// a long step compares squares) and turns `q` by the Cayley rotation `(1, ω/2)`,
/// of angle `2 atan(|ω|/2) = |ω| − |ω|³/12 + …`: no `sin`/`cos`, and an error of
/// `|ω|³/12` against the exponential, below the Newton step's own `O(|ω|²)`, so
/// convergence stays quadratic; the product is normalised once (one square root).
/// A Newton step under [`LAST_STEP`] ends the iteration. Müller's long steps keep
/// the exponential map.
#[inline]
pub fn polar(f: &Matrix3<f64>, q: &mut UnitQuaternion<f64>, max_iterations: u32) -> Polar {
    // The guard ε keeps the quotient finite for F = 0; it is negligible against
    // |Σ r_k · f_k|, which is about 3 for an element near its rest shape.
    const GUARD: f64 = 1e-9;
    let mut r = *q.to_rotation_matrix().matrix();
    let mut a = r.tr_mul(f);
    let mut k = 0;
    while k < max_iterations {
        // τ in the element frame: Σ_k e_k × a_k, the axial vector of A − Aᵀ.
        let torque = Vector3::new(a.m32 - a.m23, a.m13 - a.m31, a.m21 - a.m12);
        let trace = a.trace();
        let reach = trace.abs() + GUARD;
        // |Müller's step| < NEWTON_RANGE, compared without the division.
        let newton = if torque.norm_squared() < (NEWTON_RANGE * reach).powi(2) {
            newton_step(&a, trace, &torque)
        } else {
            None
        };
        let omega = newton.unwrap_or_else(|| torque / reach);
        // |R ω| = |ω|: the angle reads the same in either frame.
        let angle_squared = omega.norm_squared();
        if !angle_squared.is_finite() || angle_squared < ANGLE_TOLERANCE * ANGLE_TOLERANCE {
            // Converged, or non-finite input (keep the last good rotation).
            return Polar {
                r,
                a,
                iterations: k,
            };
        }
        k += 1;
        // R ← exp([R ω]×) R = R exp([ω]×): the turn is applied on the element side.
        match newton {
            Some(_) => {
                let (c, turned) = cayley(&omega, q.quaternion());
                r *= c;
                a = c.tr_mul(&a);
                *q = UnitQuaternion::new_unchecked(turned);
                if angle_squared < LAST_STEP * LAST_STEP {
                    break;
                }
            }
            None => {
                *q *= UnitQuaternion::from_scaled_axis(omega);
                r = *q.to_rotation_matrix().matrix();
                a = r.tr_mul(f);
            }
        }
    }
    Polar {
        r,
        a,
        iterations: k,
    }
}

/// The Cayley rotation of `ω` (angle `2 atan(|ω|/2)` about `ω`): its matrix
/// `C = I + s ([w]× + [w]×²)`, `w = ω/2`, `s = 2/(1 + |w|²)` (the matrix of the unit
/// quaternion `(1, w)/√(1 + |w|²)`), and the unit quaternion `p (1, w)` normalised,
/// for a unit `p`.
///
/// The next Newton step needs only `Cᵀ A`, so the quaternion is off its path; both
/// quotients are series in `t = |w|²` while `t < 1e-4` (a turn under 0.02 rad,
/// every step of a warm start): `s/2 = 1 − t + t² − t³` to `t⁴ < 1e-16`, and the
/// quaternion's norm is set by the Newton iteration for `1/√n` around 1,
/// `1 − δ/2 + 3δ²/8 − 5δ³/16` with `δ = |p (1, w)|² − 1`, to `35δ⁴/128 < 1e-16`:
/// it also removes the round-off a stored rotation's norm gathers tick after tick.
/// Larger turns divide and take the square root.
#[inline]
fn cayley(omega: &Vector3<f64>, p: &Quaternion<f64>) -> (Matrix3<f64>, Quaternion<f64>) {
    const SERIES: f64 = 1e-4;
    let w = 0.5 * omega;
    let t = w.norm_squared();
    let s = if t < SERIES {
        // 1 − t + t² − t³ = (1 − t)(1 + t²): two short chains instead of one long.
        2.0 * (1.0 - t) * (1.0 + t * t)
    } else {
        2.0 / (1.0 + t)
    };
    let ww = w * w.transpose();
    let mut c = (w.cross_matrix() + ww) * s;
    let diagonal = 1.0 - s * t;
    c.m11 += diagonal;
    c.m22 += diagonal;
    c.m33 += diagonal;
    let turned = p * Quaternion::from_parts(1.0, w);
    let delta = turned.norm_squared() - 1.0;
    let scale = if delta.abs() < SERIES {
        1.0 - delta * (0.5 - delta * (0.375 - 0.3125 * delta))
    } else {
        1.0 / (1.0 + delta).sqrt()
    };
    (c, turned * scale)
}

/// `(tr(A) I − sym(A))⁻¹ τ` when that matrix is positive definite (its leading
/// minors are positive, Sylvester), by the adjugate; `None` otherwise.
#[inline]
fn newton_step(a: &Matrix3<f64>, trace: f64, torque: &Vector3<f64>) -> Option<Vector3<f64>> {
    let (j00, j11, j22) = (trace - a.m11, trace - a.m22, trace - a.m33);
    let j01 = -0.5 * (a.m12 + a.m21);
    let j02 = -0.5 * (a.m13 + a.m31);
    let j12 = -0.5 * (a.m23 + a.m32);
    let c00 = j11 * j22 - j12 * j12;
    let c01 = j02 * j12 - j01 * j22;
    let c02 = j01 * j12 - j02 * j11;
    let c11 = j00 * j22 - j02 * j02;
    let c12 = j01 * j02 - j00 * j12;
    let c22 = j00 * j11 - j01 * j01;
    let det = j00 * c00 + j01 * c01 + j02 * c02;
    if !(j00 > 0.0 && c22 > 0.0 && det > 0.0) {
        return None;
    }
    let t = torque;
    // The reciprocal is formed beside the adjugate's product, not after it.
    let inverse = 1.0 / det;
    Some(
        Vector3::new(
            c00 * t.x + c01 * t.y + c02 * t.z,
            c01 * t.x + c11 * t.y + c12 * t.z,
            c02 * t.x + c12 * t.y + c22 * t.z,
        ) * inverse,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    #[test]
    fn polar_rotation_of_a_stretched_rotation_is_the_rotation() {
        // F = R S with S symmetric positive definite: the extraction returns R.
        let s = Matrix3::new(1.2, 0.1, 0.0, 0.1, 0.9, -0.05, 0.0, -0.05, 1.1);
        for axis in [Vector3::x(), Vector3::new(1.0, 2.0, -0.5), Vector3::z()] {
            for angle in [0.0, 0.3, std::f64::consts::FRAC_PI_2, 2.5, 3.1] {
                let r = *Rotation3::new(axis.normalize() * angle).matrix();
                let got = cold_rotation(&(r * s));
                assert!((got - r).norm() <= 1e-10, "angle {angle}: {got} vs {r}");
            }
        }
    }

    #[test]
    fn inverted_element_gives_a_proper_rotation_with_symmetric_stretch() {
        // det F < 0: the result is a rotation (det +1) and Rᵀ F is symmetric, the
        // Irving et al. factor U diag(1, 1, −1) Vᵀ.
        let r0 = *Rotation3::new(Vector3::new(0.2, -0.4, 0.7)).matrix();
        let f = r0 * Matrix3::from_diagonal(&Vector3::new(1.1, 0.9, -0.2));
        let r = cold_rotation(&f);
        assert!((r.determinant() - 1.0).abs() <= 1e-12);
        assert!((r.transpose() * r - Matrix3::identity()).norm() <= 1e-12);
        let s = r.transpose() * f;
        assert!((s - s.transpose()).norm() <= 1e-10, "{s}");
        // The flip lands on the smallest singular value: tr(Rᵀ F) = 1.1 + 0.9 − 0.2.
        assert!((s.trace() - 1.8).abs() <= 1e-10);
    }

    #[test]
    fn degenerate_and_collapsed_elements_keep_a_finite_rotation() {
        let flat = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0);
        let r = cold_rotation(&flat);
        assert!((r.determinant() - 1.0).abs() <= 1e-12 && r.iter().all(|v| v.is_finite()));
        let mut q = UnitQuaternion::from_scaled_axis(Vector3::new(0.1, 0.2, 0.3));
        let before = q;
        extract_rotation(&Matrix3::zeros(), &mut q, COLD_ITERATIONS);
        assert_eq!(q, before);
        extract_rotation(&Matrix3::from_element(f64::NAN), &mut q, COLD_ITERATIONS);
        assert_eq!(q, before);
    }

    #[test]
    fn a_warm_start_lands_on_the_polar_rotation_in_two_steps() {
        // F = R₀ S, warm start R₀ turned by δ about a skew axis: what polar returns is
        // R₀ to 1e-14 rad (a last Newton step under LAST_STEP leaves about |ω|³/4, at
        // most 2e-15; with a last step of 1e-4 this would fail), and a tick-sized
        // δ ≤ 1e-4 takes at most two steps.
        let stretches = [
            Matrix3::identity(),
            Matrix3::new(1.2, 0.1, 0.0, 0.1, 0.9, -0.05, 0.0, -0.05, 1.1),
            Matrix3::new(0.5, 0.05, 0.1, 0.05, 0.6, 0.0, 0.1, 0.0, 1.8),
            Matrix3::from_diagonal(&Vector3::new(2.0, 0.5, 1.0)),
        ];
        let r0 = Rotation3::new(Vector3::new(0.3, -1.2, 0.8));
        let axis = Vector3::new(1.0, 2.0, -0.7).normalize();
        for s in &stretches {
            let f = r0.matrix() * s;
            for delta in [0.25, 1e-2, 1e-3, 1e-4, 2e-5, 1e-5, 1e-7, 1e-9] {
                let mut q = UnitQuaternion::from_rotation_matrix(&r0)
                    * UnitQuaternion::from_scaled_axis(axis * delta);
                let p = polar(&f, &mut q, WARM_ITERATIONS);
                // |R − R₀|_F = 2√2 sin(θ/2) ≈ √2 θ for the angle θ between them.
                let off = (q.to_rotation_matrix().matrix() - r0.matrix()).norm()
                    / std::f64::consts::SQRT_2;
                assert!(off <= 1e-14, "S {s}, δ {delta}: {off:e} rad off");
                // R, Rᵀ F and the stored q, turned separately, agree to round-off
                // (a few ulps a step).
                assert!((p.r - q.to_rotation_matrix().matrix()).norm() <= 4e-15);
                assert!((p.r.transpose() * p.r - Matrix3::identity()).norm() <= 4e-15);
                assert!((p.a - p.r.transpose() * f).norm() <= 1e-15 * f.norm());
                if delta <= 1e-4 {
                    assert!(
                        p.iterations <= 2,
                        "S {s}, δ {delta}: {} steps",
                        p.iterations
                    );
                }
            }
        }
    }
}
