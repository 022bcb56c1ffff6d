//! Eq. 6: which end of a colliding edge is closer to the axis, as printed and as
//! corrected.

use super::*;

/// The printed eq. 6, `(ΔA ∧ (Z ∧ AB))·(AP ∧ (Z ∧ AB))`.
fn printed_eq6(e: &MovingEdge, pose: &InstrumentPose) -> f64 {
    let n = pose.axis.cross(&(e.b - e.a));
    e.delta_a.cross(&n).dot(&(pose.tip - e.a).cross(&n))
}

/// The corrected eq. 6, `(ΔA·(Z ∧ AB))(AP·(Z ∧ AB))`.
fn corrected_eq6(e: &MovingEdge, pose: &InstrumentPose) -> f64 {
    let n = pose.axis.cross(&(e.b - e.a));
    e.delta_a.dot(&n) * (pose.tip - e.a).dot(&n)
}

#[test]
fn eq6_as_printed_is_wrong_and_corrected_agrees() {
    let pose = z_pose();
    // The edge moves straight at the axis, along the common normal.
    let e = edge(
        [-1.0, 1.0, 0.5],
        [1.0, 1.0, 0.5],
        [0.0, -2.0, 0.0],
        [0.0, -2.0, 0.0],
    );
    let c = edge_crossing(&e, &pose, 1.0).unwrap();
    assert!(closer_to_axis(&e, EdgeEnd::A, &c, &pose));
    assert!(closer_to_axis(&e, EdgeEnd::B, &c, &pose));
    assert!(corrected_eq6(&e, &pose) > 0.0);
    assert_eq!(
        printed_eq6(&e, &pose),
        0.0,
        "printed eq. 6 sees no approach"
    );
    // Sliding along its own direction (no approach at all): the printed form
    // calls it "closer", the corrected one does not.
    let slide = edge([-1.0, 1.0, 0.5], [1.0, 1.0, 0.5], [1.0, 0.0, 0.0], [0.0; 3]);
    assert!(printed_eq6(&slide, &pose) > 0.0);
    assert_eq!(corrected_eq6(&slide, &pose), 0.0);
}

#[test]
fn only_the_moving_end_drives_a_pivoting_edge() {
    let pose = z_pose();
    // B still at (1, 1); A swings from (−1, 1) to (−1, −3): the edge is over the
    // axis when A is at (−1, −1), at t = ½.
    let e = edge(
        [-1.0, 1.0, 0.5],
        [1.0, 1.0, 0.5],
        [0.0, -4.0, 0.0],
        [0.0; 3],
    );
    let c = edge_crossing(&e, &pose, 1.0).unwrap();
    assert!((c.t - 0.5).abs() < 1e-15);
    assert!(closer_to_axis(&e, EdgeEnd::A, &c, &pose));
    assert!(!closer_to_axis(&e, EdgeEnd::B, &c, &pose));
    // A backs off slowly while B comes on fast: B drives, A does not.
    let e = edge(
        [-1.0, 1.0, 0.5],
        [1.0, 1.0, 0.5],
        [0.0, 0.2, 0.0],
        [0.0, -4.0, 0.0],
    );
    let c = edge_crossing(&e, &pose, 1.0).unwrap();
    assert!(!closer_to_axis(&e, EdgeEnd::A, &c, &pose));
    assert!(closer_to_axis(&e, EdgeEnd::B, &c, &pose));
}

#[test]
fn in_plane_ends_moving_toward_the_contact_are_closer() {
    let pose = z_pose();
    let e = edge(
        [-2.0, 0.0, 0.5],
        [-1.0, 0.0, 0.8],
        [1.5, 0.0, 0.0],
        [1.5, 0.0, 0.0],
    );
    let c = edge_crossing(&e, &pose, 1.0).unwrap();
    assert!(closer_to_axis(&e, EdgeEnd::A, &c, &pose));
    assert!(closer_to_axis(&e, EdgeEnd::B, &c, &pose));
    let e = edge(
        [0.0, 0.0, -0.5],
        [0.0, 0.0, -0.2],
        [0.0, 0.0, 0.4],
        [0.0; 3],
    );
    let e = MovingEdge {
        delta_b: e.delta_a,
        ..e
    };
    let c = edge_crossing(&e, &pose, 1.0).unwrap();
    assert_eq!(c.kind, CrossingKind::AlongAxis);
    assert!(closer_to_axis(&e, EdgeEnd::B, &c, &pose));
}
