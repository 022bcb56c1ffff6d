use super::*;
use crate::engine::contact::pose::rigid_motion;
use nalgebra::{Translation3, Unit, UnitQuaternion};

/// The axis along +z from the origin.
fn z_pose() -> InstrumentPose {
    InstrumentPose::new(Point3::origin(), Vector3::z_axis())
}

fn edge(a: [f64; 3], b: [f64; 3], da: [f64; 3], db: [f64; 3]) -> MovingEdge {
    MovingEdge::new(
        Point3::from(a),
        Point3::from(b),
        Vector3::from(da),
        Vector3::from(db),
    )
}

/// `s(t) = Z·((A(t) − P) × (B(t) − P))` evaluated directly in 3D (an independent
/// path from the 2D coefficients of the implementation).
fn s_at(e: &MovingEdge, pose: &InstrumentPose, t: f64) -> f64 {
    pose.axis
        .dot(&(e.a_at(t) - pose.tip).cross(&(e.b_at(t) - pose.tip)))
}

/// A few fixed rigid motions, far from axis-aligned.
fn frames() -> [Isometry3<f64>; 3] {
    [
        Isometry3::from_parts(
            Translation3::new(0.123, -0.456, 0.0789),
            UnitQuaternion::from_axis_angle(
                &Unit::new_normalize(Vector3::new(1.0, 2.0, 3.0)),
                1.234,
            ),
        ),
        Isometry3::from_parts(
            Translation3::new(-0.31, 0.07, 0.2),
            UnitQuaternion::from_axis_angle(
                &Unit::new_normalize(Vector3::new(-0.3, 0.1, 0.9)),
                2.9,
            ),
        ),
        Isometry3::from_parts(
            Translation3::new(0.05, 0.05, -0.11),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2),
        ),
    ]
}

fn moved(
    iso: &Isometry3<f64>,
    e: &MovingEdge,
    pose: &InstrumentPose,
) -> (MovingEdge, InstrumentPose) {
    (
        MovingEdge::new(
            iso.transform_point(&e.a),
            iso.transform_point(&e.b),
            iso.transform_vector(&e.delta_a),
            iso.transform_vector(&e.delta_b),
        ),
        InstrumentPose::new(iso.transform_point(&pose.tip), iso.rotation * pose.axis),
    )
}

/// `edge_crossing` on the axis-aligned configuration and on the same configuration
/// seen in other frames: the answer must not depend on the frame.
fn crossing_everywhere(e: &MovingEdge, length: f64) -> Option<Crossing> {
    let found = edge_crossing(e, &z_pose(), length);
    for iso in frames() {
        let (e2, p2) = moved(&iso, e, &z_pose());
        let other = edge_crossing(&e2, &p2, length);
        match (found, other) {
            (None, None) => {}
            (Some(c), Some(d)) => {
                let tol = 1e-9 * e.scale();
                assert_eq!(c.kind, d.kind);
                assert!((c.t - d.t).abs() <= 1e-9, "{c:?} vs {d:?}");
                assert!((c.alpha - d.alpha).abs() <= 1e-9, "{c:?} vs {d:?}");
                assert!((c.beta - d.beta).abs() <= tol, "{c:?} vs {d:?}");
            }
            _ => panic!("frame-dependent answer: {found:?} vs {other:?}"),
        }
    }
    found
}

fn assert_crossing(c: Option<Crossing>, t: f64, alpha: f64, beta: f64, kind: CrossingKind) {
    let c = c.unwrap_or_else(|| panic!("expected a crossing at t = {t}"));
    assert_eq!(c.kind, kind, "{c:?}");
    assert!((c.t - t).abs() < 1e-12, "t: {c:?}, expected {t}");
    assert!(
        (c.alpha - alpha).abs() < 1e-12,
        "α: {c:?}, expected {alpha}"
    );
    assert!((c.beta - beta).abs() < 1e-12, "β: {c:?}, expected {beta}");
}

mod eq6;
mod parallel;
mod properties;
mod transversal;
