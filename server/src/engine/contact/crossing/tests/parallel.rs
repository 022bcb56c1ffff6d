//! Edges parallel to the axis, edges in a plane containing the axis line, and the
//! instrument moving through a still edge.

use super::*;

#[test]
fn parallel_edge_sweeping_across_the_shaft() {
    let e = edge(
        [-1.0, 0.0, 0.2],
        [-1.0, 0.0, 0.5],
        [2.0, 0.0, 0.0],
        [2.0, 0.0, 0.0],
    );
    // The whole overlap [0.2, 0.5] touches; its middle is reported.
    assert_crossing(
        crossing_everywhere(&e, 1.0),
        0.5,
        0.5,
        0.35,
        CrossingKind::AlongAxis,
    );
    // Half beyond the tip: overlap [0, 0.3], middle 0.15, α = (0.15 + 0.2)/0.5.
    let e = edge(
        [-1.0, 0.0, -0.2],
        [-1.0, 0.0, 0.3],
        [2.0, 0.0, 0.0],
        [2.0, 0.0, 0.0],
    );
    let c = crossing_everywhere(&e, 1.0).unwrap();
    assert!(
        (c.t - 0.5).abs() < 1e-15 && (c.beta - 0.15).abs() < 1e-15 && (c.alpha - 0.7).abs() < 1e-15
    );
    // Entirely beyond the tip, or passing beside the axis: none.
    let e = edge(
        [-1.0, 0.0, -0.5],
        [-1.0, 0.0, -0.2],
        [2.0, 0.0, 0.0],
        [2.0, 0.0, 0.0],
    );
    assert_eq!(crossing_everywhere(&e, 1.0), None);
    let e = edge(
        [-1.0, 0.1, 0.2],
        [-1.0, 0.1, 0.5],
        [2.0, 0.0, 0.0],
        [2.0, 0.0, 0.0],
    );
    assert_eq!(crossing_everywhere(&e, 1.0), None);
    // Stopping on the axis at t = 1 ("into").
    let e = edge(
        [-1.0, 0.0, 0.2],
        [-1.0, 0.0, 0.5],
        [1.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
    );
    assert_crossing(
        crossing_everywhere(&e, 1.0),
        1.0,
        0.5,
        0.35,
        CrossingKind::AlongAxis,
    );
    // Starting on the axis: the contact was the previous step's.
    let e = edge(
        [0.0, 0.0, 0.2],
        [0.0, 0.0, 0.5],
        [1.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
    );
    assert_eq!(crossing_everywhere(&e, 1.0), None);
}

#[test]
fn edge_on_the_axis_line_sliding_onto_the_tip() {
    // Below the tip, moving up: its top end reaches the tip at t = ½.
    let e = edge(
        [0.0, 0.0, -0.5],
        [0.0, 0.0, -0.2],
        [0.0, 0.0, 0.4],
        [0.0, 0.0, 0.4],
    );
    assert_crossing(
        crossing_everywhere(&e, 1.0),
        0.5,
        1.0,
        0.0,
        CrossingKind::AlongAxis,
    );
    // Above the end of the shaft, moving down onto it.
    let e = edge(
        [0.0, 0.0, 1.5],
        [0.0, 0.0, 1.2],
        [0.0, 0.0, -0.4],
        [0.0, 0.0, -0.4],
    );
    assert_crossing(
        crossing_everywhere(&e, 1.0),
        0.5,
        1.0,
        1.0,
        CrossingKind::AlongAxis,
    );
    // Moving away, or not reaching it: none.
    let e = edge(
        [0.0, 0.0, -0.5],
        [0.0, 0.0, -0.2],
        [0.0, 0.0, -0.4],
        [0.0, 0.0, -0.4],
    );
    assert_eq!(crossing_everywhere(&e, 1.0), None);
    let e = edge(
        [0.0, 0.0, -0.5],
        [0.0, 0.0, -0.2],
        [0.0, 0.0, 0.1],
        [0.0, 0.0, 0.1],
    );
    assert_eq!(crossing_everywhere(&e, 1.0), None);
}

#[test]
fn point_edge_is_handled_as_parallel() {
    // A zero-length edge (A = B) moving through the axis.
    let e = edge(
        [-1.0, 0.0, 0.3],
        [-1.0, 0.0, 0.3],
        [2.0, 0.0, 0.0],
        [2.0, 0.0, 0.0],
    );
    assert_crossing(
        crossing_everywhere(&e, 1.0),
        0.5,
        0.5,
        0.3,
        CrossingKind::AlongAxis,
    );
}

// ---- Edges in a plane containing the axis line ----

#[test]
fn in_plane_edge_sliding_into_and_through_the_axis() {
    // In the plane y = 0: B passes over the axis at t = 2/3 at height 0.8 and the
    // edge ends straddling the axis ("into").
    let e = edge(
        [-2.0, 0.0, 0.5],
        [-1.0, 0.0, 0.8],
        [1.5, 0.0, 0.0],
        [1.5, 0.0, 0.0],
    );
    assert_crossing(
        crossing_everywhere(&e, 1.0),
        2.0 / 3.0,
        1.0,
        0.8,
        CrossingKind::InPlane,
    );
    // Faster: B at t = 1/3, then A at t = 2/3 ("through"): the first is reported.
    let e = edge(
        [-2.0, 0.0, 0.5],
        [-1.0, 0.0, 0.8],
        [3.0, 0.0, 0.0],
        [3.0, 0.0, 0.0],
    );
    assert_crossing(
        crossing_everywhere(&e, 1.0),
        1.0 / 3.0,
        1.0,
        0.8,
        CrossingKind::InPlane,
    );
    // B passes beyond the tip, A over the shaft: A's event is the crossing.
    let e = edge(
        [-2.0, 0.0, 0.5],
        [-1.0, 0.0, -0.3],
        [3.0, 0.0, 0.0],
        [3.0, 0.0, 0.0],
    );
    assert_crossing(
        crossing_everywhere(&e, 1.0),
        2.0 / 3.0,
        0.0,
        0.5,
        CrossingKind::InPlane,
    );
}

#[test]
fn in_plane_edge_that_misses_or_already_touches() {
    // Entirely beyond the tip.
    let e = edge(
        [-2.0, 0.0, -0.5],
        [-1.0, 0.0, -0.2],
        [3.0, 0.0, 0.0],
        [3.0, 0.0, 0.0],
    );
    assert_eq!(crossing_everywhere(&e, 1.0), None);
    // Staying on one side.
    let e = edge(
        [-3.0, 0.0, 0.5],
        [-2.0, 0.0, 0.5],
        [1.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
    );
    assert_eq!(crossing_everywhere(&e, 1.0), None);
    // Already across the axis at the start.
    let e = edge(
        [-1.0, 0.0, 0.5],
        [1.0, 0.0, 0.5],
        [0.5, 0.0, 0.0],
        [0.5, 0.0, 0.0],
    );
    assert_eq!(crossing_everywhere(&e, 1.0), None);
    // Across the axis all along while its plane turns about it (a = (−1, −t),
    // b = (1, t)): s ≡ 0 with a rotating plane; touching from the start.
    let e = edge(
        [-1.0, 0.0, 0.5],
        [1.0, 0.0, 0.5],
        [0.0, -1.0, 0.0],
        [0.0, 1.0, 0.0],
    );
    assert_eq!(crossing_everywhere(&e, 1.0), None);
}

#[test]
fn in_plane_endpoint_sliding_along_the_axis_line_onto_the_tip() {
    // A stays on the axis line and rises: its height reaches the tip at t = ½.
    let e = edge(
        [0.0, 0.0, -0.5],
        [1.0, 0.0, -0.5],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, 1.0],
    );
    assert_crossing(
        crossing_everywhere(&e, 1.0),
        0.5,
        0.0,
        0.0,
        CrossingKind::InPlane,
    );
}

// ---- Motion of the instrument ----

#[test]
fn instrument_sweeping_through_a_still_edge() {
    // In the world the mesh is still and the instrument moves from x = −1 to
    // x = 1 while tilting; seen from the instrument, the edge sweeps across it.
    let old = InstrumentPose::new(Point3::new(-1.0, 0.0, 0.0), Vector3::z_axis());
    let new = InstrumentPose::new(
        Point3::new(1.0, 0.0, 0.0),
        Unit::new_normalize(Vector3::new(0.2, 0.0, 1.0)),
    );
    let (a, b) = (Point3::new(0.0, -1.0, 0.3), Point3::new(0.0, 1.0, 0.3));
    let e = MovingEdge::in_instrument_frame(&rigid_motion(&old, &new), [a, b], [a, b]);
    let c = edge_crossing(&e, &new, 1.0).expect("the shaft went through the edge");
    assert_eq!(c.kind, CrossingKind::Transversal);
    assert!((c.alpha - 0.5).abs() < 1e-12, "{c:?}");
    // Still edge, instrument moving alongside it: nothing.
    let (a, b) = (Point3::new(-1.0, 0.5, 0.3), Point3::new(1.0, 0.5, 0.3));
    let e = MovingEdge::in_instrument_frame(&rigid_motion(&old, &new), [a, b], [a, b]);
    assert_eq!(edge_crossing(&e, &new, 1.0), None);
}
