//! First contact without a spike, and no chatter: on a grid of mechanics rates,
//! stiffnesses, Poisson ratios and both dynamic integrators, the tip arrives 1 mm into
//! the free front in one tick (from just outside its reach), then holds still. The
//! force of the first-contact tick is within 2× of the steady force the hold settles to
//! at the same depth, and through the hold nothing is let go and the force stays
//! within 2× of the steady one.

mod common;

use common::contact::{front_vertex, pose};
use laparo_server::engine::scene::Scene;

/// Depth of the first-contact tick, m.
const DEPTH: f64 = 1e-3;
/// Simulated time of the hold, s: the damping (10/s) takes the slowest modes down by
/// e⁻¹⁰ in 2 s.
const HOLD: f64 = 2.0;

struct Touch {
    first: f64,
    steady: f64,
    /// Smallest and largest force through the hold, N.
    range: (f64, f64),
    /// Fewest vertices held through the hold.
    fewest_held: usize,
}

/// The touch for one point of the grid; `None` where the scene refuses the explicit
/// integrator (more substeps a tick than a session can run).
fn touch(rate: f64, e: f64, nu: f64, integrator: &str) -> Option<Touch> {
    let mut scene = Scene::default_scene();
    scene.material.young_modulus = e;
    scene.material.poisson_ratio = nu;
    scene.mechanics.rate_hz = rate;
    scene.mechanics.integrator = common::integrator_kind(integrator);
    scene.mechanics.cg_tolerance = 1e-8;
    scene.gravity = [0.0; 3];
    scene.instruments.truncate(1);
    let mut sim = match scene.build() {
        Ok(sim) => sim,
        Err(e) if integrator == "explicit" && e.to_string().contains("substeps") => return None,
        Err(e) => panic!("{e}"),
    };
    let v = front_vertex(&sim);
    let p = sim.state.x[v as usize];
    let r = sim.instruments[0].radius;
    let at = |z: f64| Some(pose([p.x, p.y, z], [0.0, 0.0, 1.0]));
    sim.set_pose(0, at(p.z + r + 1e-4));
    sim.tick();
    assert!(sim.instruments[0].held.is_empty());
    sim.set_pose(0, at(p.z + r - DEPTH));
    sim.tick();
    let first = sim.instruments[0].report.reaction.norm();
    let mut range = (f64::INFINITY, 0.0f64);
    let mut fewest_held = usize::MAX;
    let ticks = ((HOLD * rate) as usize).max(5);
    for _ in 0..ticks {
        sim.tick();
        let f = sim.instruments[0].report.reaction.norm();
        range = (range.0.min(f), range.1.max(f));
        fewest_held = fewest_held.min(sim.instruments[0].held.len());
    }
    Some(Touch {
        first,
        steady: sim.instruments[0].report.reaction.norm(),
        range,
        fewest_held,
    })
}

/// Runs the grid for one integrator; returns the lines that break the bounds.
fn grid(integrator: &str) -> Vec<String> {
    let mut failures = Vec::new();
    for rate in [1.0, 30.0, 1000.0] {
        for e in [1e3, 1e5, 1e7] {
            for nu in [0.3, 0.49, 0.499] {
                let Some(t) = touch(rate, e, nu, integrator) else {
                    println!("{integrator} {rate} Hz E {e:e} ν {nu}: refused by the scene");
                    continue;
                };
                let line = format!(
                    "{integrator} {rate} Hz E {e:e} ν {nu}: first {:.4e} N, steady {:.4e} N (×{:.2}), hold {:.4e}..{:.4e} N, fewest held {}",
                    t.first,
                    t.steady,
                    t.first / t.steady,
                    t.range.0,
                    t.range.1,
                    t.fewest_held
                );
                println!("{line}");
                let within = |f: f64| (0.5 * t.steady..=2.0 * t.steady).contains(&f);
                if !(within(t.first) && within(t.range.0) && within(t.range.1) && t.fewest_held > 0)
                {
                    failures.push(line);
                }
            }
        }
    }
    failures
}

#[test]
fn implicit_first_contact_within_twice_the_steady_force_without_chatter() {
    let failures = grid("implicit");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn explicit_first_contact_within_twice_the_steady_force_without_chatter() {
    let failures = grid("explicit");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
