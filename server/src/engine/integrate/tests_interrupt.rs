//! A raised interrupt ends a step at once: between explicit substeps, between
//! conjugate-gradient iterations. And a solve asked for a tolerance far below
//! round-off stays finite.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use crate::engine::integrate::IntegratorKind;
use crate::engine::scene::Scene;

fn default_with(kind: IntegratorKind) -> Scene {
    let mut scene = Scene::default_scene();
    scene.mechanics.integrator = kind;
    scene
}

#[test]
fn a_raised_interrupt_stops_the_explicit_step_before_its_first_substep() {
    let mut sim = default_with(IntegratorKind::Explicit).build().unwrap();
    let needed = sim.integrator.explicit_substeps(sim.dt);
    assert!(needed > 1);
    let flag = Arc::new(AtomicBool::new(false));
    sim.integrator.set_interrupt(flag.clone());
    assert_eq!(
        sim.tick().substeps,
        needed,
        "a lowered flag changes nothing"
    );
    flag.store(true, std::sync::atomic::Ordering::Relaxed);
    let before = sim.state.x.clone();
    let report = sim.tick();
    assert_eq!(report.substeps, 0);
    assert_eq!(sim.state.x, before, "no substep moved the liver");
}

#[test]
fn a_raised_interrupt_stops_the_conjugate_gradient_before_its_first_iteration() {
    for kind in [IntegratorKind::Implicit, IntegratorKind::Static] {
        let mut sim = default_with(kind).build().unwrap();
        let flag = Arc::new(AtomicBool::new(true));
        sim.integrator.set_interrupt(flag);
        let report = sim.tick();
        assert_eq!(report.cg_iterations, 0, "{kind:?}");
        assert!(!report.converged, "{kind:?}: gravity needs iterations");
    }
}

#[test]
fn a_tolerance_below_round_off_never_converges_and_stays_finite() {
    let mut scene = default_with(IntegratorKind::Implicit);
    scene.mechanics.cg_tolerance = 1e-300;
    scene.mechanics.cg_max_iterations = 5_000;
    let mut sim = scene.build().unwrap();
    for _ in 0..10 {
        let report = sim.tick();
        assert!(!report.converged);
        assert!(
            sim.state.x.iter().all(|p| p.iter().all(|c| c.is_finite())),
            "tick {}: {report:?}",
            sim.tick
        );
    }
}
