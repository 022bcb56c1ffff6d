//! Reaction forces on the default liver: a steady push held still gives a steady force
//! out of the tissue that grows with depth and with Young's modulus, for both force
//! models; withdrawing gives none.

mod common;

use common::contact::*;
use laparo_server::engine::local_model::ForceModelKind;
use laparo_server::engine::scene::Scene;
use nalgebra::Vector3;

/// What a tip press into the front of the default liver gave.
struct Press {
    /// The server's force at each tick of the hold, N.
    hold: Vec<Vector3<f64>>,
    /// The force once withdrawn and once out of the body.
    withdrawn: [Vector3<f64>; 2],
}

/// Settles the default liver (modulus `e`, force model `kind`), pushes the tip along
/// −z into its front face to `depth` past the surface over 0.5 s, holds 0.5 s, backs
/// out over 0.25 s and leaves.
fn press(kind: ForceModelKind, e: f64, depth: f64) -> Press {
    let mut scene = Scene::default_scene();
    scene.material.young_modulus = e;
    scene.force_model.kind = kind;
    let mut sim = scene.build().unwrap();
    for _ in 0..60 {
        sim.tick();
    }
    let front = front_point(&sim);
    let (x, y, z0) = (front.x, front.y, front.z + 0.01);
    let mut hold = Vec::new();
    let mut withdrawn = [Vector3::repeat(f64::NAN); 2];
    for k in 0..100 {
        let t = k as f64 / 60.0;
        let z = if t < 0.5 {
            z0 - (0.01 + depth) * t / 0.5
        } else if t < 1.0 {
            z0 - 0.01 - depth
        } else {
            (z0 - 0.01 - depth + (0.01 + depth) * (t - 1.0) / 0.25).min(z0)
        };
        let in_body = t < 1.5;
        sim.set_pose(0, in_body.then(|| pose([x, y, z], [0.0, 0.0, 1.0])));
        sim.tick();
        let force = sim.forces.as_ref().unwrap().forces[0].force;
        if (0.75..1.0).contains(&t) {
            hold.push(force);
        }
        if k == 88 {
            withdrawn[0] = force;
        }
        if k == 99 {
            withdrawn[1] = force;
        }
    }
    Press { hold, withdrawn }
}

/// Largest relative spread of the force magnitude over a hold.
fn spread(hold: &[Vector3<f64>]) -> f64 {
    let (lo, hi) = hold.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), f| {
        (lo.min(f.norm()), hi.max(f.norm()))
    });
    (hi - lo) / hi
}

#[test]
fn a_steady_push_gives_a_steady_force_growing_with_depth_and_stiffness() {
    for kind in [ForceModelKind::Geometric, ForceModelKind::Calibrated] {
        let base = press(kind, 4500.0, 0.006);
        let deeper = press(kind, 4500.0, 0.012);
        let stiffer = press(kind, 18000.0, 0.006);
        for (name, p) in [("base", &base), ("deeper", &deeper), ("stiffer", &stiffer)] {
            let last = p.hold.last().unwrap();
            // Out of the front face (+z), non-zero, steady to 2% while held still.
            assert!(last.z > 0.05, "{kind:?} {name}: {last}");
            assert!(last.z > 0.8 * last.norm(), "{kind:?} {name}: {last}");
            assert!(
                spread(&p.hold) < 0.02,
                "{kind:?} {name}: spread {}",
                spread(&p.hold)
            );
            // Withdrawn (still in the body, in front of the liver) and gone: nothing.
            assert_eq!(p.withdrawn, [Vector3::zeros(); 2], "{kind:?} {name}");
        }
        let f = |p: &Press| p.hold.last().unwrap().norm();
        // Twice the depth past the surface (the indentation is depth + r: 11 → 17 mm).
        assert!(
            f(&deeper) > 1.3 * f(&base),
            "{kind:?}: {} vs {}",
            f(&deeper),
            f(&base)
        );
        // Four times the modulus: the geometric λ scales with E exactly, and the
        // elastic model's reaction at the same indentation with it too (linear
        // elasticity, gravity aside).
        assert!(
            f(&stiffer) > 3.0 * f(&base),
            "{kind:?}: {} vs {}",
            f(&stiffer),
            f(&base)
        );
    }
}

#[test]
fn a_steady_sideways_shaft_push_holds_a_steady_force() {
    // The shaft lying across the front face (axis −x), pushed 3 cm along −z into it
    // over 2 s, then held 1.5 s. Tissue on the shaft's flanks is dragged harder than
    // friction allows and slides; it must not flip between held and free.
    for kind in [ForceModelKind::Geometric, ForceModelKind::Calibrated] {
        let mut scene = Scene::default_scene();
        scene.force_model.kind = kind;
        let mut sim = scene.build().unwrap();
        for _ in 0..60 {
            sim.tick();
        }
        let f = front_point(&sim);
        let mut hold = Vec::new();
        for k in 0..210 {
            let t = k as f64 / 60.0;
            let z = f.z + 0.02 - 0.03 * (t / 2.0).min(1.0);
            sim.set_pose(0, Some(pose([f.x + 0.06, f.y, z], [-1.0, 0.0, 0.0])));
            sim.tick();
            let stage = sim.forces.as_ref().unwrap();
            if t >= 2.75 {
                assert!(stage.models[0].shaft_plane.is_some(), "{kind:?} tick {k}");
                hold.push(stage.forces[0].force);
            }
        }
        let last = hold.last().unwrap();
        assert!(last.z > 0.5, "{kind:?}: {last}");
        assert!(spread(&hold) < 0.03, "{kind:?}: spread {}", spread(&hold));
    }
}

#[test]
fn a_deep_tip_press_renders_the_reaction_on_every_liver() {
    // The tip, axis +z, pressed 15 mm past the free front over 0.5 s and held: the
    // default scene's force model (calibrated) renders the tissue's reaction
    // whatever the mesh. On a fine liver the tissue wraps around the tip, no
    // triangle stays on its axis and the nearest surface lies beside it; its held
    // vertices must still make a plane.
    // liver-80k, where that happened, runs when the shared meshes are found.
    let mut meshes = vec![
        "builtin:liver.msh".to_string(),
        common::LIVER_5K.to_string(),
    ];
    let dir = std::env::var_os("LAPARO_MESH_DIR")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/liver").into());
    let fine = dir.join("liver-80k.msh");
    if fine.exists() {
        meshes.push(fine.display().to_string());
    }
    for mesh in meshes {
        let mut scene = Scene::default_scene();
        scene.mesh.file = mesh.clone();
        let mut sim = scene.build().unwrap();
        for _ in 0..60 {
            sim.tick();
        }
        let f = front_point(&sim);
        let r = sim.instruments[0].radius;
        for k in 1..=60 {
            let z = f.z + r + 0.01 - 0.025 * (k as f64 / 30.0).min(1.0);
            sim.set_pose(0, Some(pose([f.x, f.y, z], [0.0, 0.0, 1.0])));
            sim.tick();
        }
        let ins = &sim.instruments[0];
        let reaction = ins.report.reaction;
        let rendered = sim.forces.as_ref().unwrap().forces[0].force;
        let case = format!(
            "{mesh}: {} held, reaction {:.3} N, rendered {:.3} N",
            ins.held.len(),
            reaction.norm(),
            rendered.norm()
        );
        println!("{case}");
        assert!(!ins.held.is_empty() && reaction.norm() > 0.1, "{case}");
        assert!(
            (rendered - reaction).norm() <= 0.05 * reaction.norm(),
            "{case}"
        );
    }
}
