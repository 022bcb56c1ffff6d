//! Properties over random edges and poses: every crossing found is valid, and one is
//! found where there is one.

use super::*;
use proptest::prelude::*;

fn arb_vec(r: f64) -> impl Strategy<Value = Vector3<f64>> {
    prop::array::uniform3(-r..r).prop_map(Vector3::from)
}

fn arb_unit() -> impl Strategy<Value = Unit<Vector3<f64>>> {
    arb_vec(1.0)
        .prop_filter("not too short", |v| v.norm() > 0.1)
        .prop_map(Unit::new_normalize)
}

fn arb_pose() -> impl Strategy<Value = InstrumentPose> {
    (arb_vec(0.2), arb_unit()).prop_map(|(p, z)| InstrumentPose::new(Point3::from(p), z))
}

/// An edge built to cross the axis of `pose` at `(t, α, β)`, with random motion.
fn constructed(
    pose: &InstrumentPose,
    (t, alpha, beta): (f64, f64, f64),
    dir: Vector3<f64>,
    da: Vector3<f64>,
    db: Vector3<f64>,
) -> MovingEdge {
    let x = pose.point_at(beta);
    MovingEdge::new(
        x - dir * alpha - da * t,
        x + dir * (1.0 - alpha) - db * t,
        da,
        db,
    )
}

/// A returned crossing is a solution of eq. 2 within the stated tolerance.
fn check_valid(e: &MovingEdge, pose: &InstrumentPose, length: f64, c: &Crossing) {
    let tol = TOUCH_RELATIVE * e.scale();
    assert!(c.t > 0.0 && c.t <= 1.0, "{c:?}");
    assert!((0.0..=1.0).contains(&c.alpha), "{c:?}");
    assert!((0.0..=length).contains(&c.beta), "{c:?}");
    let r = e.point_at(c.t, c.alpha) - pose.tip;
    let height = r.dot(&pose.axis);
    let radial = (r - pose.axis.into_inner() * height).norm();
    assert!(
        radial <= tol,
        "{radial:e} off the axis line (tol {tol:e}): {c:?}"
    );
    assert!(
        (height - c.beta).abs() <= tol,
        "height {height} vs β: {c:?}"
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    /// Random edges and motions near the axis: any crossing returned is a real one.
    #[test]
    fn any_crossing_found_is_on_the_axis_segment(
        pose in arb_pose(), a in arb_vec(0.3), b in arb_vec(0.3),
        da in arb_vec(0.4), db in arb_vec(0.4), length in 0.05..0.5f64,
    ) {
        let e = MovingEdge::new(pose.tip + a, pose.tip + b, da, db);
        if let Some(c) = edge_crossing(&e, &pose, length) {
            check_valid(&e, &pose, length, &c);
        }
    }

    /// Edges built to cross at a known (t, α, β): whenever s changes sign over the
    /// step (so that root is its only one in [0, 1]), the crossing is found, at the
    /// constructed values; whatever is found is valid.
    #[test]
    fn a_single_sign_change_at_a_valid_point_is_found(
        pose in arb_pose(), t in 0.02..0.98f64, alpha in 0.02..0.98f64, beta_frac in 0.02..0.98f64,
        dir in arb_vec(0.05), da in arb_vec(0.05), db in arb_vec(0.05), length in 0.05..0.3f64,
    ) {
        let beta = beta_frac * length;
        let e = constructed(&pose, (t, alpha, beta), dir, da, db);
        let found = edge_crossing(&e, &pose, length);
        if let Some(c) = &found {
            check_valid(&e, &pose, length, c);
        }
        let scale = e.scale();
        let shadow = pose.across(&dir).norm();
        let (s0, s1) = (s_at(&e, &pose, 0.0), s_at(&e, &pose, 1.0));
        if shadow <= 1e-3 * scale || !(s0 * s1 < 0.0 && s0.abs().min(s1.abs()) > 1e-9 * scale * scale) {
            return Ok(());
        }
        let c = found.expect("a single valid sign change must be found");
        prop_assert_eq!(c.kind, CrossingKind::Transversal);
        prop_assert!((c.t - t).abs() < 1e-9, "t {} vs {}", c.t, t);
        prop_assert!((c.alpha - alpha).abs() < 1e-6, "α {} vs {}", c.alpha, alpha);
        prop_assert!((c.beta - beta).abs() < 1e-6 * scale, "β {} vs {}", c.beta, beta);
        // Swapping the ends gives the same crossing with α ↦ 1 − α.
        let r = edge_crossing(&e.reversed(), &pose, length).expect("reversed");
        prop_assert!((r.t - c.t).abs() < 1e-12 && (r.alpha - (1.0 - c.alpha)).abs() < 1e-9);
    }

    /// Nearly degenerate configurations — an edge in (or within 10⁻ᵏ of) a plane
    /// containing the axis line, or nearly parallel to the axis — never give an
    /// invalid crossing, whichever branch decides them.
    #[test]
    fn near_degenerate_edges_give_only_valid_crossings(
        pose in arb_pose(), xa in -0.3..0.3f64, xb in -0.3..0.3f64, za in -0.1..0.4f64, zb in -0.1..0.4f64,
        dxa in -0.5..0.5f64, dxb in -0.5..0.5f64, dza in -0.2..0.2f64, dzb in -0.2..0.2f64,
        noise in arb_vec(1.0), k in 4.0..16.0f64, parallel in any::<bool>(), length in 0.05..0.3f64,
    ) {
        let z = pose.axis.into_inner();
        let e1 = perpendicular(&z).into_inner();
        let eps = 10f64.powf(-k);
        let (xb, dxb) = if parallel { (xa, dxa) } else { (xb, dxb) };
        let a = pose.tip + e1 * xa + z * za;
        let b = pose.tip + e1 * xb + z * zb + noise * eps;
        let e = MovingEdge::new(a, b, e1 * dxa + z * dza, e1 * dxb + z * dzb + noise.yzx() * eps);
        if let Some(c) = edge_crossing(&e, &pose, length) {
            check_valid(&e, &pose, length, &c);
        }
    }

    /// Eq. 6 as derived: holding each end just before the crossing if it drives
    /// the edge toward the axis, just after otherwise, keeps the edge on the side
    /// it came from (to first order, which the step `h` makes dominant).
    #[test]
    fn closer_to_axis_keeps_the_edge_on_its_side(
        pose in arb_pose(), t in 0.05..0.95f64, alpha in 0.05..0.95f64, beta_frac in 0.05..0.95f64,
        dir in arb_vec(0.05), da in arb_vec(0.05), db in arb_vec(0.05),
    ) {
        let length = 0.2;
        let e = constructed(&pose, (t, alpha, beta_frac * length), dir, da, db);
        let Some(c) = edge_crossing(&e, &pose, length) else { return Ok(()) };
        if c.kind != CrossingKind::Transversal {
            return Ok(());
        }
        let z = pose.axis.into_inner();
        let kappa_a = z.dot(&e.delta_a.cross(&(e.b_at(c.t) - pose.tip))).abs();
        let kappa_b = z.dot(&(e.a_at(c.t) - pose.tip).cross(&e.delta_b)).abs();
        let c2 = z.dot(&e.delta_a.cross(&e.delta_b)).abs();
        let rate = (kappa_a + kappa_b).max(1e-300);
        let h = 1e-4;
        // First order dominates the bilinear term, and rounding.
        if !(c2 * h < 1e-2 * rate && rate > 1e-6 * e.scale() * e.scale()) {
            return Ok(());
        }
        let sign_before = -(s_at(&e, &pose, c.t + 1e-7) - s_at(&e, &pose, c.t - 1e-7)).signum();
        let ta = if closer_to_axis(&e, EdgeEnd::A, &c, &pose) { c.t - h } else { c.t + h };
        let tb = if closer_to_axis(&e, EdgeEnd::B, &c, &pose) { c.t - h } else { c.t + h };
        let s = z.dot(&(e.a_at(ta) - pose.tip).cross(&(e.b_at(tb) - pose.tip)));
        prop_assert!(s * sign_before > 0.0, "s = {s:e} on the wrong side");
    }
}
