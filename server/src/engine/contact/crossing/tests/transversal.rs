//! Generic (transversal) crossings: an edge sweeping across the axis segment, and
//! what is not a crossing.

use super::*;

#[test]
fn translating_edge_sweeps_across_the_shaft() {
    // y = 1 − 2t: the edge is over the axis at t = 0.5, its middle at height 0.5.
    let e = edge(
        [-1.0, 1.0, 0.3],
        [1.0, 1.0, 0.7],
        [0.0, -2.0, 0.0],
        [0.0, -2.0, 0.0],
    );
    let c = crossing_everywhere(&e, 1.0);
    assert_crossing(c, 0.5, 0.5, 0.5, CrossingKind::Transversal);
    // Swapping the ends swaps α.
    let r = edge_crossing(&e.reversed(), &z_pose(), 1.0);
    assert_crossing(r, 0.5, 0.5, 0.5, CrossingKind::Transversal);
    // The point found is on the axis.
    let c = c.unwrap();
    assert!((e.point_at(c.t, c.alpha) - Point3::new(0.0, 0.0, 0.5)).norm() < 1e-15);
}

#[test]
fn off_centre_crossing_keeps_the_sign_of_alpha() {
    // Edge from x = −0.5 to x = 1.5: it meets the axis a quarter of the way along.
    // A ratio of norms (printed eq. 4) cannot tell α = 0.25 from the mirrored edge
    // x ∈ [0.5, 2.5] (α = −0.25), which must be rejected.
    let e = edge(
        [-0.5, 1.0, 0.2],
        [1.5, 1.0, 0.6],
        [0.0, -2.0, 0.0],
        [0.0, -2.0, 0.0],
    );
    assert_crossing(
        crossing_everywhere(&e, 1.0),
        0.5,
        0.25,
        0.3,
        CrossingKind::Transversal,
    );
    let beside = edge(
        [0.5, 1.0, 0.2],
        [2.5, 1.0, 0.6],
        [0.0, -2.0, 0.0],
        [0.0, -2.0, 0.0],
    );
    assert_eq!(crossing_everywhere(&beside, 1.0), None);
}

#[test]
fn rotating_edge_crosses_at_the_constructed_instant() {
    // Built backwards from the crossing: at t = 0.25 the point α = 0.75 of the edge
    // is at P + 0.2 Z.
    let (t, alpha, beta) = (0.25, 0.75, 0.2);
    let x = Point3::new(0.0, 0.0, beta);
    let dir = Vector3::new(1.0, 0.5, 0.3);
    let (da, db) = (Vector3::new(0.2, -1.0, 0.1), Vector3::new(-0.3, -0.8, 0.0));
    let a = x - dir * alpha - da * t;
    let b = x + dir * (1.0 - alpha) - db * t;
    let e = MovingEdge::new(a, b, da, db);
    assert!(cross_free_of_second_root(&e));
    let c = crossing_everywhere(&e, 0.5).expect("crossing");
    assert!(
        (c.t - t).abs() < 1e-14 && (c.alpha - alpha).abs() < 1e-14 && (c.beta - beta).abs() < 1e-14,
        "{c:?}"
    );
}

/// s changes sign over [0, 1] (so exactly one root there).
fn cross_free_of_second_root(e: &MovingEdge) -> bool {
    s_at(e, &z_pose(), 0.0) * s_at(e, &z_pose(), 1.0) < 0.0
}

#[test]
fn passing_beyond_the_tip_or_beyond_the_shaft_is_not_a_crossing() {
    // The same sweep as above, lowered: it meets the axis line at β = −0.5.
    let e = edge(
        [-1.0, 1.0, -0.7],
        [1.0, 1.0, -0.3],
        [0.0, -2.0, 0.0],
        [0.0, -2.0, 0.0],
    );
    assert_eq!(crossing_everywhere(&e, 1.0), None);
    // At β = 0.5 with a shaft of 0.4: beyond its end.
    let e = edge(
        [-1.0, 1.0, 0.3],
        [1.0, 1.0, 0.7],
        [0.0, -2.0, 0.0],
        [0.0, -2.0, 0.0],
    );
    assert_eq!(crossing_everywhere(&e, 0.4), None);
    // Exactly at the ends of the shaft: still on it.
    assert_crossing(
        edge_crossing(&e, &z_pose(), 0.5),
        0.5,
        0.5,
        0.5,
        CrossingKind::Transversal,
    );
    let at_tip = edge(
        [-1.0, 1.0, -0.2],
        [1.0, 1.0, 0.2],
        [0.0, -2.0, 0.0],
        [0.0, -2.0, 0.0],
    );
    assert_crossing(
        edge_crossing(&at_tip, &z_pose(), 0.5),
        0.5,
        0.5,
        0.0,
        CrossingKind::Transversal,
    );
}

/// The edge `a(t) = m(t) − h(t)`, `b(t) = m(t) + h(t)` with midpoint
/// `m = (t − ½, offset)` and half-vector `h = (1, t − ½)`: `s = 2 m × h =
/// 2(t − ½)² − 2·offset`, a double root at ½ for offset 0 and two roots
/// `½ ± √offset` for offset > 0. Heights `z(t) = z0 + dz·t` at both ends.
fn rocking_edge(offset: f64, z0: f64, dz: f64) -> MovingEdge {
    edge(
        [-1.5, offset + 0.5, z0],
        [0.5, offset - 0.5, z0],
        [1.0, -1.0, dz],
        [1.0, 1.0, dz],
    )
}

#[test]
fn crossing_and_coming_back_within_the_step_is_not_colliding() {
    let e = rocking_edge(0.05, 0.3, 0.0);
    // Two sign changes of s inside the step, both on the shaft.
    let r = 0.05f64.sqrt();
    for t in [0.5 - r, 0.5 + r] {
        assert!(s_at(&e, &z_pose(), t).abs() < 1e-15);
    }
    assert_eq!(crossing_everywhere(&e, 1.0), None);
}

#[test]
fn one_crossing_on_the_shaft_and_one_beyond_it_is_colliding() {
    // Heights 1.5 − 2t: the first root is at β ≈ 0.947, the second at β ≈ 0.053.
    let e = rocking_edge(0.05, 1.5, -2.0);
    assert_eq!(crossing_everywhere(&e, 1.0), None, "both on a shaft of 1");
    let c = crossing_everywhere(&e, 0.5).expect("only the second is on a shaft of 0.5");
    let t2 = 0.5 + 0.05f64.sqrt();
    assert!(
        (c.t - t2).abs() < 1e-14 && (c.beta - (1.5 - 2.0 * t2)).abs() < 1e-14,
        "{c:?}"
    );
    assert!((e.point_at(c.t, c.alpha) - Point3::new(0.0, 0.0, c.beta)).norm() < 1e-14);
}

#[test]
fn tangent_contact_is_not_a_crossing() {
    // s = 2(t − ½)²: the edge touches the axis at t = ½ (α = ½) without changing side.
    let e = rocking_edge(0.0, 0.3, 0.0);
    assert_eq!(s_at(&e, &z_pose(), 0.5), 0.0);
    assert!((e.point_at(0.5, 0.5) - Point3::new(0.0, 0.0, 0.3)).norm() < 1e-15);
    assert_eq!(crossing_everywhere(&e, 1.0), None);
    // Nor is passing just beside it (no real root).
    assert_eq!(
        crossing_everywhere(&rocking_edge(-0.01, 0.3, 0.0), 1.0),
        None
    );
}

#[test]
fn linear_and_constant_cases() {
    // Translation: c₂ = Δa × Δa = 0 exactly, one linear root (tested above); a
    // translation along the edge's own direction keeps s constant: c₂ = c₁ = 0.
    let e = edge(
        [-1.0, 1.0, 0.3],
        [1.0, 1.0, 0.3],
        [5.0, 0.0, 0.2],
        [5.0, 0.0, 0.2],
    );
    assert_eq!(crossing_everywhere(&e, 1.0), None);
    let e = edge(
        [-1.0, 1.0, 0.3],
        [1.0, 1.0, 0.7],
        [0.0, -0.4, 0.0],
        [0.0, -0.4, 0.0],
    );
    assert_eq!(
        crossing_everywhere(&e, 1.0),
        None,
        "the root t = 2.5 is after the step"
    );
}

#[test]
fn an_edge_that_does_not_move_never_crosses() {
    // Even one lying across the axis.
    let e = edge([-1.0, 0.0, 0.3], [1.0, 0.0, 0.3], [0.0; 3], [0.0; 3]);
    assert_eq!(crossing_everywhere(&e, 1.0), None);
    let e = edge([-1.0, 1.0, 0.3], [1.0, 1.0, 0.3], [0.0; 3], [0.0; 3]);
    assert_eq!(crossing_everywhere(&e, 1.0), None);
    // Motion below the touching tolerance counts as none.
    let e = edge(
        [-1.0, 1e-12, 0.3],
        [1.0, 1e-12, 0.3],
        [0.0, -2e-12, 0.0],
        [0.0, -2e-12, 0.0],
    );
    assert_eq!(edge_crossing(&e, &z_pose(), 1.0), None);
}

#[test]
fn endpoint_passing_exactly_through_the_axis() {
    // A moves along x through the axis at t = ½; B stays off the axis line.
    let e = edge(
        [-1.0, 0.0, 0.3],
        [-1.0, 1.0, 0.3],
        [2.0, 0.0, 0.0],
        [0.0; 3],
    );
    assert_crossing(
        crossing_everywhere(&e, 1.0),
        0.5,
        0.0,
        0.3,
        CrossingKind::Transversal,
    );
    assert_crossing(
        edge_crossing(&e.reversed(), &z_pose(), 1.0),
        0.5,
        1.0,
        0.3,
        CrossingKind::Transversal,
    );
    // Starting on the axis and leaving: the contact was the previous step's.
    let e = edge([0.0, 0.0, 0.3], [-1.0, 1.0, 0.3], [1.0, 0.0, 0.0], [0.0; 3]);
    assert_eq!(crossing_everywhere(&e, 1.0), None);
    // Arriving on the axis at the end of the step.
    let e = edge(
        [-1.0, 0.0, 0.3],
        [-1.0, 1.0, 0.3],
        [1.0, 0.0, 0.0],
        [0.0; 3],
    );
    assert_crossing(
        crossing_everywhere(&e, 1.0),
        1.0,
        0.0,
        0.3,
        CrossingKind::Transversal,
    );
}

#[test]
fn edge_parallel_to_the_axis_at_one_instant_is_not_a_spurious_crossing() {
    // d(t) = (2 − 4t, 0): the shadow collapses to a point at t = ½, making s = 0
    // there, but that point is at (1, 1), not on the axis.
    let e = edge(
        [0.0, 1.0, 0.0],
        [2.0, 1.0, 0.5],
        [2.0, 0.0, 0.0],
        [-2.0, 0.0, 0.0],
    );
    assert_eq!(s_at(&e, &z_pose(), 0.5), 0.0);
    assert_eq!(crossing_everywhere(&e, 1.0), None);
}
