use nalgebra::{Point3, Vector3};

use super::*;

const H: f64 = 1e-3;
const MASS: f64 = 0.15;
/// The default hand's stiffness limit, N/m.
const K_MAX: f64 = 200_000.0;

/// A free mass on the z axis thrown at a wall whose surface, at `z = wall(t)`, pushes
/// back with `λ (wall(t) − z)` while the mass is behind it; the force loop's order at
/// each tick (observe, control, render), and the mass moved exactly under the force
/// held over the tick, as a device's handle moves (so that the work of the force over
/// a tick is the change of kinetic energy). Returns the mass's kinetic energy once it
/// has left the wall, J, and the most the damper added to the wall's force in one
/// tick, N.
fn throw(passivity: &mut Passivity, lambda: f64, wall: impl Fn(f64) -> f64) -> (f64, f64) {
    let axis = Vector3::z_axis();
    let (mut z, mut v) = (0.002, -0.2);
    let mut largest = 0.0f64;
    for k in 0..2000 {
        let t = k as f64 * H;
        let tip = Point3::new(0.0, 0.0, z);
        passivity.observe(t, &tip, &axis);
        let model = Vector3::z() * lambda * (wall(t) - z).max(0.0);
        let force = passivity.control(&model);
        largest = largest.max((force - model).norm());
        passivity.rendered(t, force, tip, 0.0);
        let a = force.z / MASS;
        z += H * v + 0.5 * H * H * a;
        v += H * a;
    }
    assert!(z > wall(2.0), "the mass left the wall");
    (0.5 * MASS * v * v, largest)
}

const INCOMING: f64 = 0.5 * MASS * 0.2 * 0.2;

#[test]
fn a_wall_that_pushes_out_gives_back_no_more_than_it_took() {
    // The wall's surface moves out at 0.1 m/s while the mass is against it: an
    // environment that makes energy, as a model whose anchor steps toward the
    // instrument at every tick does. Without the damper the mass leaves with 5 times
    // the energy it came with; with it, with no more than it came with (measured:
    // equal to 1e-15).
    let wall = |t: f64| 0.1 * t;
    let (unchecked, _) = throw(&mut Passivity::new(f64::INFINITY), 5_000.0, wall);
    assert!(
        unchecked > 1.5 * INCOMING,
        "the moving wall makes energy: {unchecked} J out for {INCOMING} J in"
    );
    let mut passivity = Passivity::new(K_MAX);
    let (damped, largest) = throw(&mut passivity, 5_000.0, wall);
    assert!(
        damped <= INCOMING * (1.0 + 1e-9),
        "{damped} J out for {INCOMING} J in"
    );
    assert!(passivity.damped_ticks() > 0);
    // Never more than the cap, α_max |v| with α_max = K_max h / 4 and |v| ≤ the
    // fastest the mass went (the unchecked run's exit speed).
    let fastest = (2.0 * unchecked / MASS).sqrt();
    assert!(largest <= 0.25 * K_MAX * H * fastest * (1.0 + 1e-12));
}

#[test]
fn a_still_wall_loses_only_what_holding_its_force_over_a_tick_made() {
    // A fixed wall is passive, but rendered with its force held over each tick it
    // pushes out with the force of the deeper position a tick before: the mass
    // leaves with more than it brought (1.8 times, at 20 kN/m and 0.2 m/s: nine ticks
    // of contact). The damper takes that back and no more: the mass leaves with its
    // incoming energy, to within 1% (measured: 5e-6 less).
    let (unchecked, _) = throw(&mut Passivity::new(f64::INFINITY), 20_000.0, |_| 0.0);
    assert!(unchecked > INCOMING, "{unchecked} J");
    let mut passivity = Passivity::new(K_MAX);
    let (damped, _) = throw(&mut passivity, 20_000.0, |_| 0.0);
    assert!(
        (0.99 * INCOMING..=INCOMING * (1.0 + 1e-9)).contains(&damped),
        "{damped} J out for {INCOMING} J in"
    );
}

#[test]
fn a_still_instrument_feels_the_models_force_exactly() {
    let mut passivity = Passivity::new(K_MAX);
    let axis = Vector3::z_axis();
    let push = Vector3::new(0.0, 0.0, 2.0);
    // The instrument moves 1 mm along the force: the environment gives 2 mJ.
    passivity.observe(0.0, &Point3::origin(), &axis);
    passivity.rendered(0.0, push, Point3::origin(), 0.0);
    passivity.observe(H, &Point3::new(0.0, 0.0, 1e-3), &axis);
    assert!((passivity.energy() + 2e-3).abs() < 1e-15);
    assert_ne!(passivity.control(&push), push, "moving: damped");
    // Then it stays where it is: no velocity, nothing to damp.
    passivity.rendered(H, push, Point3::new(0.0, 0.0, 1e-3), 0.0);
    passivity.observe(2.0 * H, &Point3::new(0.0, 0.0, 1e-3), &axis);
    assert_eq!(passivity.control(&push), push);
}

#[test]
fn out_of_contact_the_observer_starts_again() {
    let mut passivity = Passivity::new(K_MAX);
    let axis = Vector3::z_axis();
    passivity.rendered(0.0, Vector3::new(0.0, 0.0, 2.0), Point3::origin(), 0.0);
    passivity.observe(H, &Point3::new(0.0, 0.0, 1e-3), &axis);
    assert!(passivity.energy() < 0.0);
    assert_eq!(passivity.control(&Vector3::zeros()), Vector3::zeros());
    assert_eq!(passivity.energy(), 0.0);
}

#[test]
fn the_point_followed_is_the_instruments_own() {
    // The force applies 5 cm up the axis; the instrument turns about a trocar 10 cm
    // up while its tip moves 1 mm along x: the point 5 cm up moves 0.5 mm, and the
    // energy is the force times that, not the tip's move.
    let mut passivity = Passivity::new(K_MAX);
    let trocar = Point3::new(0.0, 0.0, 0.1);
    let (tip0, tip1) = (Point3::origin(), Point3::new(1e-3, 0.0, 0.0));
    let axis = |tip: Point3<f64>| Unit::new_normalize(trocar - tip);
    let along = 0.05;
    let point = tip0 + axis(tip0).into_inner() * along;
    let force = Vector3::new(-1.0, 0.0, 0.0);
    passivity.rendered(0.0, force, point, along);
    passivity.observe(H, &tip1, &axis(tip1));
    let moved = tip1 + axis(tip1).into_inner() * along - point;
    assert!((moved.x - 0.5e-3).abs() < 1e-6, "{moved:?}");
    assert!((passivity.energy() - 1.0 * moved.x).abs() < 1e-15);
}
