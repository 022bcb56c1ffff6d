use nalgebra::{Point3, Vector3};

use super::*;
use crate::proto::force::DeviceForce;

fn push(force: Vector3<f64>) -> DeviceForce {
    DeviceForce {
        force,
        axial: 0.0,
        torque: Vector3::zeros(),
    }
}

fn still(target: Point3<f64>) -> Trajectory {
    Box::new(move |_| (target, Vector3::z_axis()))
}

const TROCAR: Point3<f64> = Point3::new(0.0, 0.0, 0.15);

#[test]
fn scripted_device_follows_its_path_and_keeps_the_last_forces() {
    let mut d = ScriptedDevice::new(
        Box::new(|t| (Point3::new(t, 0.0, 0.0), Vector3::z_axis())),
        5.0,
        3,
    );
    assert_eq!(d.pose(0.25).0, Point3::new(0.25, 0.0, 0.0));
    assert!(d.last().is_none());
    for i in 0..5 {
        d.render(i as f64, &push(Vector3::new(i as f64, 0.0, 0.0)));
    }
    assert_eq!(d.rendered(), 5);
    let kept: Vec<f64> = d.recorded().map(|r| r.time).collect();
    assert_eq!(kept, [2.0, 3.0, 4.0]);
    assert_eq!(d.last().map(|r| r.force.force.x), Some(4.0));
    assert_eq!(d.max_force(), 5.0);
}

#[test]
fn hand_without_force_settles_on_its_target_with_the_axis_through_the_trocar() {
    let target = Point3::new(0.01, -0.005, -0.02);
    let mut hand = HandDevice::new(
        HandParams::default(),
        TROCAR,
        Point3::new(-0.01, 0.01, 0.0),
        still(target),
    );
    let dt = 1e-3;
    for k in 0..5000 {
        hand.pose(k as f64 * dt);
        hand.render(k as f64 * dt, &push(Vector3::zeros()));
    }
    let (tip, axis) = hand.pose(5.0);
    assert!((tip - target).norm() < 1e-6, "{tip:?}");
    assert!(hand.velocity().norm() < 1e-5);
    assert!((axis.into_inner() - (TROCAR - tip).normalize()).norm() < 1e-12);
}

/// With a fixed target and no rendered force the scheme's energy never grows, and
/// what it loses is exactly what the damping dissipated.
#[test]
fn hand_energy_never_grows_without_force() {
    let target = Point3::new(0.0, 0.0, -0.03);
    let mut hand = HandDevice::new(
        HandParams::default(),
        TROCAR,
        Point3::origin(),
        still(target),
    );
    let dt = 1e-3;
    hand.render(0.0, &push(Vector3::zeros()));
    let e0 = hand.discrete_energy();
    assert!((e0 - hand.spring_energy()).abs() < 1e-15);
    let mut last = e0;
    for k in 1..3000 {
        hand.render(k as f64 * dt, &push(Vector3::zeros()));
        let e = hand.discrete_energy();
        assert!(e <= last + 1e-15 * e0, "tick {k}: {e} > {last}");
        assert!(e >= 0.0);
        last = e;
    }
    assert!((e0 - last - hand.damping_loss()).abs() < 1e-12 * e0);
    assert_eq!(hand.force_work(), 0.0);
}

/// With a rendered force, the energy balance holds: `E − E₀ = W_F − D`.
#[test]
fn hand_energy_balance_counts_the_work_of_the_rendered_force() {
    let target = Point3::new(0.0, 0.0, -0.03);
    let mut hand = HandDevice::new(
        HandParams::default(),
        TROCAR,
        Point3::origin(),
        still(target),
    );
    let dt = 1e-3;
    hand.render(0.0, &push(Vector3::zeros()));
    let e0 = hand.discrete_energy();
    for k in 1..2000 {
        let t = k as f64 * dt;
        let f = Vector3::new(
            (7.0 * t).sin(),
            0.5 * (3.0 * t).cos(),
            2.0 * (11.0 * t).sin(),
        );
        hand.render(t, &push(f));
    }
    let balance = hand.discrete_energy() - e0 - (hand.force_work() - hand.damping_loss());
    assert!(balance.abs() < 1e-12 * e0, "{balance}");
    assert!(hand.force_work().abs() > 1e-4);
    let true_energy = hand.kinetic_energy() + hand.spring_energy();
    assert!((true_energy - hand.discrete_energy()).abs() < 0.05 * e0);
}
