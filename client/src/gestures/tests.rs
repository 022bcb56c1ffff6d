use nalgebra::{Point3, Vector3};

use super::*;
use crate::proto::v1::{InstrumentDescription, SceneDescription, SurfaceMesh, Vec3};

fn scene(positions: Vec<f32>) -> SceneDescription {
    SceneDescription {
        rest_surface: Some(SurfaceMesh {
            positions,
            triangles: vec![0, 1, 2],
        }),
        ..Default::default()
    }
}

#[test]
fn press_starts_outside_goes_in_and_keeps_the_axis_through_the_trocar() {
    let trocar = Point3::new(0.0, 0.0, 0.2);
    let target = Point3::origin();
    let path = default_press(trocar, target);
    let (tip0, axis) = path(0.0);
    assert!((tip0.z - DEFAULT_STANDOFF_M).abs() < 1e-12);
    assert!((axis.into_inner() - Vector3::z()).norm() < 1e-12);
    let (tip_half, _) = path(DEFAULT_PERIOD_S / 2.0);
    assert!((tip_half.z + DEFAULT_DEPTH_M).abs() < 1e-12);
    let (tip1, _) = path(DEFAULT_PERIOD_S);
    assert!((tip1 - tip0).norm() < 1e-12);
}

#[test]
fn aims_at_the_surface_vertex_nearest_the_trocar() {
    let scene = scene(vec![0.0, 0.0, 0.0, 0.0, 0.0, 0.05, 1.0, 1.0, 1.0]);
    let instrument = InstrumentDescription {
        trocar: Some(Vec3 {
            x: 0.0,
            y: 0.0,
            z: 0.2,
        }),
        ..Default::default()
    };
    let (tip, _) = default_press_for(&scene, &instrument)(0.0);
    assert!((tip.z - (0.05 + DEFAULT_STANDOFF_M)).abs() < 1e-6, "{tip}");
}

#[test]
fn the_front_is_the_most_forward_point_near_the_middle() {
    // (0.1, 0, 0.9) is further forward but 10 cm off the middle.
    let s = scene(vec![0.0, 0.0, 0.1, 0.01, 0.01, 0.2, 0.1, 0.0, 0.9]);
    assert_eq!(front(&s), Point3::new(0.01, 0.01, 0.2).cast::<f32>().cast());
    // With nothing near the middle, the most forward of all; with no surface, the
    // origin.
    let s = scene(vec![0.1, 0.0, 0.1, 0.2, 0.0, 0.3, 0.1, 0.1, 0.2]);
    assert_eq!(front(&s), Point3::new(0.2, 0.0, 0.3).cast::<f32>().cast());
    assert_eq!(front(&SceneDescription::default()), Point3::origin());
}

#[test]
fn the_demo_gesture_presses_past_the_front_and_repeats() {
    let s = scene(vec![0.0, 0.0, 0.1, 0.5, 0.5, 0.0, -0.5, 0.5, 0.0]);
    let f = front(&s);
    let path = tip_and_shaft(&s, &InstrumentDescription::default());
    let (start, _) = path(0.0);
    assert!((start.z - (f.z + 0.02)).abs() < 1e-12, "{start}");
    // Tip held 1 cm past the surface, axis +z.
    let (tip, axis) = path(3.0);
    assert!((tip.z - (f.z - 0.01)).abs() < 1e-12, "{tip}");
    assert!((axis.into_inner() - Vector3::z()).norm() < 1e-12);
    // Shaft across the face (axis −x) and 1 cm past it.
    let (tip, axis) = path(8.0);
    assert!((tip.z - (f.z - 0.01)).abs() < 1e-12, "{tip}");
    assert!((axis.into_inner() + Vector3::x()).norm() < 1e-12);
    let (again, _) = path(tip_and_shaft::PERIOD_S);
    assert!((again - start).norm() < 1e-12);
}

#[test]
fn the_probe_goes_in_slides_and_comes_back_with_its_axis_through_the_trocar() {
    let surface = [Point3::new(0.0, 0.0, 0.1), Point3::new(0.0, 0.5, 0.9)];
    let trocar = Point3::new(0.05, 0.0, 0.3);
    assert!(Probe::on_front([Point3::new(0.5, 0.5, 0.0)], trocar, 0.01, 0.0).is_none());
    let probe = Probe::on_front(surface, trocar, 0.008, 0.02).unwrap();
    assert!((probe.tip(0.0) - Point3::new(-0.01, 0.0, 0.11)).norm() < 1e-12);
    // Held 8 mm past the surface, before and after the 2 cm slide.
    assert!((probe.tip(1.5) - Point3::new(-0.01, 0.0, 0.092)).norm() < 1e-12);
    assert!((probe.tip(3.0) - Point3::new(0.01, 0.0, 0.092)).norm() < 1e-12);
    assert!((probe.tip(PROBE_SECONDS) - Point3::new(0.01, 0.0, 0.11)).norm() < 1e-12);
    for k in 0..=40 {
        let (tip, axis) = probe.pose(k as f64 * 0.1);
        let to_trocar = trocar - tip;
        assert!(axis.cross(&to_trocar).norm() < 1e-12 && axis.dot(&to_trocar) > 0.0);
    }
}
