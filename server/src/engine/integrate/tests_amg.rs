//! The multigrid preconditioner inside the solves: the same answers as block Jacobi,
//! and iterations that do not grow with the mesh.

use nalgebra::Vector3;

use super::*;
use crate::engine::elastic::ElasticModel;
use crate::engine::material::Material;
use crate::engine::scene::Scene;
use crate::engine::simulation::Simulation;
use crate::engine::testing::box_mesh;

const LIVER_5K: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/meshes/liver-5k.msh");

fn default_scene_on(mesh: &str, preconditioner: PreconditionerKind, tolerance: f64) -> Simulation {
    let mut scene = Scene::default_scene();
    scene.mesh.file = mesh.to_string();
    scene.mechanics.preconditioner = preconditioner;
    scene.mechanics.cg_tolerance = tolerance;
    scene.build().expect("the scene builds")
}

/// Largest relative difference of two position sets' displacements from rest.
fn relative_difference(
    model: &ElasticModel,
    a: &[nalgebra::Point3<f64>],
    b: &[nalgebra::Point3<f64>],
) -> f64 {
    let scale = a
        .iter()
        .zip(&model.rest)
        .map(|(x, r)| (x - r).norm())
        .fold(0.0, f64::max);
    let diff = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - y).norm())
        .fold(0.0, f64::max);
    diff / scale
}

#[test]
fn multigrid_and_block_jacobi_reach_the_same_implicit_step() {
    // Ten ticks of the gravity transient of liver-5k, solved tightly with either
    // preconditioner: the same trajectory to the solver's tolerance.
    let tight = 1e-10;
    let mut jacobi = default_scene_on(LIVER_5K, PreconditionerKind::BlockJacobi, tight);
    let mut amg = default_scene_on(LIVER_5K, PreconditionerKind::Amg, tight);
    for _ in 0..10 {
        let (a, b) = (jacobi.tick(), amg.tick());
        assert!(a.converged && b.converged, "{a:?} {b:?}");
    }
    assert!(!jacobi.integrator.used_amg() && amg.integrator.used_amg());
    let d = relative_difference(&jacobi.model, &jacobi.state.x, &amg.state.x);
    assert!(d < 1e-7, "tight solves differ by {d:e}");
    // At the default tolerance each stays close to the tight answer.
    let mut loose = default_scene_on(LIVER_5K, PreconditionerKind::Amg, 1e-4);
    for _ in 0..10 {
        assert!(loose.tick().converged);
    }
    let d = relative_difference(&jacobi.model, &jacobi.state.x, &loose.state.x);
    assert!(
        d < 1e-3,
        "1e-4 multigrid solves differ from tight ones by {d:e}"
    );
}

#[test]
fn multigrid_and_block_jacobi_reach_the_same_static_equilibrium() {
    let mut scene = Scene::default_scene();
    scene.mesh.file = LIVER_5K.to_string();
    scene.mechanics.integrator = IntegratorKind::Static;
    scene.mechanics.cg_tolerance = 1e-10;
    let mut jacobi = scene.clone();
    jacobi.mechanics.preconditioner = PreconditionerKind::BlockJacobi;
    scene.mechanics.preconditioner = PreconditionerKind::Amg;
    let (mut a, mut b) = (jacobi.build().unwrap(), scene.build().unwrap());
    let (ra, rb) = (a.tick(), b.tick());
    assert!(ra.converged && rb.converged, "{ra:?} {rb:?}");
    assert!(b.integrator.used_amg());
    assert!(
        rb.cg_iterations * 4 < ra.cg_iterations,
        "multigrid {} against block Jacobi {} iterations",
        rb.cg_iterations,
        ra.cg_iterations
    );
    let d = relative_difference(&a.model, &a.state.x, &b.state.x);
    assert!(d < 1e-7, "static solves differ by {d:e}");
}

/// The most CG iterations of the first `ticks` ticks of `sim`.
fn most_iterations(sim: &mut Simulation, ticks: usize) -> u32 {
    (0..ticks)
        .map(|_| {
            let r = sim.tick();
            assert!(r.converged, "{r:?}");
            r.cg_iterations
        })
        .max()
        .unwrap()
}

#[test]
fn multigrid_iterations_stay_flat_on_the_livers() {
    // The default scene's gravity transient at the default tolerance (1e-4).
    let mut counts = Vec::new();
    let mut meshes = vec!["builtin:liver.msh".to_string(), LIVER_5K.to_string()];
    // liver-20k lives beside the repository (too large to ship); used when present.
    let dir = std::env::var_os("LAPARO_MESH_DIR")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| {
            std::path::PathBuf::from(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../../shared/data/liver"
            ))
        });
    let big = dir.join("liver-20k.msh");
    if big.exists() {
        meshes.push(big.display().to_string());
    } else {
        eprintln!(
            "liver-20k not found at {}: checking the two shipped livers",
            big.display()
        );
    }
    for mesh in &meshes {
        let mut sim = default_scene_on(mesh, PreconditionerKind::Amg, 1e-4);
        counts.push(most_iterations(&mut sim, 10));
    }
    let (sofa, five) = (counts[0], counts[1]);
    assert!(five <= 2 * sofa.max(2), "iterations {counts:?}");
    if let Some(&twenty) = counts.get(2) {
        assert!(twenty <= five + 3, "iterations {counts:?}");
    }
    // Block Jacobi on the same runs grows (what the multigrid removes).
    let mut sim = default_scene_on(LIVER_5K, PreconditionerKind::BlockJacobi, 1e-4);
    let jacobi_five = most_iterations(&mut sim, 10);
    assert!(
        jacobi_five > 2 * five,
        "block Jacobi {jacobi_five} against {counts:?}"
    );
}

#[test]
fn multigrid_iterations_stay_flat_on_refined_boxes() {
    // A 10 × 2.5 × 2.5 cm bar held at x = 0 under gravity, implicit at 60 Hz, on
    // nested Kuhn meshes of 2, 4 and 8 cells across (1, 8 and 64 times the elements).
    // A slender bar bends: its stiffness has a wide spectrum, so block Jacobi needs
    // many iterations and each refinement doubles them; multigrid's grow by at most
    // half while the element count grows 64-fold.
    let mut counts = Vec::new();
    let mut jacobi = Vec::new();
    for cells in [2usize, 4, 8] {
        let mesh = box_mesh([4 * cells, cells, cells], [0.1, 0.025, 0.025]);
        let material = Material {
            young_modulus: 5000.0,
            poisson_ratio: 0.45,
            density: 1060.0,
        };
        let model = ElasticModel::new(&mesh, vec![material], vec![0; mesh.tets.len()]);
        let mut imposed = Imposed::new(mesh.vertex_count());
        for (i, p) in mesh.positions.iter().enumerate() {
            if p.x == 0.0 {
                imposed.set(i as u32, *p);
            }
        }
        for (kind, out) in [
            (PreconditionerKind::Amg, &mut counts),
            (PreconditionerKind::BlockJacobi, &mut jacobi),
        ] {
            let config = IntegratorConfig {
                preconditioner: kind,
                ..IntegratorConfig::default()
            };
            let mut it = Integrator::new(config, &model);
            it.prepare(&model, imposed.mask(), 1.0 / 60.0);
            let mut state = State::at_rest(&model);
            let g = Vector3::new(0.0, -9.81, 0.0);
            let most = (0..10)
                .map(|_| {
                    let r = it.step(&model, &mut state, &imposed, g, 1.0 / 60.0);
                    assert!(r.converged, "{r:?}");
                    r.cg_iterations
                })
                .max()
                .unwrap();
            out.push(most);
        }
    }
    let report = format!("multigrid {counts:?}, block Jacobi {jacobi:?}");
    assert!(2 * counts[2] <= 3 * counts[0], "{report}");
    assert!(jacobi[2] > 3 * jacobi[0], "{report}");
}

#[test]
fn a_hierarchy_that_cannot_be_built_leaves_block_jacobi_in_charge() {
    // Tissue so soft that the mass term swamps every coupling: no two vertices are
    // strongly connected, there is nothing to aggregate, and the solve goes on with
    // block Jacobi (which is then nearly exact).
    let mesh = box_mesh([4, 2, 2], [0.1, 0.05, 0.05]);
    let material = Material {
        young_modulus: 1e-9,
        poisson_ratio: 0.3,
        density: 1000.0,
    };
    let model = ElasticModel::new(&mesh, vec![material], vec![0; mesh.tets.len()]);
    let config = IntegratorConfig {
        preconditioner: PreconditionerKind::Amg,
        ..IntegratorConfig::default()
    };
    let mut it = Integrator::new(config, &model);
    let imposed = Imposed::new(mesh.vertex_count());
    it.prepare(&model, imposed.mask(), 1.0 / 60.0);
    assert!(it.amg().is_none() && !it.used_amg());
    let mut state = State::at_rest(&model);
    let g = Vector3::new(0.0, -9.81, 0.0);
    for _ in 0..3 {
        let r = it.step(&model, &mut state, &imposed, g, 1.0 / 60.0);
        assert!(r.converged && !it.used_amg(), "{r:?}");
    }
    // Free fall: v = g t after three ticks, up to the damping (1 + hα per tick).
    let v = state.v[0];
    assert!(v.y < 0.0 && v.x.abs() < 1e-9 && v.z.abs() < 1e-9, "{v}");
}
