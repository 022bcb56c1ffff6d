//! The instrument's pose and the rigid motion between two poses (paper §2.2, eq. 1).
//!
//! The contact stage looks at the mesh from the instrument: the previous positions of
//! the mesh vertices are carried along with the instrument by the rigid motion `R` that
//! takes the instrument from its previous pose `{Z_old, P_old}` to its current pose
//! `{Z, P}`, so that in this frame the instrument is still and only the mesh moves
//! (`A = R(A_old)`, `ΔA = A_new − R(A_old)`, paper §2.2).
//!
//! Eq. 1 fixes `R` by three conditions:
//!
//! ```text
//! (a) R(Z_old) = Z            the axis turns onto the new axis
//! (b) R(P_old) = P            the tip moves onto the new tip
//! (c) R(Z_old × Z) = Z_old × Z  the rotation is about Z_old × Z
//! ```
//!
//! (a) and (c) make the rotation part the *minimal* rotation taking `Z_old` to `Z`: the
//! rotation about `k = Z_old × Z / |Z_old × Z|` by the angle `θ` between the two axes.
//! Rolling of the instrument about its own axis is not part of the pose (an instrument
//! is a cylinder, symmetric about its axis), so eq. 1 leaves none in `R`. The
//! translation then follows from (b): `R(x) = Q (x − P_old) + P` with `Q` the rotation.

use nalgebra::{Isometry3, Point3, Quaternion, Translation3, Unit, UnitQuaternion, Vector3};

/// Where an instrument is at one instant (SI units, metres).
///
/// The instrument is the set of points within its radius `r` of the segment
/// `{P + s·Z : 0 ≤ s ≤ l}`; its radius and shaft length `l` belong to the instrument,
/// not to the pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InstrumentPose {
    /// The tip `P`, m.
    pub tip: Point3<f64>,
    /// The unit axis `Z`, pointing from the tip toward the handle.
    pub axis: Unit<Vector3<f64>>,
}

impl InstrumentPose {
    /// A pose from its tip and unit axis.
    pub fn new(tip: Point3<f64>, axis: Unit<Vector3<f64>>) -> Self {
        Self { tip, axis }
    }

    /// The pose a fraction `f` of the way to `to`: the tip on the straight line, the
    /// axis turning at constant angular speed on the great circle; exactly `self` at
    /// `f ≤ 0` and `to` at `f ≥ 1`. A half-turn has no unique great circle, so it keeps
    /// the nearer end's axis (antiparallel below a sine of 1e-9).
    pub fn lerp(&self, to: &InstrumentPose, f: f64) -> InstrumentPose {
        if f <= 0.0 {
            return *self;
        }
        if f >= 1.0 {
            return *to;
        }
        let axis = self
            .axis
            .try_slerp(&to.axis, f, 1e-9)
            .unwrap_or(if f < 0.5 { self.axis } else { to.axis });
        InstrumentPose::new(self.tip + (to.tip - self.tip) * f, axis)
    }

    /// The point of the axis at distance `s` from the tip toward the handle, `P + s·Z`.
    pub fn point_at(&self, s: f64) -> Point3<f64> {
        self.tip + self.axis.into_inner() * s
    }

    /// The part of `d` across the axis, `d − Z (Z·d)`: a move with it removed is
    /// along the axis.
    pub fn across(&self, d: &Vector3<f64>) -> Vector3<f64> {
        d - self.axis.into_inner() * self.axis.dot(d)
    }
}

/// The rigid motion `R` of eq. 1 that takes the instrument from `old` to `new`: the
/// minimal rotation taking `Z_old` to `Z` (about `Z_old × Z`), followed by the
/// translation that takes `P_old` to `P`. It maps `old.tip` to `new.tip`, `old.axis` to
/// `new.axis`, and fixes `Z_old × Z`; see [`minimal_rotation`] for the parallel and
/// antiparallel cases.
///
/// Apply it to the previous vertex positions to express them in the instrument's
/// current frame: `A = R(A_old)`.
pub fn rigid_motion(old: &InstrumentPose, new: &InstrumentPose) -> Isometry3<f64> {
    let rotation = minimal_rotation(&old.axis, &new.axis);
    // R(x) = Q x + t with R(P_old) = P  ⇒  t = P − Q P_old.
    let translation = new.tip.coords - rotation * old.tip.coords;
    Isometry3::from_parts(Translation3::from(translation), rotation)
}

/// Below this, `|u × v|` of two unit vectors (the sine of their angle) is rounding
/// noise and carries no direction: the cross product of unit vectors is computed with
/// an absolute error of a few `ε` (two rounded products and a subtraction per
/// component, plus the `±ε` by which a normalised vector misses unit length), so 8ε is
/// a safe ceiling on that noise. Below it the vectors are parallel or antiparallel to
/// working precision, and the rotation is chosen by rule instead of from the noise.
const PARALLEL_SINE: f64 = 8.0 * f64::EPSILON;

/// The minimal rotation taking unit vector `from` (`u`) to unit vector `to` (`v`):
/// about `k = u × v / |u × v|` by `θ = atan2(|u × v|, u · v)` ∈ [0, π].
///
/// Cases:
/// - `u = v` (to working precision, `|u × v| ≤ 8ε` and `u · v > 0`): the identity.
/// - `u = −v` (`|u × v| ≤ 8ε` and `u · v ≤ 0`): the axis of a minimal rotation is any
///   unit vector ⊥ `u`; we take the half-turn about `k = u × e / |u × e|`, where `e` is
///   the coordinate axis least aligned with `u` (smallest `|u_i|`, the first of x, y, z
///   on ties). The choice depends only on `u`, so it is deterministic, and `|u × e|` ≥
///   √(2/3), so `k` is accurate. The quaternion is built exactly as `(0, k)`.
/// - otherwise, including nearly (anti)parallel: nothing is divided by a small sine.
///   The angle comes from `atan2`, accurate over all of [0, π] (unlike `acos(u · v)`
///   near 0 and π, or Rodrigues' `[w]×² / (1 + u · v)` near π). The axis is `u × v`
///   with its rounding component along `u` removed before normalising, so that `k ⊥ u`
///   exactly to working precision: near θ = π the direction of `u × v` carries a
///   relative error ~ε / sin θ, and a `k` not ⊥ `u` would then miss `v` by that much;
///   with `k ⊥ u`, `R u = cos θ u + sin θ (k × u)`, whose error is sin θ times the
///   direction error of `k`, i.e. a few ε.
pub fn minimal_rotation(from: &Unit<Vector3<f64>>, to: &Unit<Vector3<f64>>) -> UnitQuaternion<f64> {
    let u = from.into_inner();
    let v = to.into_inner();
    let cos = u.dot(&v);
    let w = u.cross(&v);
    let sin = w.norm();
    // The component of w along u is pure rounding (u × v ⊥ u exactly); drop it.
    let k = w - u * u.dot(&w);
    let k_norm = k.norm();
    if sin <= PARALLEL_SINE || k_norm <= PARALLEL_SINE {
        if cos > 0.0 {
            UnitQuaternion::identity()
        } else {
            half_turn(&perpendicular(&u))
        }
    } else {
        let axis = Unit::new_unchecked(k / k_norm);
        UnitQuaternion::from_axis_angle(&axis, sin.atan2(cos))
    }
}

/// The half-turn about unit vector `k`: the quaternion `(cos π/2, sin π/2 · k) = (0, k)`,
/// written exactly (no `cos(π/2) ≈ 6e-17`).
fn half_turn(k: &Unit<Vector3<f64>>) -> UnitQuaternion<f64> {
    UnitQuaternion::new_unchecked(Quaternion::new(0.0, k.x, k.y, k.z))
}

/// A unit vector ⊥ `u` (unit): `u × e / |u × e|` with `e` the coordinate axis of the
/// smallest `|u_i|` (the first on ties). That component is at most 1/√3, so
/// `|u × e| = √(1 − u_i²) ≥ √(2/3)` and the division is well conditioned.
pub(super) fn perpendicular(u: &Vector3<f64>) -> Unit<Vector3<f64>> {
    let abs = u.abs();
    let i = if abs.x <= abs.y && abs.x <= abs.z {
        0
    } else if abs.y <= abs.z {
        1
    } else {
        2
    };
    Unit::new_normalize(u.cross(&Vector3::ith(i, 1.0)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;
    use proptest::prelude::*;

    fn unit(x: f64, y: f64, z: f64) -> Unit<Vector3<f64>> {
        Unit::new_normalize(Vector3::new(x, y, z))
    }

    fn pose(tip: [f64; 3], axis: Unit<Vector3<f64>>) -> InstrumentPose {
        InstrumentPose::new(Point3::from(tip), axis)
    }

    fn rotation_matrix(r: &Isometry3<f64>) -> Matrix3<f64> {
        r.rotation.to_rotation_matrix().into_inner()
    }

    /// Every property eq. 1 and "rigid" ask for, to `tol`.
    fn assert_eq1(old: &InstrumentPose, new: &InstrumentPose, tol: f64) {
        let r = rigid_motion(old, new);
        let m = rotation_matrix(&r);
        // (b) tip onto tip.
        let tip_err = (r.transform_point(&old.tip) - new.tip).norm();
        assert!(
            tip_err <= tol * (1.0 + old.tip.coords.norm() + new.tip.coords.norm()),
            "tip error {tip_err:e}"
        );
        // (a) axis onto axis.
        let axis_err = (r.transform_vector(&old.axis) - new.axis.into_inner()).norm();
        assert!(axis_err <= tol, "axis error {axis_err:e}");
        // (c) Z_old × Z is fixed.
        let w = old.axis.cross(&new.axis);
        let w_err = (r.transform_vector(&w) - w).norm();
        assert!(w_err <= tol, "Z_old × Z moved by {w_err:e}");
        // Proper isometry: orthonormal, det +1.
        let ortho_err = (m.transpose() * m - Matrix3::identity()).norm();
        assert!(ortho_err <= tol, "RᵀR − I = {ortho_err:e}");
        assert!(
            (m.determinant() - 1.0).abs() <= tol,
            "det = {}",
            m.determinant()
        );
        // Minimal: the rotation angle is the angle between the axes.
        let angle = w.norm().atan2(old.axis.dot(&new.axis));
        assert!(
            (r.rotation.angle() - angle).abs() <= 1e-7,
            "angle {} vs {angle}",
            r.rotation.angle()
        );
        // The whole shaft follows: R(P_old + s Z_old) = P + s Z.
        for s in [0.0, 0.1, 0.3] {
            let err = (r.transform_point(&old.point_at(s)) - new.point_at(s)).norm();
            assert!(
                err <= tol * (1.0 + new.tip.coords.norm() + s),
                "shaft point {s}: {err:e}"
            );
        }
    }

    fn arb_unit() -> impl Strategy<Value = Unit<Vector3<f64>>> {
        prop::array::uniform3(-1.0..1.0f64)
            .prop_filter("not too short", |v| Vector3::from(*v).norm() > 0.1)
            .prop_map(|v| Unit::new_normalize(Vector3::from(v)))
    }

    fn arb_point() -> impl Strategy<Value = [f64; 3]> {
        prop::array::uniform3(-0.5..0.5f64)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        #[test]
        fn random_poses_satisfy_eq1(p0 in arb_point(), z0 in arb_unit(), p1 in arb_point(), z1 in arb_unit()) {
            assert_eq1(&pose(p0, z0), &pose(p1, z1), 1e-13);
        }

        /// Nearly antiparallel axes, down to a sine of 1e-14: R(Z_old) = Z stays
        /// accurate to a few ε (a formula dividing by 1 + cos θ or using acos would
        /// lose up to half the digits here).
        #[test]
        fn nearly_antiparallel_axes_stay_accurate(z0 in arb_unit(), e in 2.0..14.0f64, p in arb_point()) {
            let k = perpendicular(&z0);
            let z1 = UnitQuaternion::from_axis_angle(&k, std::f64::consts::PI - 10f64.powf(-e)) * z0;
            assert_eq1(&pose(p, z0), &pose([0.0; 3], z1), 1e-14);
        }

        /// Nearly parallel axes, down to a sine of 1e-14.
        #[test]
        fn nearly_parallel_axes_stay_accurate(z0 in arb_unit(), e in 2.0..14.0f64, p in arb_point()) {
            let k = perpendicular(&z0);
            let z1 = UnitQuaternion::from_axis_angle(&k, 10f64.powf(-e)) * z0;
            assert_eq1(&pose(p, z0), &pose([0.1, 0.0, 0.0], z1), 1e-14);
        }

        /// Exactly opposite axes: a half-turn about an axis ⊥ Z_old, chosen by rule.
        #[test]
        fn antiparallel_axes_give_a_half_turn(z0 in arb_unit(), p in arb_point()) {
            let z1 = Unit::new_unchecked(-z0.into_inner());
            assert_eq1(&pose(p, z0), &pose([0.0; 3], z1), 1e-14);
            let r = rigid_motion(&pose(p, z0), &pose([0.0; 3], z1));
            let (axis, angle) = r.rotation.axis_angle().expect("a half-turn has an axis");
            prop_assert!((angle - std::f64::consts::PI).abs() < 1e-12);
            prop_assert!(axis.dot(&z0).abs() < 1e-14);
            // The same inputs give the same rotation.
            prop_assert_eq!(r, rigid_motion(&pose(p, z0), &pose([0.0; 3], z1)));
        }
    }

    #[test]
    fn same_axis_is_a_pure_translation() {
        let z = unit(0.3, -0.4, 0.8);
        let old = pose([0.01, 0.02, 0.03], z);
        let new = pose([-0.05, 0.04, 0.1], z);
        let r = rigid_motion(&old, &new);
        assert_eq!(r.rotation, UnitQuaternion::identity());
        assert!((r.translation.vector - (new.tip - old.tip)).norm() < 1e-17);
        assert_eq1(&old, &new, 1e-15);
    }

    #[test]
    fn antiparallel_axis_rule_is_the_documented_one() {
        // u = z: |u_x| = |u_y| = 0 tie → e = x, k = z × x = y: a half-turn about y.
        let r = minimal_rotation(&Vector3::z_axis(), &-Vector3::z_axis());
        assert_eq!(r.quaternion().coords, Vector3::y().push(0.0));
        // u = x: e = y (first of the tie y, z), k = x × y = z.
        let r = minimal_rotation(&Vector3::x_axis(), &-Vector3::x_axis());
        assert_eq!(r.quaternion().coords, Vector3::z().push(0.0));
        assert_eq!(r * Vector3::x(), -Vector3::x());
    }

    #[test]
    fn quarter_turn_about_the_cross_product() {
        // Z_old = x, Z = y: a quarter turn about z; z itself is fixed, tip follows.
        let old = pose([1.0, 0.0, 0.0], Vector3::x_axis());
        let new = pose([0.0, 0.0, 2.0], Vector3::y_axis());
        let r = rigid_motion(&old, &new);
        assert!((r.rotation * Vector3::z() - Vector3::z()).norm() < 1e-15);
        assert!((r.rotation * Vector3::x() - Vector3::y()).norm() < 1e-15);
        // A point beside the old tip, off the axis along z, keeps its offset along z.
        let q = r.transform_point(&Point3::new(1.0, 0.0, 0.5));
        assert!((q - Point3::new(0.0, 0.0, 2.5)).norm() < 1e-15);
        assert_eq1(&old, &new, 1e-15);
    }
}
