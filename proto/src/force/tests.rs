use nalgebra::{Point3, Rotation3, Unit, Vector3};
use proptest::prelude::*;

use super::*;

fn vec3() -> impl Strategy<Value = Vector3<f64>> {
    [-10.0..10.0f64, -10.0..10.0f64, -10.0..10.0f64].prop_map(Vector3::from)
}

fn close(a: &Vector3<f64>, b: &Vector3<f64>, tol: f64) -> bool {
    (a - b).norm() <= tol * (1.0 + a.norm().max(b.norm()))
}

proptest! {
    #[test]
    fn a_zero_force_leaves_the_other(f in vec3()) {
        prop_assert_eq!(combine(&f, &Vector3::zeros()), f);
        prop_assert_eq!(combine(&Vector3::zeros(), &f), f);
    }

    #[test]
    fn same_direction_gives_the_larger(f in vec3(), k in 0.01..100.0f64) {
        let g = f * k;
        let larger = if k >= 1.0 { g } else { f };
        prop_assert!(close(&combine(&f, &g), &larger, 1e-12));
        prop_assert!(close(&combine(&g, &f), &larger, 1e-12));
    }

    #[test]
    fn orthogonal_or_opposed_gives_the_sum(f in vec3(), g in vec3(), k in 0.01..100.0f64) {
        prop_assume!(f.norm() > 1e-6 && g.norm() > 1e-6);
        let orthogonal = g - f * (g.dot(&f) / f.norm_squared());
        prop_assert!(close(&combine(&f, &orthogonal), &(f + orthogonal), 1e-12));
        prop_assert!(close(&combine(&f, &(-f * k)), &(f - f * k), 1e-12));
    }

    #[test]
    fn continuous_across_every_case_boundary(f in vec3(), g in vec3(), eps in 1e-9..1e-6f64) {
        // Move f1 across p = 0, p = |f0|² and p = |f1|² along f0: the result moves by
        // no more than a small multiple of the step.
        prop_assume!(f.norm() > 0.1 && g.norm() > 0.1);
        let u = f.normalize();
        let perp = g - u * g.dot(&u);
        prop_assume!(perp.norm() > 0.1);
        // f1 = perp + s·u has p = s|f0|; the boundaries are s = 0, s = |f0| and the s
        // solving s|f0| = |perp|² + s² (when it exists).
        let mut boundaries = vec![0.0, f.norm()];
        let (a, c) = (f.norm(), perp.norm_squared());
        let disc = a * a - 4.0 * c;
        if disc >= 0.0 {
            boundaries.push((a - disc.sqrt()) / 2.0);
            boundaries.push((a + disc.sqrt()) / 2.0);
        }
        let scale = f.norm() + g.norm();
        for s in boundaries {
            let step = eps * scale;
            let below = combine(&f, &(perp + u * (s - step)));
            let above = combine(&f, &(perp + u * (s + step)));
            prop_assert!((below - above).norm() <= 1e3 * step + 1e-12 * scale,
                "jump {} at s = {s} for a step {step}", (below - above).norm());
        }
    }

    #[test]
    fn nearly_equal_forces_combine_accurately(f in vec3(), angle in 1e-12..1e-6f64) {
        // Two forces equal but for a tiny turn are in the blend region, where a naive
        // denominator |f0|²|f1|² − p² is all rounding; the result must be ≈ f.
        prop_assume!(f.norm() > 1e-3);
        let axis = Unit::new_normalize(f.cross(&Vector3::new(0.3, -0.2, 1.0)));
        let g = Rotation3::from_axis_angle(&axis, angle) * f;
        let r = combine(&f, &g);
        prop_assert!(r.iter().all(|c| c.is_finite()));
        prop_assert!(close(&r, &f, 1e-6), "{r} vs {f}");
    }
}

#[test]
fn the_printed_case_b_contradicts_the_prose() {
    // f0 small, f1 large and the same way: the prose wants the larger, f1. The printed
    // eq. 9 (b) — |F0|² ≤ F0·F1 ⇒ F0 — would give the smaller.
    let f0 = Vector3::new(1.0, 0.0, 0.0);
    let f1 = Vector3::new(3.0, 0.5, 0.0);
    assert!(f0.norm_squared() <= f0.dot(&f1));
    assert_eq!(combine(&f0, &f1), f1);
}

#[test]
fn plane_force_grows_with_depth_and_stiffness_and_points_out() {
    let plane = Plane {
        normal: Unit::new_normalize(Vector3::new(0.0, 0.0, 1.0)),
        anchor: Point3::origin(),
        stiffness: 200.0,
        drag: Vector3::zeros(),
    };
    assert_eq!(
        plane_force(&plane, &Point3::new(0.1, 0.0, 0.01)),
        Vector3::zeros()
    );
    let f1 = plane_force(&plane, &Point3::new(0.1, 0.0, -0.01));
    let f2 = plane_force(&plane, &Point3::new(0.1, 0.0, -0.02));
    assert!((f1 - Vector3::new(0.0, 0.0, 2.0)).norm() < 1e-12);
    assert!((f2 - f1 * 2.0).norm() < 1e-12);
    let stiffer = Plane {
        stiffness: 400.0,
        drag: Vector3::zeros(),
        ..plane
    };
    assert!((plane_force(&stiffer, &Point3::new(0.0, 0.0, -0.01)) - f1 * 2.0).norm() < 1e-12);
}

#[test]
fn split_gives_the_axial_part_and_the_torque_about_the_trocar() {
    let axis = Unit::new_normalize(Vector3::new(0.0, 0.0, 1.0));
    let trocar = Point3::new(0.0, 0.0, 0.2);
    let tip = Point3::new(0.0, 0.0, 0.0);
    // A push along the shaft has no torque about a trocar on the axis.
    let along = split(&Vector3::new(0.0, 0.0, 3.0), &tip, &axis, &trocar);
    assert_eq!(along.axial, 3.0);
    assert_eq!(along.torque, Vector3::zeros());
    // A sideways push (+x) at the tip, 0.2 m below the trocar on the axis:
    // (P − T) × F = (0, 0, −0.2) × (1, 0, 0) = (0, −0.2, 0) N·m.
    let side = split(&Vector3::new(1.0, 0.0, 0.0), &tip, &axis, &trocar);
    assert_eq!(side.axial, 0.0);
    assert!((side.torque - Vector3::new(0.0, -0.2, 0.0)).norm() < 1e-15);
}

fn z_up() -> Unit<Vector3<f64>> {
    Unit::new_normalize(Vector3::new(0.0, 0.0, 1.0))
}

/// A model made at tip (0, 0, 0), axis +z, with a tip plane 2 mm deep along +z and a
/// shaft plane 3 mm deep along +x, level with the axis 0.05 m above the tip.
fn two_plane_model() -> LocalModel {
    let x = Unit::new_normalize(Vector3::new(1.0, 0.0, 0.0));
    LocalModel {
        tip_plane: Some(Plane {
            normal: z_up(),
            anchor: Point3::new(0.0, 0.0, 0.002),
            stiffness: 100.0,
            drag: Vector3::zeros(),
        }),
        shaft_plane: Some(Plane {
            normal: x,
            anchor: Point3::new(0.003, 0.0, 0.05),
            stiffness: 300.0,
            drag: Vector3::zeros(),
        }),
        young_modulus: Some(4500.0),
        kind: ForceModel::Calibrated,
        ..LocalModel::free(7, 0.1, Point3::origin(), z_up())
    }
}

#[test]
fn the_model_pose_feels_the_indentation_of_each_plane() {
    let m = two_plane_model();
    let f = m.force(&m.tip, &m.axis);
    // Orthogonal forces add: 100 N/m × 2 mm along z, 300 N/m × 3 mm along x.
    assert!((f.force - Vector3::new(0.9, 0.0, 0.2)).norm() < 1e-12);
    // Applied between the tip and the shaft contact, weighted by magnitude.
    let expected_z = 0.05 * 0.9 / (0.9 + 0.2);
    assert!((f.point - Point3::new(0.0, 0.0, expected_z)).norm() < 1e-12);
}

#[test]
fn the_shaft_depth_follows_the_lever_of_its_contact() {
    // Pivot about a trocar 0.1 m above the tip so the tip moves 2 mm in −x: the
    // shaft point level with the anchor (0.05 m up, half way) moves 1 mm in −x.
    let m = LocalModel {
        tip_plane: None,
        ..two_plane_model()
    };
    let trocar = Point3::new(0.0, 0.0, 0.1);
    let tip = Point3::new(-0.002, 0.0, 0.0);
    let axis = Unit::new_normalize(trocar - tip);
    let f = m.force(&tip, &axis);
    // Depth 3 mm + about 1 mm (to first order in the small tilt).
    assert!((f.force.x / 300.0 - 0.004).abs() < 2e-5, "{}", f.force);
    // Pivoting the tip 8 mm to +x moves the shaft contact 4 mm, past the 3 mm
    // indentation: out of the plane, no force.
    let away = Point3::new(0.008, 0.0, 0.0);
    let axis = Unit::new_normalize(trocar - away);
    assert_eq!(m.force(&away, &axis).force, Vector3::zeros());
}

#[test]
fn a_free_model_gives_no_force() {
    let m = LocalModel::free(0, 0.0, Point3::new(1.0, 2.0, 3.0), z_up());
    assert!(!m.in_contact());
    let f = m.force(&Point3::new(-5.0, 0.0, 0.0), &z_up());
    assert_eq!(f.force, Vector3::zeros());
}

#[test]
fn the_local_model_round_trips_through_the_wire() {
    let m = two_plane_model();
    let msg = crate::v1::LocalModel::from(&m);
    let back = LocalModel::try_from(&msg).unwrap();
    assert_eq!(back, m);
    let free = LocalModel::free(3, 0.05, Point3::new(0.1, 0.2, 0.3), z_up());
    assert_eq!(
        LocalModel::try_from(&crate::v1::LocalModel::from(&free)).unwrap(),
        free
    );
}

#[test]
fn bad_local_models_name_their_field() {
    use wire::WireError;
    let good = crate::v1::LocalModel::from(&two_plane_model());
    type Spoil = Box<dyn Fn(&mut crate::v1::LocalModel)>;
    let cases: Vec<(Spoil, WireError)> = vec![
        (Box::new(|m| m.pose = None), WireError::Missing("pose")),
        (
            Box::new(|m| m.pose.as_mut().unwrap().tip.as_mut().unwrap().y = f64::NAN),
            WireError::NotFinite("pose.tip"),
        ),
        (
            Box::new(|m| m.pose.as_mut().unwrap().axis.as_mut().unwrap().z = 0.0),
            WireError::NotUnit {
                field: "pose.axis",
                norm: 0.0,
            },
        ),
        (
            Box::new(|m| m.tip_plane.as_mut().unwrap().normal.as_mut().unwrap().z = 2.0),
            WireError::NotUnit {
                field: "tip_plane.normal",
                norm: 2.0,
            },
        ),
        (
            Box::new(|m| m.shaft_plane.as_mut().unwrap().anchor = None),
            WireError::Missing("shaft_plane.anchor"),
        ),
        (
            Box::new(|m| m.shaft_plane.as_mut().unwrap().stiffness_n_per_m = -1.0),
            WireError::Negative {
                field: "shaft_plane.stiffness_n_per_m",
                value: -1.0,
            },
        ),
        (
            Box::new(|m| m.tip_plane.as_mut().unwrap().stiffness_n_per_m = f64::INFINITY),
            WireError::NotFinite("tip_plane.stiffness_n_per_m"),
        ),
        (
            Box::new(|m| {
                m.tip_plane.as_mut().unwrap().drag_n = Some(crate::v1::Vec3 {
                    x: 0.0,
                    y: f64::NAN,
                    z: 0.0,
                })
            }),
            WireError::NotFinite("tip_plane.drag_n"),
        ),
        (
            Box::new(|m| m.young_modulus_pa = Some(f64::NAN)),
            WireError::NotFinite("young_modulus_pa"),
        ),
        (
            Box::new(|m| m.sim_time_s = f64::NEG_INFINITY),
            WireError::NotFinite("sim_time_s"),
        ),
    ];
    for (spoil, expected) in cases {
        let mut m = good;
        spoil(&mut m);
        assert_eq!(LocalModel::try_from(&m), Err(expected));
    }
    // An inactive plane's fields mean nothing, even when they are garbage.
    let mut m = good;
    let tip = m.tip_plane.as_mut().unwrap();
    tip.active = false;
    tip.stiffness_n_per_m = f64::NAN;
    assert_eq!(LocalModel::try_from(&m).unwrap().tip_plane, None);
}

/// A calibrated tip plane made at the origin, 2 mm deep along +z with λ = 1000 N/m
/// (a 2 N push), dragged 0.5 N along +x.
fn dragged_tip() -> LocalModel {
    LocalModel {
        tip_plane: Some(Plane {
            normal: z_up(),
            anchor: Point3::new(0.0, 0.0, 0.002),
            stiffness: 1000.0,
            drag: Vector3::new(0.5, 0.0, 0.0),
        }),
        kind: ForceModel::Calibrated,
        ..LocalModel::free(9, 0.2, Point3::origin(), z_up())
    }
}

#[test]
fn the_drag_is_felt_at_the_model_pose_and_pulls_back_sideways() {
    let m = dragged_tip();
    // At the model's pose: the push and the drag, the elastic reaction.
    let f = m.force(&m.tip, &m.axis).force;
    assert!((f - Vector3::new(0.5, 0.0, 2.0)).norm() < 1e-12, "{f}");
    // 0.3 mm sideways (+x, −y): the held tissue pulls back with κλ at once.
    let moved = Point3::new(3e-4, -3e-4, 0.0);
    let f = m.force(&moved, &m.axis).force;
    let pull = LATERAL_STIFFNESS_RATIO * 1000.0 * 3e-4;
    let expected = Vector3::new(0.5 - pull, pull, 2.0);
    assert!((f - expected).norm() < 1e-12, "{f}");
    // Deeper by 1 mm: the push grows by λ · 1 mm, the drag stays.
    let f = m.force(&Point3::new(0.0, 0.0, -0.001), &m.axis).force;
    assert!((f - Vector3::new(0.5, 0.0, 3.0)).norm() < 1e-12, "{f}");
}

#[test]
fn the_drag_fades_to_nothing_as_the_contact_ends() {
    let m = dragged_tip();
    // Half the model's depth: half the drag (and half the push).
    let f = m.force(&Point3::new(0.0, 0.0, 0.001), &m.axis).force;
    assert!((f - Vector3::new(0.25, 0.0, 1.0)).norm() < 1e-12, "{f}");
    // Far to the side near the surface: the pull is held within the cone
    // |f_t| ≤ max(1, |D| / (λ d₀)) λ d = λ d, and vanishes with d.
    let mut last = f64::INFINITY;
    for depth in [1e-3, 1e-4, 1e-5, 1e-6, 0.0] {
        let at = Point3::new(-0.01, 0.004, 0.002 - depth);
        let f = m.force(&at, &m.axis).force;
        let lateral = Vector3::new(f.x, f.y, 0.0).norm();
        assert!(lateral <= 1000.0 * depth * (1.0 + 1e-12), "{depth}: {f}");
        assert!(lateral < last || lateral == 0.0);
        last = lateral;
    }
    assert_eq!(
        m.force(&Point3::new(-0.01, 0.004, 0.002), &m.axis).force,
        Vector3::zeros()
    );
    // A geometric plane carries no drag and pulls nothing sideways.
    let geometric = LocalModel {
        kind: ForceModel::Geometric,
        tip_plane: m.tip_plane.map(|p| Plane {
            drag: Vector3::zeros(),
            ..p
        }),
        ..m
    };
    let f = geometric.force(&Point3::new(3e-4, 0.0, 0.0), &m.axis).force;
    assert!((f - Vector3::new(0.0, 0.0, 2.0)).norm() < 1e-12, "{f}");
}

#[test]
fn the_drag_round_trips_through_the_wire() {
    let m = dragged_tip();
    let msg = crate::v1::LocalModel::from(&m);
    assert!(msg.tip_plane.unwrap().drag_n.is_some());
    assert_eq!(LocalModel::try_from(&msg).unwrap(), m);
}

/// The slopes of a tip model's force at its pose, N/m: along `n` (pressing deeper)
/// and sideways (+x), by differences over 1 µm.
fn slopes(m: &LocalModel) -> (f64, f64) {
    let f0 = m.force(&m.tip, &m.axis).force;
    let h = 1e-6;
    let deeper = m.force(&(m.tip - Vector3::z() * h), &m.axis).force;
    let aside = m.force(&(m.tip + Vector3::x() * h), &m.axis).force;
    ((deeper - f0).z / h, -(aside - f0).x / h)
}

#[test]
fn a_limited_plane_has_no_spring_stiffer_than_the_limit() {
    let mut m = dragged_tip();
    let (normal, lateral) = slopes(&m);
    assert!((normal - 1000.0).abs() < 1e-6, "{normal}");
    assert!(
        (lateral - LATERAL_STIFFNESS_RATIO * 1000.0).abs() < 1e-6,
        "{lateral}"
    );
    // The pull of the held tissue is the stiffest spring; the limit lowers it to
    // the limit, and the push with it.
    let limit = 1200.0;
    m.tip_plane.as_mut().unwrap().limit_stiffness(limit);
    let (normal, lateral) = slopes(&m);
    assert!((lateral - limit).abs() < 1e-6, "{lateral}");
    assert!(
        (normal - limit / LATERAL_STIFFNESS_RATIO).abs() < 1e-6,
        "{normal}"
    );
    // Without drag only the push is a spring; a limit above it changes nothing.
    let mut bare = m.tip_plane.unwrap();
    bare.drag = Vector3::zeros();
    bare.limit_stiffness(500.0);
    assert_eq!(bare.stiffness, 500.0);
    let before = bare;
    bare.limit_stiffness(501.0);
    assert_eq!(bare, before);
}
