//! The contact stage on the default liver: pressing with the tip and the shaft,
//! holding, withdrawing, and the invariants after every tick.

mod common;

use common::contact::*;
use laparo_server::engine::contact::InstrumentPose;
use laparo_server::engine::integrate::IntegratorKind;
use laparo_server::engine::scene::Scene;
use laparo_server::engine::simulation::Simulation;

#[test]
fn tip_press_deforms_holds_and_releases() {
    tip_press(IntegratorKind::Implicit);
}

#[test]
fn tip_press_with_the_explicit_integrator() {
    // Held vertices move along their targets over the explicit substeps.
    tip_press(IntegratorKind::Explicit);
}

fn tip_press(integrator: IntegratorKind) {
    let mut scene = Scene::default_scene();
    scene.mechanics.integrator = integrator;
    let mut sim = scene.build().unwrap();
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
        let ins = &sim.instruments[0];
        // The report carries each held vertex's reaction, and they add up to the force.
        assert_eq!(ins.report.held_reactions.len(), ins.held.len());
        let sum: nalgebra::Vector3<f64> = ins.report.held_reactions.iter().sum();
        assert!((sum - ins.report.reaction).norm() <= 1e-12 * (1.0 + sum.norm()));
        forces.push(ins.report.reaction);
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

/// Runs `frames` (one pose per instrument per tick) and checks the invariants after
/// every tick.
fn run_checked(
    sim: &mut Simulation,
    frames: impl IntoIterator<Item = Vec<Option<InstrumentPose>>>,
) {
    for poses in frames {
        for (k, p) in poses.into_iter().enumerate() {
            sim.set_pose(k, p);
        }
        sim.tick();
        if let Err(e) = check_invariants(sim) {
            panic!("{e}");
        }
    }
}

/// Linear interpolation of a tip between two points over `n` ticks.
fn sweep(
    from: [f64; 3],
    to: [f64; 3],
    axis: [f64; 3],
    n: usize,
) -> impl Iterator<Item = InstrumentPose> {
    (1..=n).map(move |k| {
        let s = k as f64 / n as f64;
        pose([0, 1, 2].map(|a| from[a] + (to[a] - from[a]) * s), axis)
    })
}

#[test]
fn shaft_pressing_sideways_deforms_the_liver_with_the_tip_outside() {
    // The shaft lies along x in front of the liver's front face, its tip beyond the
    // liver's −x end, and moves 1 cm into the face: the gesture a point-contact
    // simulator cannot make.
    for shaft in [true, false] {
        let mut scene = Scene::default_scene();
        scene.instruments[0].shaft_contact = shaft;
        let mut sim = scene.build().unwrap();
        for _ in 0..60 {
            sim.tick();
        }
        let before = sim.state.x.clone();
        let front = front_point(&sim);
        let (lo, _) = sim.mesh.bounding_box();
        let tip_x = lo.x - 0.03;
        let z0 = front.z + 0.008;
        let frames = sweep(
            [tip_x, front.y, z0],
            [tip_x, front.y, z0 - 0.018],
            [1.0, 0.0, 0.0],
            30,
        )
        .chain(std::iter::repeat_n(
            pose([tip_x, front.y, z0 - 0.018], [1.0, 0.0, 0.0]),
            30,
        ))
        .map(|p| vec![Some(p), None]);
        run_checked(&mut sim, frames);
        let pushed = sim
            .state
            .x
            .iter()
            .zip(&before)
            .map(|(a, b)| b.z - a.z)
            .fold(0.0, f64::max);
        let stats = sim.contact.as_ref().unwrap().stats();
        let report = &sim.instruments[0].report;
        assert!(report.tip.is_none(), "the tip stays outside the liver");
        if shaft {
            assert!(
                pushed > 0.005,
                "the shaft pushed the face back by only {pushed} m"
            );
            assert!(stats.edge_tests > 0 && !sim.instruments[0].held.is_empty());
            assert!(
                report.reaction.z > 0.0,
                "the tissue pushes the shaft back: {:?}",
                report.reaction
            );
            assert!(!report.shaft_edges.is_empty());
        } else {
            // Without shaft contact the instrument is its tip alone: the shaft passes
            // through the tissue, and the stage tests no edge at all.
            assert!(pushed < 1e-3, "moved {pushed} m without shaft contact");
            assert_eq!(stats.edge_tests, 0);
            assert!(sim.instruments[0].held.is_empty());
        }
    }
}

#[test]
fn a_scene_without_instruments_builds_no_contact_stage() {
    let mut scene = Scene::default_scene();
    scene.instruments.clear();
    let mut sim = scene.build().unwrap();
    sim.tick();
    assert!(sim.contact.is_none() && sim.instruments.is_empty());
    let mut scene = Scene::default_scene();
    for ins in &mut scene.instruments {
        ins.tip_contact = false;
        ins.shaft_contact = false;
    }
    assert!(
        scene.build().unwrap().contact.is_none(),
        "instruments that push nothing need no stage"
    );
}
