//! A scene whose solve reads its stiffness in f32 moves the liver as the f64 one,
//! to within what rounding the blocks to f32 changes (see
//! [`StiffnessStorage`](crate::engine::integrate::StiffnessStorage)).

use nalgebra::Vector3;

use crate::engine::elastic::Formulation;
use crate::engine::integrate::{PreconditionerKind, StiffnessStorage};
use crate::engine::scene::Scene;

/// How far the f32 run may lie from the f64 one, relative to the largest
/// displacement and to the pull's reaction. Only the solve's operator is rounded:
/// the elastic force `K u₀` (or `K̂ u₀ + o`) on the right-hand side is f64, so the
/// rounding (at most 2⁻²⁴ ≈ 6e-8 of each block entry) perturbs a tick's velocity
/// update, not the equilibrium the ticks settle to. The runs lie 0.9e-9 to 1.4e-9
/// apart (printed): 1e-7 leaves room for another machine's sums, while a copy of
/// `K̂` left at rest instead of refreshed each tick lies 1.1e-4 apart.
const APART: f64 = 1e-7;

#[test]
fn an_f32_stiffness_moves_the_liver_as_the_f64_one() {
    let liver_5k = concat!(env!("CARGO_MANIFEST_DIR"), "/meshes/liver-5k.msh");
    let (jacobi, multigrid) = (PreconditionerKind::BlockJacobi, PreconditionerKind::Amg);
    for (model, threads, preconditioner) in [
        (Formulation::Linear, 1, jacobi),
        (Formulation::Corotational, 1, jacobi),
        (Formulation::Corotational, 2, jacobi),
        (Formulation::Corotational, 1, multigrid),
    ] {
        let mut scene = Scene::default_scene();
        scene.mesh.file = liver_5k.into();
        scene.material.model = model;
        scene.mechanics.threads = threads;
        scene.mechanics.preconditioner = preconditioner;
        scene.mechanics.cg_tolerance = 1e-10;
        // `auto` keeps f64 on liver-5k (0.65 MB of blocks, a 2.4 MB hierarchy).
        let mut a = scene.build().unwrap();
        assert!(!a.integrator.reads_f32());
        assert!(a.integrator.amg().is_none_or(|h| !h.is_f32()));
        scene.mechanics.stiffness = StiffnessStorage::F32;
        let mut b = scene.build().unwrap();
        assert!(b.integrator.reads_f32());
        // The multigrid hierarchy follows the setting.
        assert_eq!(
            b.integrator.amg().map(|h| h.is_f32()),
            (preconditioner == multigrid).then_some(true)
        );
        let n = a.mesh.vertex_count();
        let mut front: Vec<u32> = (0..n as u32).filter(|v| !a.fixed.contains(v)).collect();
        front.sort_by(|&p, &q| {
            a.model.rest[q as usize]
                .z
                .total_cmp(&a.model.rest[p as usize].z)
        });
        front.truncate(5);
        for k in 0..60 {
            if k >= 30 {
                let pull = Vector3::z() * (-0.008 * ((k - 29) as f64 / 20.0).min(1.0));
                for &v in &front {
                    let target = a.model.rest[v as usize] + pull;
                    a.imposed.set(v, target);
                    b.imposed.set(v, target);
                }
            }
            a.tick();
            b.tick();
        }
        let moved = (0..n)
            .map(|v| (a.state.x[v] - a.model.rest[v]).norm())
            .fold(0.0, f64::max);
        let apart = (0..n)
            .map(|v| (a.state.x[v] - b.state.x[v]).norm())
            .fold(0.0, f64::max);
        let pull_a: Vector3<f64> = front.iter().map(|&v| a.state.reaction[v as usize]).sum();
        let pull_b: Vector3<f64> = front.iter().map(|&v| b.state.reaction[v as usize]).sum();
        println!(
            "{model:?}, {threads} thread(s): apart {:.1e} of the displacement, reactions {:.1e} apart",
            apart / moved,
            (pull_a - pull_b).norm() / pull_a.norm()
        );
        assert!(moved > 0.005, "{model:?}: moved {moved:e} m");
        assert!(apart > 0.0, "{model:?}: the f32 run is a different run");
        assert!(
            apart <= APART * moved,
            "{model:?}, {threads}: apart {apart:e} m of {moved:e} m"
        );
        assert!(pull_a.norm() > 0.1, "{model:?}: {pull_a}");
        assert!(
            (pull_a - pull_b).norm() <= APART * pull_a.norm(),
            "{model:?}, {threads}: {pull_a} against {pull_b}"
        );
    }
}
