use nalgebra::{Matrix3, Vector3};

use super::*;
use crate::engine::elastic::ElasticModel;
use crate::engine::material::Material;
use crate::engine::mesh::TetMesh;
use crate::engine::testing::{box_mesh, liver_mesh};

fn model_of(mesh: &TetMesh, e: f64, nu: f64, rho: f64) -> ElasticModel {
    let mat = Material {
        young_modulus: e,
        poisson_ratio: nu,
        density: rho,
    };
    ElasticModel::new(mesh, vec![mat], vec![0; mesh.tets.len()])
}

fn config(kind: IntegratorKind) -> IntegratorConfig {
    IntegratorConfig {
        kind,
        ..IntegratorConfig::default()
    }
}

/// Patch test: impose an affine displacement `u = G X + c` on every surface vertex;
/// the static solution inside must be the same affine field, since P1 elements
/// represent it exactly and it is in equilibrium without body force.
fn patch_test(mesh: &TetMesh, nu: f64) {
    let model = model_of(mesh, 4000.0, nu, 1000.0);
    let g = Matrix3::new(0.02, -0.01, 0.005, 0.003, -0.015, 0.0, 0.01, 0.002, 0.03);
    let c = Vector3::new(0.001, -0.002, 0.0005);
    let exact = |i: usize| g * model.rest[i].coords + c;
    let mut imposed = Imposed::new(mesh.vertex_count());
    for &s in &mesh.surface.vertices {
        imposed.set(s, model.rest[s as usize] + exact(s as usize));
    }
    let mut it = Integrator::new(
        IntegratorConfig {
            cg_tolerance: 1e-15,
            cg_max_iterations: 20_000,
            ..config(IntegratorKind::Static)
        },
        &model,
    );
    let mut state = State::at_rest(&model);
    let interior = (0..mesh.vertex_count())
        .filter(|&i| !imposed.is_imposed(i))
        .count();
    assert!(interior > 0, "the patch needs interior vertices");
    it.solve_static(&model, &mut state, &imposed, Vector3::zeros());
    let scale = (0..mesh.vertex_count())
        .map(|i| exact(i).norm())
        .fold(0.0, f64::max);
    let err = (0..mesh.vertex_count())
        .map(|i| (state.x[i] - model.rest[i] - exact(i)).norm())
        .fold(0.0, f64::max);
    assert!(
        err <= 1e-9 * scale,
        "patch test error {:e} (relative)",
        err / scale
    );
}

#[test]
fn patch_test_on_a_structured_box() {
    patch_test(&box_mesh([4, 3, 3], [0.1, 0.06, 0.05]), 0.3);
}

#[test]
fn patch_test_on_the_irregular_liver_near_incompressible() {
    patch_test(&liver_mesh(), 0.49);
}

pub(super) fn hanging_box() -> (TetMesh, Imposed) {
    // A 10 × 2 × 2 cm bar held at its x = 0 face.
    let mesh = box_mesh([10, 2, 2], [0.1, 0.02, 0.02]);
    let mut imposed = Imposed::new(mesh.vertex_count());
    for (i, p) in mesh.positions.iter().enumerate() {
        if p.x == 0.0 {
            imposed.set(i as u32, *p);
        }
    }
    (mesh, imposed)
}

#[test]
fn reaction_on_supports_balances_the_weight_at_equilibrium() {
    // 1ᵀ K u = 0 (translations are in K's null space), so at equilibrium
    // Σ_supports −(K u)_c = Σ_free m_f g: the supports carry the weight of the rest.
    let (mesh, imposed) = hanging_box();
    let model = model_of(&mesh, 50_000.0, 0.45, 1060.0);
    let g = Vector3::new(0.0, -9.81, 0.0);
    let mut it = Integrator::new(
        IntegratorConfig {
            cg_tolerance: 1e-12,
            ..config(IntegratorKind::Static)
        },
        &model,
    );
    let mut state = State::at_rest(&model);
    it.solve_static(&model, &mut state, &imposed, g);
    let on_supports: Vector3<f64> = imposed
        .list()
        .iter()
        .map(|&c| state.reaction[c as usize])
        .sum();
    let free_weight: Vector3<f64> = (0..mesh.vertex_count())
        .filter(|&i| !imposed.is_imposed(i))
        .map(|i| model.mass[i] * g)
        .sum();
    assert!(
        (on_supports - free_weight).norm() <= 1e-8 * free_weight.norm(),
        "{on_supports} vs {free_weight}"
    );
    assert!(
        state
            .reaction
            .iter()
            .enumerate()
            .all(|(i, r)| imposed.is_imposed(i) || *r == Vector3::zeros())
    );
}

#[test]
fn implicit_euler_never_gains_energy() {
    // Backward Euler on a linear damped system dissipates: E(n+1) ≤ E(n), for any h.
    let (mesh, imposed) = hanging_box();
    let model = model_of(&mesh, 20_000.0, 0.45, 1060.0);
    let g = Vector3::new(0.0, -9.81, 0.0);
    for dt in [0.001, 0.02, 0.05] {
        let mut it = Integrator::new(
            IntegratorConfig {
                cg_tolerance: 1e-10,
                ..config(IntegratorKind::Implicit)
            },
            &model,
        );
        let mut state = State::at_rest(&model);
        let mut last = mechanical_energy(&model, &state, g);
        for _ in 0..(0.5 / dt) as usize {
            it.step(&model, &mut state, &imposed, g, dt);
            let e = mechanical_energy(&model, &state, g);
            assert!(
                e <= last + 1e-9 * last.abs().max(1e-12),
                "energy rose from {last} to {e} at dt {dt}"
            );
            last = e;
        }
        assert!(last < 0.0, "the bar sagged and lost potential energy");
    }
}

#[test]
fn explicit_substeps_follow_the_square_root_of_stiffness() {
    // K is linear in E, so ω_max ∝ √E and the stable substep ∝ 1/√E: a hundred times
    // stiffer tissue takes ten times as many substeps, whatever the mesh.
    let mesh = liver_mesh();
    let soft = Integrator::new(
        config(IntegratorKind::Explicit),
        &model_of(&mesh, 3000.0, 0.45, 1000.0),
    );
    let stiff = Integrator::new(
        config(IntegratorKind::Explicit),
        &model_of(&mesh, 300_000.0, 0.45, 1000.0),
    );
    let ratio = soft.explicit_h_max / stiff.explicit_h_max;
    assert!((ratio - 10.0).abs() <= 1e-9 * 10.0, "ratio {ratio}");
    let dt = 1.0;
    let (a, b) = (
        soft.explicit_substeps(dt) as f64,
        stiff.explicit_substeps(dt) as f64,
    );
    assert!(
        (b / a - 10.0).abs() <= 10.0 / a + 1e-9,
        "substeps {a} and {b}"
    );
}

#[test]
fn imposed_vertices_reach_their_targets_at_the_end_of_a_tick() {
    let (mesh, mut imposed) = hanging_box();
    let model = model_of(&mesh, 20_000.0, 0.45, 1060.0);
    // Pull the far face 5 mm along +x.
    let pulled: Vec<u32> = (0..mesh.vertex_count() as u32)
        .filter(|&i| mesh.positions[i as usize].x >= 0.1 - 1e-12)
        .collect();
    for &i in &pulled {
        imposed.set(
            i,
            mesh.positions[i as usize] + Vector3::new(0.005, 0.0, 0.0),
        );
    }
    for kind in [
        IntegratorKind::Explicit,
        IntegratorKind::Implicit,
        IntegratorKind::Static,
    ] {
        let mut it = Integrator::new(config(kind), &model);
        let mut state = State::at_rest(&model);
        it.step(&model, &mut state, &imposed, Vector3::zeros(), 0.01);
        for &i in imposed.list() {
            assert!(
                (state.x[i as usize] - imposed.target(i as usize)).norm() <= 1e-15,
                "{kind:?}"
            );
        }
        // The pulled face feels the tissue pulling back (−x), the held face is pulled +x.
        let pull: f64 = pulled.iter().map(|&i| state.reaction[i as usize].x).sum();
        assert!(pull < 0.0, "{kind:?}: reaction on the pulled face {pull}");
        // Free vertices follow the pull.
        let mid = (0..mesh.vertex_count())
            .find(|&i| (mesh.positions[i].x - 0.05).abs() < 1e-12)
            .unwrap();
        assert!(state.x[mid].x > mesh.positions[mid].x, "{kind:?}");
    }
}

#[test]
fn released_vertices_are_free_again() {
    let mut imposed = Imposed::new(5);
    for i in [3, 1, 4] {
        imposed.set(i, nalgebra::Point3::new(i as f64, 0.0, 0.0));
    }
    imposed.release(1);
    imposed.release(1);
    let mut list = imposed.list().to_vec();
    list.sort();
    assert_eq!(list, vec![3, 4]);
    assert!(!imposed.is_imposed(1) && imposed.is_imposed(4));
    imposed.release(4);
    imposed.set(0, nalgebra::Point3::origin());
    let mut list = imposed.list().to_vec();
    list.sort();
    assert_eq!(list, vec![0, 3]);
}
