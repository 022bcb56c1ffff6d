//! A liver renumbered for locality is the same liver: supports given in file order
//! find the same vertices, and a press moves it as it moves the file's numbering.

use nalgebra::{Unit, Vector3};

use crate::engine::contact::InstrumentPose;
use crate::engine::elastic::Formulation;
use crate::engine::integrate::PreconditionerKind;
use crate::engine::mesh::reverse_cuthill_mckee;
use crate::engine::scene::Scene;
use crate::engine::simulation::Simulation;
use crate::engine::simulation::mesh::load;

#[test]
fn a_renumbered_liver_holds_and_moves_as_the_file_numbered_one() {
    let mut scene = Scene::default_scene();
    // Tight enough that the two runs differ by the order of their sums only.
    scene.mechanics.cg_tolerance = 1e-10;
    // Supports by file index, beside the scene's boxes.
    scene.fixed.nodes = vec![0, 5, 17];
    let file = load(&scene).unwrap();
    let n = file.vertex_count();
    let new = reverse_cuthill_mckee(n, &file.edges);
    assert!(new.iter().enumerate().any(|(v, &k)| v as u32 != k));
    let a = scene.build_on(file.clone()).unwrap();
    let b = scene.build_on(file.renumbered(&new)).unwrap();
    let renumber = |v: &u32| new[*v as usize];
    let mut fixed: Vec<u32> = a.fixed.iter().map(renumber).collect();
    fixed.sort_unstable();
    assert_eq!(fixed, b.fixed);
    for i in [0, 5, 17] {
        assert!(b.fixed.contains(&new[i]));
        assert_eq!(b.mesh.positions[new[i] as usize], file.positions[i]);
    }

    same_press(a, b, &new);
}

/// Two runs of one liver, `b` numbered `new[v]` for `a`'s vertex `v`: settled under
/// gravity, then the tip pressed 6 mm into the front and held, they hold the same
/// vertices, and their positions and reactions agree to 1e-6.
fn same_press(mut a: Simulation, mut b: Simulation, new: &[u32]) {
    let n = a.mesh.vertex_count();
    let renumber = |v: &u32| new[*v as usize];
    // Settle under gravity, then press the front with the tip 6 mm and hold.
    for _ in 0..30 {
        a.tick();
        b.tick();
    }
    // The liver's foremost point (largest z), pressed straight in.
    let front = *a.state.x.iter().max_by(|p, q| p.z.total_cmp(&q.z)).unwrap();
    let axis = Unit::new_normalize(Vector3::z());
    for k in 0..45 {
        let depth = 0.008 * (k.min(30) as f64 / 30.0) - 0.002;
        let pose = InstrumentPose::new(front - Vector3::z() * depth, axis);
        a.set_pose(0, Some(pose));
        b.set_pose(0, Some(pose));
        a.tick();
        b.tick();
    }
    let mut held_a: Vec<u32> = a.instruments[0].held.iter().map(renumber).collect();
    let mut held_b = b.instruments[0].held.clone();
    held_a.sort_unstable();
    held_b.sort_unstable();
    assert!(!held_a.is_empty());
    assert_eq!(held_a, held_b);
    let moved = (0..n)
        .map(|v| (a.state.x[v] - a.mesh.positions[v]).norm())
        .fold(0.0, f64::max);
    let apart = (0..n)
        .map(|v| (a.state.x[v] - b.state.x[new[v] as usize]).norm())
        .fold(0.0, f64::max);
    assert!(apart <= 1e-6 * moved, "apart {apart:e} m of {moved:e} m");
    let (fa, fb) = (
        a.instruments[0].report.reaction,
        b.instruments[0].report.reaction,
    );
    assert!(fa.norm() > 0.1);
    assert!((fa - fb).norm() <= 1e-6 * fa.norm(), "{fa} against {fb}");
}

/// A scene on two threads splits liver-5k (1,408 vertices) into two parts and is
/// renumbered when loaded (SOFA's liver, too small to split, is not); it moves as
/// the one-thread scene on the same numbering does: settled under gravity,
/// then five vertices of its front pulled 8 mm along −z and held (imposed directly,
/// so that the comparison is of the mechanics alone: the contact stage runs on one
/// thread whatever the scene says), positions and the imposed vertices' reactions
/// agree to 1e-8 (the runs differ by the order of some sums, and by where CG at
/// 1e-10 stops).
#[test]
fn two_threads_move_the_liver_as_one() {
    let mut sofa = Scene::default_scene();
    let file = load(&sofa).unwrap();
    sofa.mechanics.threads = 2;
    assert_eq!(
        load(&sofa).unwrap().positions,
        file.positions,
        "not renumbered"
    );
    // `auto` takes multigrid for liver-5k on one thread, block Jacobi on two.
    let mut scene = Scene::default_scene();
    scene.mesh.file = concat!(env!("CARGO_MANIFEST_DIR"), "/meshes/liver-5k.msh").into();
    assert!(scene.build().unwrap().integrator.used_amg());
    scene.mechanics.threads = 2;
    assert!(!scene.build().unwrap().integrator.used_amg());
    for model in [Formulation::Linear, Formulation::Corotational] {
        let mut scene = Scene::default_scene();
        scene.mesh.file = concat!(env!("CARGO_MANIFEST_DIR"), "/meshes/liver-5k.msh").into();
        scene.mechanics.preconditioner = PreconditionerKind::BlockJacobi;
        scene.material.model = model;
        scene.mechanics.cg_tolerance = 1e-10;
        let file = load(&scene).unwrap();
        let mesh = file.renumbered(&reverse_cuthill_mckee(file.vertex_count(), &file.edges));
        let mut a = scene.build_on(mesh.clone()).unwrap();
        scene.mechanics.threads = 2;
        let mut b = scene.build().unwrap();
        assert_eq!(b.mesh.positions, mesh.positions, "loaded renumbered");
        assert_eq!(b.integrator.parts(), 2);
        let n = mesh.vertex_count();
        let mut front: Vec<u32> = (0..n as u32).filter(|v| !a.fixed.contains(v)).collect();
        front.sort_by(|&p, &q| {
            mesh.positions[q as usize]
                .z
                .total_cmp(&mesh.positions[p as usize].z)
        });
        front.truncate(5);
        for k in 0..60 {
            if k >= 30 {
                let pull = Vector3::z() * (-0.008 * ((k - 29) as f64 / 20.0).min(1.0));
                for &v in &front {
                    let target = mesh.positions[v as usize] + pull;
                    a.imposed.set(v, target);
                    b.imposed.set(v, target);
                }
            }
            a.tick();
            b.tick();
        }
        let moved = (0..n)
            .map(|v| (a.state.x[v] - mesh.positions[v]).norm())
            .fold(0.0, f64::max);
        let apart = (0..n)
            .map(|v| (a.state.x[v] - b.state.x[v]).norm())
            .fold(0.0, f64::max);
        assert!(moved > 0.005, "{model:?}: moved {moved:e} m");
        assert!(
            apart <= 1e-8 * moved,
            "{model:?}: apart {apart:e} m of {moved:e} m"
        );
        let pull_a: Vector3<f64> = front.iter().map(|&v| a.state.reaction[v as usize]).sum();
        let pull_b: Vector3<f64> = front.iter().map(|&v| b.state.reaction[v as usize]).sum();
        assert!(pull_a.norm() > 0.1, "{model:?}: {pull_a}");
        assert!(
            (pull_a - pull_b).norm() <= 1e-8 * pull_a.norm(),
            "{pull_a} against {pull_b}"
        );
    }
}
