//! The integrators with the corotational model: the rotated patch test, agreement
//! with the linear model at small load, a large rigid turn, reactions and energy.

use nalgebra::{Matrix3, Point3, Rotation3, Vector3};

use super::tests::hanging_box;
use super::*;
use crate::engine::elastic::{ElasticModel, Formulation, TANGENT_TURN};
use crate::engine::material::Material;
use crate::engine::mesh::TetMesh;
use crate::engine::testing::{box_mesh, liver_mesh};

fn model_of(mesh: &TetMesh, nu: f64, formulation: Formulation) -> ElasticModel {
    let mat = Material {
        young_modulus: 4000.0,
        poisson_ratio: nu,
        density: 1000.0,
    };
    ElasticModel::with_formulation(mesh, vec![mat], vec![0; mesh.tets.len()], formulation)
}

fn integrator(kind: IntegratorKind, model: &ElasticModel, tol: f64) -> Integrator {
    Integrator::new(
        IntegratorConfig {
            kind,
            cg_tolerance: tol,
            cg_max_iterations: 20_000,
            ..IntegratorConfig::default()
        },
        model,
    )
}

/// Rotated patch test: the surface is imposed on `x = Q (X + G X) + c`, a strain
/// `G` turned by 90°. Every element then has the same `F = Q (I + G)`, the same
/// rotation and stress, so the interior forces cancel and the static answer inside
/// is that same affine field, exactly. (So it is for the linear model, for which any
/// affine displacement is a patch solution; what differs is that its strain, and so
/// its energy and reactions, would include the turn.)
fn rotated_patch_test(mesh: &TetMesh, nu: f64) {
    let q = Rotation3::new(Vector3::new(0.3, -0.5, 0.8).normalize() * std::f64::consts::FRAC_PI_2);
    let g = Matrix3::new(0.02, -0.01, 0.005, 0.003, -0.015, 0.0, 0.01, 0.002, 0.03);
    let c = Vector3::new(0.001, -0.002, 0.0005);
    let exact = |p: &Point3<f64>| q * (p + g * p.coords) + c;
    {
        let model = model_of(mesh, nu, Formulation::Corotational);
        let mut imposed = Imposed::new(mesh.vertex_count());
        for &s in &mesh.surface.vertices {
            imposed.set(s, exact(&model.rest[s as usize]));
        }
        let mut it = integrator(IntegratorKind::Static, &model, 1e-14);
        let mut state = State::at_rest(&model);
        // Start from the rigid turn alone: the solve must find the strain.
        for (x, r) in state.x.iter_mut().zip(&model.rest) {
            *x = q * r + c;
        }
        let report = it.solve_static(&model, &mut state, &imposed, Vector3::zeros());
        assert!(report.converged, "{report:?}");
        let strain_scale = mesh
            .positions
            .iter()
            .map(|p| (g * p.coords).norm())
            .fold(0.0, f64::max);
        let err = mesh
            .positions
            .iter()
            .zip(&state.x)
            .map(|(p, x)| (x - exact(p)).norm())
            .fold(0.0, f64::max);
        assert!(
            err <= 1e-9 * strain_scale,
            "patch error {:e}",
            err / strain_scale
        );
    }
}

#[test]
fn rotated_patch_test_on_a_structured_box() {
    rotated_patch_test(&box_mesh([4, 3, 3], [0.1, 0.06, 0.05]), 0.3);
}

#[test]
fn rotated_patch_test_on_the_irregular_liver_near_incompressible() {
    rotated_patch_test(&liver_mesh(), 0.49);
}

#[test]
fn corotational_equals_linear_at_small_load() {
    // Gravity of 1e-6 m/s² bends the bar by about 1e-9 of its length: the
    // corotational and linear answers (static, and a few implicit and explicit
    // ticks) agree to 1e-6 of the displacement.
    let (mesh, imposed) = hanging_box();
    let g = Vector3::new(0.0, -1e-6, 0.0);
    for kind in [
        IntegratorKind::Static,
        IntegratorKind::Implicit,
        IntegratorKind::Explicit,
    ] {
        let mut finals = Vec::new();
        for formulation in [Formulation::Linear, Formulation::Corotational] {
            let model = model_of(&mesh, 0.45, formulation);
            let mut it = integrator(kind, &model, 1e-12);
            let mut state = State::at_rest(&model);
            for _ in 0..5 {
                it.step(&model, &mut state, &imposed, g, 0.01);
            }
            let u: Vec<_> = state
                .x
                .iter()
                .zip(&model.rest)
                .map(|(x, r)| x - r)
                .collect();
            finals.push((u, state.reaction.clone()));
        }
        let scale = finals[0].0.iter().map(|u| u.norm()).fold(0.0, f64::max);
        let diff = finals[0]
            .0
            .iter()
            .zip(&finals[1].0)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        assert!(
            scale > 0.0 && diff <= 1e-6 * scale,
            "{kind:?}: {:e}",
            diff / scale
        );
        let r_scale = finals[0].1.iter().map(|r| r.norm()).fold(0.0, f64::max);
        let r_diff = finals[0]
            .1
            .iter()
            .zip(&finals[1].1)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        assert!(
            r_diff <= 1e-6 * r_scale,
            "{kind:?} reaction: {:e}",
            r_diff / r_scale
        );
    }
}

#[test]
fn a_body_turned_by_its_supports_stays_unstrained() {
    // Every vertex of the bar imposed on a 90° turn about its end, reached over 20
    // implicit ticks, then all but the end face released: with no gravity the
    // corotational bar is left at rest in its turned shape with no reaction, where
    // the linear one springs back.
    let (mesh, imposed_end) = hanging_box();
    let model = model_of(&mesh, 0.45, Formulation::Corotational);
    let mut it = integrator(IntegratorKind::Implicit, &model, 1e-12);
    let mut state = State::at_rest(&model);
    let mut imposed = Imposed::new(mesh.vertex_count());
    let steps = 20;
    for k in 1..=steps {
        let q =
            Rotation3::new(Vector3::z() * std::f64::consts::FRAC_PI_2 * k as f64 / steps as f64);
        for (i, p) in mesh.positions.iter().enumerate() {
            imposed.set(i as u32, q * p);
        }
        it.step(&model, &mut state, &imposed, Vector3::zeros(), 0.01);
    }
    let q = Rotation3::new(Vector3::z() * std::f64::consts::FRAC_PI_2);
    let mut held = Imposed::new(mesh.vertex_count());
    for &i in imposed_end.list() {
        held.set(i, q * mesh.positions[i as usize]);
    }
    state.v.iter_mut().for_each(|v| *v = Vector3::zeros());
    for _ in 0..10 {
        it.step(&model, &mut state, &held, Vector3::zeros(), 0.01);
    }
    let drift = mesh
        .positions
        .iter()
        .zip(&state.x)
        .map(|(p, x)| (x - q * p).norm())
        .fold(0.0, f64::max);
    assert!(drift <= 1e-9 * 0.1, "turned bar moved by {drift} m");
    let reaction = state.reaction.iter().map(|r| r.norm()).fold(0.0, f64::max);
    assert!(reaction <= 1e-9, "reaction {reaction} N");
    assert!(mechanical_energy(&model, &state, Vector3::zeros()) <= 1e-18);
}

/// The hanging bar, corotational and soft enough (E = 30 kPa) to droop by about a
/// third of its length under gravity: its supports and model.
fn soft_bar() -> (TetMesh, Imposed, ElasticModel) {
    let (mesh, imposed) = hanging_box();
    let mat = Material {
        young_modulus: 3e4,
        poisson_ratio: 0.45,
        density: 1000.0,
    };
    let model = ElasticModel::with_formulation(
        &mesh,
        vec![mat],
        vec![0; mesh.tets.len()],
        Formulation::Corotational,
    );
    (mesh, imposed, model)
}

#[test]
fn corotational_implicit_euler_never_gains_energy() {
    // The rotations frozen over a tick, backward Euler still dissipates: the bar,
    // soft enough to droop by about a third of its length under gravity (an end
    // rotation near 30°), never gains
    // mechanical energy (corotated strain energy) beyond the lag of the frozen
    // rotations, and settles on the static answer.
    let (_, imposed, model) = soft_bar();
    let g = Vector3::new(0.0, -9.81, 0.0);
    let mut reference = State::at_rest(&model);
    let report = integrator(IntegratorKind::Static, &model, 1e-9).solve_static(
        &model,
        &mut reference,
        &imposed,
        g,
    );
    assert!(report.converged, "{report:?}");
    let sag = reference
        .x
        .iter()
        .zip(&model.rest)
        .map(|(x, r)| (x - r).norm())
        .fold(0.0, f64::max);
    assert!(sag > 0.02, "the soft bar droops by {sag} m");
    println!("static: {report:?}, sag {sag}");
    let mut it = integrator(IntegratorKind::Implicit, &model, 1e-10);
    let mut state = State::at_rest(&model);
    let mut last = 0.0;
    let e_static = mechanical_energy(&model, &reference, g);
    for _ in 0..300 {
        it.step(&model, &mut state, &imposed, g, 0.01);
        let e = mechanical_energy(&model, &state, g);
        assert!(
            e <= last + 1e-3 * e_static.abs(),
            "energy rose from {last} to {e}"
        );
        last = e;
    }
    let off = state
        .x
        .iter()
        .zip(&reference.x)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(off <= 1e-3 * sag, "settled {off} m from the static answer");
}

#[test]
fn a_kept_tangent_moves_the_drooping_bar_as_the_exact_one_does() {
    // The soft bar of the test above, dropped under gravity, once with each
    // element's share of K̂ kept until it turns by TANGENT_TURN and once with K̂
    // reassembled every tick. The force is exact in both, so only each tick's step
    // differs, by at most about 2·turn of the step (the tangent's relative error):
    // the two paths may part by about 2·turn times the distance travelled, and must
    // end on the same static answer.
    let (mesh, imposed, model) = soft_bar();
    let g = Vector3::new(0.0, -9.81, 0.0);
    let mut kept = integrator(IntegratorKind::Implicit, &model, 1e-10);
    let mut exact = integrator(IntegratorKind::Implicit, &model, 1e-10);
    exact.set_tangent_turn(0.0);
    let (mut a, mut b) = (State::at_rest(&model), State::at_rest(&model));
    let (mut travelled, mut widest, mut fewest) = (0.0, 0.0f64, usize::MAX);
    for _ in 0..300 {
        let before = b.x.clone();
        kept.step(&model, &mut a, &imposed, g, 0.01);
        exact.step(&model, &mut b, &imposed, g, 0.01);
        travelled += before
            .iter()
            .zip(&b.x)
            .map(|(p, q)| (p - q).norm())
            .fold(0.0, f64::max);
        let apart =
            a.x.iter()
                .zip(&b.x)
                .map(|(p, q)| (p - q).norm())
                .fold(0.0, f64::max);
        widest = widest.max(apart / travelled.max(f64::MIN_POSITIVE));
        fewest = fewest.min(kept.tangent_reassembled());
        assert_eq!(exact.tangent_reassembled(), mesh.tets.len());
    }
    println!("widest parting {widest:e} of the path, fewest shares reassembled {fewest}");
    assert!(
        widest <= 2.0 * TANGENT_TURN,
        "parted by {widest:e} of the path"
    );
    assert!(fewest < mesh.tets.len() / 2, "kept too little: {fewest}");
    let end =
        a.x.iter()
            .zip(&b.x)
            .map(|(p, q)| (p - q).norm())
            .fold(0.0, f64::max);
    assert!(end <= 1e-6 * travelled, "ended {end} m apart");
}
