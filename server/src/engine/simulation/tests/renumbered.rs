//! A liver renumbered for locality is the same liver: supports given in file order
//! find the same vertices, and a press moves it as it moves the file's numbering.

use nalgebra::{Unit, Vector3};

use crate::engine::contact::InstrumentPose;
use crate::engine::mesh::reverse_cuthill_mckee;
use crate::engine::scene::Scene;
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
    let mut a = scene.build_on(file.clone()).unwrap();
    let mut b = scene.build_on(file.renumbered(&new)).unwrap();
    let renumber = |v: &u32| new[*v as usize];
    let mut fixed: Vec<u32> = a.fixed.iter().map(renumber).collect();
    fixed.sort_unstable();
    assert_eq!(fixed, b.fixed);
    for i in [0, 5, 17] {
        assert!(b.fixed.contains(&new[i]));
        assert_eq!(b.mesh.positions[new[i] as usize], file.positions[i]);
    }

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
