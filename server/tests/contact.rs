//! The contact stage on the default liver: pressing with the tip and the shaft,
//! holding, withdrawing, and the invariants after every tick.

mod common;

use common::contact::*;
use laparo_server::engine::scene::Scene;

#[test]
fn tip_press_deforms_holds_and_releases() {
    let mut sim = Scene::default_scene().build().unwrap();
    // Let the liver settle under gravity first.
    for _ in 0..60 {
        sim.tick();
    }
    let sag = sim.max_displacement();
    let front = front_point(&sim);
    let start = [front.x, front.y, front.z + 0.01];
    let depth = 0.012;
    let mut forces = Vec::new();
    // In over 0.5 s, hold for 0.5 s, out over 0.25 s, then 1 s away.
    for k in 0..150 {
        let t = k as f64 / 60.0;
        let z = if t < 0.5 {
            start[2] - (0.01 + depth) * t / 0.5
        } else if t < 1.0 {
            start[2] - 0.01 - depth
        } else {
            (start[2] - 0.01 - depth + (0.01 + depth) * (t - 1.0) / 0.25).min(start[2])
        };
        let in_body = t < 1.5;
        sim.set_pose(
            0,
            in_body.then(|| pose([start[0], start[1], z], [0.0, 0.0, 1.0])),
        );
        sim.tick();
        check_invariants(&sim).unwrap();
        forces.push(sim.instruments[0].report.reaction);
    }
    let pressed = &forces[45..60];
    // The tissue pushes the instrument back toward its handle (+z).
    assert!(pressed.iter().all(|f| f.z > 0.0), "{pressed:?}");
    // Held still, the force is steady.
    let (lo, hi) = pressed.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), f| {
        (lo.min(f.norm()), hi.max(f.norm()))
    });
    assert!(
        hi - lo <= 0.05 * hi,
        "force while holding still varies from {lo} to {hi} N"
    );
    assert!(
        sim.instruments[0].held.is_empty(),
        "withdrawn instrument still holds {:?}",
        sim.instruments[0].held
    );
    // The liver relaxes back to its sag.
    for _ in 0..120 {
        sim.tick();
    }
    assert!(
        (sim.max_displacement() - sag).abs() < 0.1 * sag,
        "relaxed to {} vs sag {sag}",
        sim.max_displacement()
    );
    println!(
        "force while holding {:.4} N; stats {:?}",
        hi,
        sim.contact.as_ref().unwrap().stats()
    );
}
