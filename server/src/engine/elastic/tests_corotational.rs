//! The corotational force model: rigid motions, consistency of `K̂ u + o`, the energy
//! it derives from, and agreement with the linear model at small displacements.

use nalgebra::{Point3, Rotation3, Vector3};

use super::*;
use crate::engine::material::Material;
use crate::engine::testing::liver_mesh;

pub(super) fn models(mesh: &TetMesh, nu: f64) -> (ElasticModel, ElasticModel) {
    let mat = Material {
        young_modulus: 3000.0,
        poisson_ratio: nu,
        density: 1000.0,
    };
    let n = mesh.tets.len();
    (
        ElasticModel::new(mesh, vec![mat], vec![0; n]),
        ElasticModel::with_formulation(mesh, vec![mat], vec![0; n], Formulation::Corotational),
    )
}

fn max_norm(v: &[Vector3<f64>]) -> f64 {
    v.iter().map(|v| v.norm()).fold(0.0, f64::max)
}

/// The linear model's `K u` at `x`.
fn linear_force(model: &ElasticModel, x: &[Point3<f64>]) -> Vec<Vector3<f64>> {
    let u: Vec<_> = x.iter().zip(&model.rest).map(|(x, r)| x - r).collect();
    let mut out = vec![Vector3::zeros(); u.len()];
    model.stiffness.mul(&u, &mut out);
    out
}

/// The corotational model's `Σ R K (Rᵀ x − X)` at `x`, from rest rotations.
fn corotational_force(model: &ElasticModel, x: &[Point3<f64>]) -> Vec<Vector3<f64>> {
    let mut c = model.corotated().unwrap();
    let mut out = vec![Vector3::zeros(); x.len()];
    c.force(model, x, &mut out);
    out
}

/// A smooth, non-affine field of size about `scale` (SOFA liver units).
fn wobble(p: &Point3<f64>, scale: f64) -> Vector3<f64> {
    scale
        * Vector3::new(
            (0.7 * p.y).sin(),
            (0.5 * p.z + 0.3 * p.x).cos() - 1.0,
            0.2 * p.x * p.y,
        )
}

/// The mesh's rest points wobbled by `scale` and then turned by the rotation whose
/// axis-angle vector is `turn`: a large rotation with a strain on top.
fn turned(mesh: &TetMesh, turn: Vector3<f64>, scale: f64) -> Vec<Point3<f64>> {
    let q = Rotation3::new(turn);
    mesh.positions
        .iter()
        .map(|p| q * (p + wobble(p, scale)))
        .collect()
}

/// `Σ_e R_e K_e R_eᵀ` with `rotation(e)`, built from the element tensors of the
/// turned rest shape `R_e X` (independent of the model's own assembly).
pub(super) fn tangent_at(
    mesh: &TetMesh,
    model: &ElasticModel,
    rotation: impl Fn(usize) -> nalgebra::Matrix3<f64>,
) -> BlockMatrix {
    let mut expected = BlockMatrix::with_pattern(mesh.vertex_count(), &mesh.edges);
    for (e, &t) in mesh.tets.iter().enumerate() {
        let r = rotation(e);
        let turned: Vec<_> = mesh
            .positions
            .iter()
            .map(|p| Point3::from(r * p.coords))
            .collect();
        let (g, v) = shape_gradients(&turned, t);
        let k = tet_stiffness(&g, v, &model.materials[0]);
        for a in 0..4 {
            for b in 0..4 {
                if t[a] <= t[b] {
                    expected.add(t[a], t[b], &k[a][b]);
                }
            }
        }
    }
    expected
}

#[test]
fn a_rigidly_turned_liver_feels_no_elastic_force() {
    // x = Q X + c with Q a 90° rotation: R_e = Q, S = I, no strain, no force. The
    // linear model sees u = (Q − I) X + c and answers with a large force.
    let mesh = liver_mesh();
    let (linear, corot) = models(&mesh, 0.45);
    for axis in [Vector3::x(), Vector3::new(1.0, -2.0, 0.5).normalize()] {
        let q = Rotation3::new(axis * std::f64::consts::FRAC_PI_2);
        let x: Vec<_> = mesh
            .positions
            .iter()
            .map(|p| q * p + Vector3::new(0.3, -1.0, 2.0))
            .collect();
        let f_lin = max_norm(&linear_force(&linear, &x));
        let f_cor = max_norm(&corotational_force(&corot, &x));
        assert!(f_lin > 1e3, "linear force {f_lin}");
        assert!(
            f_cor <= 1e-10 * f_lin,
            "corotational {f_cor} vs linear {f_lin}"
        );
        assert!(corot.strain_energy_at(&x) <= 1e-20 * linear.strain_energy_at(&x));
    }
}

#[test]
fn rotated_tangent_and_offset_give_the_force() {
    // update() writes the force and K̂: K̂ u + o must be that same force (and the
    // kept affine force's rows must be K̂ u + o at any configuration), and K̂ must be
    // the sum of the element tensors of the rotated rest shapes R_e X_e.
    let mesh = liver_mesh();
    let (_, model) = models(&mesh, 0.3);
    let x = turned(&mesh, Vector3::new(0.4, 1.1, -0.3), 0.05);
    let n = x.len();
    let mut c = model.corotated().unwrap();
    let mut force = vec![Vector3::zeros(); n];
    for _ in 0..3 {
        c.update(&model, &x, &mut force);
    }
    // o = Σ_e R_e K_e (R_eᵀ X_e − X_e), from the rotations alone; each row of
    // K̂ u + o, at x and at another configuration y, is the kept affine force's row.
    let mut offset = vec![Vector3::zeros(); n];
    for (e, el) in model.elements.iter().enumerate() {
        let r = c.rotation(e);
        let rs = el.volume * r * el.stress(&r);
        for (&v, g) in el.tet.iter().zip(&el.gradients()) {
            offset[v as usize] += rs * g;
        }
    }
    let scale = max_norm(&force);
    for y in [x.clone(), x.iter().map(|p| p + wobble(p, 0.02)).collect()] {
        let u: Vec<_> = y.iter().zip(&model.rest).map(|(y, r)| y - r).collect();
        let mut ku = vec![Vector3::zeros(); n];
        c.tangent.mul(&u, &mut ku);
        for i in 0..n {
            assert!(
                (ku[i] + offset[i] - c.row(i, &y)).norm() <= 1e-11 * scale,
                "row {i}"
            );
        }
    }
    for (i, f) in force.iter().enumerate() {
        assert!((c.row(i, &x) - f).norm() <= 1e-11 * scale, "row {i}");
    }
    let expected = tangent_at(&mesh, &model, |e| c.rotation(e));
    let top = expected
        .block
        .iter()
        .map(|b| b.abs().max())
        .fold(0.0, f64::max);
    for (got, want) in c.tangent.block.iter().zip(&expected.block) {
        assert!((got - want).abs().max() <= 1e-11 * top);
    }
}

#[test]
fn the_force_on_one_vertex_is_its_row_of_the_whole_force() {
    // What an instrument holding a vertex feels must be the model's own force there:
    // for the corotational model the turned, wobbled liver's force (with rotations
    // extracted afresh), not the linear K u, which differs at the level of the force
    // itself on this turned shape.
    let mesh = liver_mesh();
    let x = turned(&mesh, Vector3::new(0.4, 1.1, -0.3), 0.05);
    let (linear, corot) = models(&mesh, 0.3);
    for model in [&linear, &corot] {
        let mut whole = vec![Vector3::zeros(); x.len()];
        model.negated_elastic_force_at(&x, &mut whole);
        let scale = max_norm(&whole);
        for v in 0..x.len() as u32 {
            let one = model.negated_elastic_force_on(v, &x);
            assert!(
                (one - whole[v as usize]).norm() <= 1e-12 * scale,
                "{:?} vertex {v}: {one} vs {}",
                model.formulation,
                whole[v as usize]
            );
        }
    }
    let (a, b) = (linear_force(&linear, &x), corotational_force(&corot, &x));
    let gap = a
        .iter()
        .zip(&b)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(gap >= 0.1 * max_norm(&b), "gap {gap}");
}

#[test]
fn forces_are_the_gradient_of_the_corotated_energy() {
    // f = −∂W/∂x: a central difference of W along a direction d matches −f · d to
    // the O(δ²) truncation of the difference.
    let mesh = liver_mesh();
    let (_, model) = models(&mesh, 0.45);
    let x = turned(&mesh, Vector3::new(0.0, 0.9, 0.2), 0.1);
    let minus_f = corotational_force(&model, &x);
    let d: Vec<_> = mesh
        .positions
        .iter()
        .map(|p| wobble(p, 1.0) + Vector3::x())
        .collect();
    let delta = 1e-5;
    let shifted =
        |s: f64| -> Vec<Point3<f64>> { x.iter().zip(&d).map(|(x, d)| x + s * delta * d).collect() };
    let dw = (model.strain_energy_at(&shifted(1.0)) - model.strain_energy_at(&shifted(-1.0)))
        / (2.0 * delta);
    let predicted: f64 = minus_f.iter().zip(&d).map(|(f, d)| f.dot(d)).sum();
    assert!(
        (dw - predicted).abs() <= 1e-6 * predicted.abs(),
        "dW {dw} vs f·d {predicted}"
    );
}

#[test]
fn corotational_equals_linear_at_small_displacement() {
    // R = I + O(|∇u|), so the two forces differ by O(|∇u|²) against a force of
    // O(|∇u|): at |∇u| ≈ 1e-8 they agree to about 1e-8, well inside 1e-6.
    let mesh = liver_mesh();
    let (linear, corot) = models(&mesh, 0.45);
    let x: Vec<_> = mesh.positions.iter().map(|p| p + wobble(p, 1e-8)).collect();
    let (a, b) = (linear_force(&linear, &x), corotational_force(&corot, &x));
    let scale = max_norm(&a);
    let diff = a
        .iter()
        .zip(&b)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(
        diff <= 1e-6 * scale,
        "relative difference {:e}",
        diff / scale
    );
}

#[test]
fn explicit_bound_covers_every_rotation() {
    // The rotation-invariant bound must sit above the largest eigenvalue of M⁻¹K̂
    // for a turned, deformed liver (power iteration converges to it from below).
    let mesh = liver_mesh();
    let (_, model) = models(&mesh, 0.49);
    let x = turned(&mesh, Vector3::new(0.7, 0.0, 0.7), 0.2);
    let mut c = model.corotated().unwrap();
    let n = x.len();
    let mut scratch = vec![Vector3::zeros(); n];
    for _ in 0..4 {
        c.update(&model, &x, &mut scratch);
    }
    let lambda = super::tests::largest_scaled_eigenvalue(&c.tangent, &model.mass);
    let bound = model.max_eigenvalue_bound();
    assert!(bound >= lambda, "bound {bound} below {lambda}");
    // And it is not uselessly loose: explicit substeps grow as its square root.
    assert!(bound <= 4.0 * lambda, "bound {bound} far above {lambda}");
}
