use nalgebra::{Matrix3, Point3, Vector3};

use super::*;
use crate::engine::material::Material;
use crate::engine::testing::{box_mesh, liver_mesh};

fn model_of(mesh: &TetMesh, e: f64, nu: f64) -> ElasticModel {
    let mat = Material {
        young_modulus: e,
        poisson_ratio: nu,
        density: 1000.0,
    };
    ElasticModel::new(mesh, vec![mat], vec![0; mesh.tets.len()])
}

fn matrix_scale(k: &BlockMatrix) -> f64 {
    k.block.iter().map(|b| b.abs().max()).fold(0.0, f64::max)
}

#[test]
fn stored_stiffness_is_the_sum_of_the_element_tensors() {
    // The product with the symmetric block storage equals the product assembled
    // element by element, y = Σ_T K_T u_T, and single rows agree with it.
    let mesh = liver_mesh();
    let model = model_of(&mesh, 3000.0, 0.45);
    let mat = model.materials[0];
    let n = mesh.vertex_count();
    let u: Vec<_> = (0..n)
        .map(|i| Vector3::new((i as f64).sin(), (0.3 * i as f64).cos(), 0.01 * i as f64))
        .collect();
    let mut expected = vec![Vector3::zeros(); n];
    for &t in &mesh.tets {
        let (g, v) = shape_gradients(&mesh.positions, t);
        let k = tet_stiffness(&g, v, &mat);
        for a in 0..4 {
            for b in 0..4 {
                expected[t[a] as usize] += k[a][b] * u[t[b] as usize];
            }
        }
    }
    let mut got = vec![Vector3::zeros(); n];
    model.stiffness.mul(&u, &mut got);
    let scale = expected.iter().map(|v| v.norm()).fold(0.0, f64::max);
    for i in 0..n {
        assert!((got[i] - expected[i]).norm() <= 1e-12 * scale, "row {i}");
        assert!(
            (model.stiffness.row_times(i, &u) - expected[i]).norm() <= 1e-12 * scale,
            "row {i}"
        );
    }
    // Symmetry: vᵀ(K u) = uᵀ(K v).
    let v: Vec<_> = (0..n)
        .map(|i| Vector3::new(0.5, (i % 5) as f64, -(i as f64).cos()))
        .collect();
    let mut kv = vec![Vector3::zeros(); n];
    model.stiffness.mul(&v, &mut kv);
    let (a, b): (f64, f64) = (
        v.iter().zip(&got).map(|(x, y)| x.dot(y)).sum(),
        u.iter().zip(&kv).map(|(x, y)| x.dot(y)).sum(),
    );
    assert!((a - b).abs() <= 1e-12 * a.abs().max(b.abs()));
    // get() sees K_ji = K_ijᵀ.
    let [i, j] = mesh.edges[7];
    assert_eq!(
        model.stiffness.get(j, i).unwrap(),
        model.stiffness.get(i, j).unwrap().transpose()
    );
}

#[test]
fn rigid_motions_cost_no_energy_and_no_force() {
    // Translations and infinitesimal rotations are in the null space of K: Σ_b K_ab = 0
    // and the rotation's strain ½(∇u + ∇uᵀ) vanishes.
    let mesh = liver_mesh();
    let model = model_of(&mesh, 3000.0, 0.3);
    let n = mesh.vertex_count();
    let mut out = vec![Vector3::zeros(); n];
    let omega = Vector3::new(0.3, -0.7, 0.2);
    let translation = Vector3::new(1.0, -2.0, 0.5);
    let u: Vec<_> = model
        .rest
        .iter()
        .map(|x| translation + omega.cross(&x.coords))
        .collect();
    model.stiffness.mul(&u, &mut out);
    let u_norm = u.iter().map(|v| v.norm()).fold(0.0, f64::max);
    let f_max = out.iter().map(|v| v.norm()).fold(0.0, f64::max);
    assert!(
        f_max <= 1e-11 * matrix_scale(&model.stiffness) * u_norm,
        "rigid force {f_max}"
    );
}

#[test]
fn affine_field_has_the_exact_strain_energy() {
    // For u = G X the strain is uniform, ε = sym G, and the energy is exactly
    // Vol · (λ/2 (tr ε)² + μ ε:ε) on any mesh of P1 elements.
    for mesh in [liver_mesh(), box_mesh([3, 2, 2], [0.1, 0.05, 0.04])] {
        let (e, nu) = (5000.0, 0.45);
        let model = model_of(&mesh, e, nu);
        let g = Matrix3::new(0.01, 0.002, -0.003, 0.0, -0.02, 0.004, 0.001, 0.0, 0.015);
        let u: Vec<_> = model.rest.iter().map(|x| g * x.coords).collect();
        let volume: f64 = mesh
            .tets
            .iter()
            .map(|&t| TetMesh::six_volume(&mesh.positions, t) / 6.0)
            .sum();
        let eps = 0.5 * (g + g.transpose());
        let (l, m) = Material {
            young_modulus: e,
            poisson_ratio: nu,
            density: 1.0,
        }
        .lame();
        let exact = volume * (0.5 * l * eps.trace().powi(2) + m * eps.component_mul(&eps).sum());
        let w = model.strain_energy(&u);
        assert!((w - exact).abs() <= 1e-10 * exact, "energy {w} vs {exact}");
    }
}

#[test]
fn lumped_masses_sum_to_the_body_mass() {
    let mesh = liver_mesh();
    let model = model_of(&mesh, 3000.0, 0.3);
    let volume: f64 = mesh
        .tets
        .iter()
        .map(|&t| TetMesh::six_volume(&mesh.positions, t) / 6.0)
        .sum();
    let total: f64 = model.mass.iter().sum();
    assert!((total - 1000.0 * volume).abs() <= 1e-12 * total);
    assert!(model.mass.iter().all(|&m| m > 0.0));
}

#[test]
fn region_materials_scale_their_own_tensors() {
    // Doubling E in the tetrahedra of one region doubles exactly their contribution:
    // the energy of a field splits as W = W_rest + W_region.
    let mesh = box_mesh([2, 2, 2], [1.0, 1.0, 1.0]);
    let soft = Material {
        young_modulus: 1000.0,
        poisson_ratio: 0.3,
        density: 1.0,
    };
    let stiff = Material {
        young_modulus: 2000.0,
        ..soft
    };
    let region: Vec<u16> = (0..mesh.tets.len())
        .map(|t| u16::from(t % 3 == 0))
        .collect();
    let only_region: Vec<u16> = region.clone();
    let u: Vec<_> = mesh
        .positions
        .iter()
        .map(|p| Vector3::new(p.y * p.z, 0.1 * p.x, -p.x * p.y))
        .collect();
    let uniform = ElasticModel::new(&mesh, vec![soft], vec![0; mesh.tets.len()]).strain_energy(&u);
    let mixed = ElasticModel::new(&mesh, vec![soft, stiff], region).strain_energy(&u);
    let region_only = ElasticModel::new(
        &mesh,
        vec![
            Material {
                young_modulus: 0.0,
                ..soft
            },
            soft,
        ],
        only_region,
    )
    .strain_energy(&u);
    assert!((mixed - (uniform + region_only)).abs() <= 1e-12 * mixed);
    assert!(region_only > 0.0 && region_only < uniform);
}

#[test]
fn gershgorin_bound_covers_the_largest_eigenvalue() {
    // Power iteration on M^{-½} K M^{-½} converges to λ_max from below; the bound must
    // sit above whatever it reaches.
    let mesh = liver_mesh();
    let model = model_of(&mesh, 3000.0, 0.49);
    let lambda = largest_scaled_eigenvalue(&model.stiffness, &model.mass);
    let bound = model.max_eigenvalue_bound();
    assert!(
        bound >= lambda,
        "bound {bound} below power estimate {lambda}"
    );
}

#[test]
fn von_mises_of_uniaxial_stress_is_the_stress() {
    // Uniaxial stress σ along x: ε_xx = σ/E, ε_yy = ε_zz = −ν σ/E; σ_vM = σ.
    let mesh = box_mesh([1, 1, 1], [1.0, 1.0, 1.0]);
    let mat = Material {
        young_modulus: 4000.0,
        poisson_ratio: 0.45,
        density: 1.0,
    };
    let sigma = 120.0;
    let (ex, et) = (sigma / 4000.0, -0.45 * sigma / 4000.0);
    for &t in &mesh.tets {
        let (g, _) = shape_gradients(&mesh.positions, t);
        let u = t.map(|i| {
            let p: Point3<f64> = mesh.positions[i as usize];
            Vector3::new(ex * p.x, et * p.y, et * p.z)
        });
        let von_mises = von_mises_of_strain(&small_strain(&g, u), &mat);
        assert!((von_mises - sigma).abs() <= 1e-9 * sigma);
    }
}

/// The largest eigenvalue of M^{-1/2} K M^{-1/2} (K a block matrix, M the lumped
/// masses), by 2,000 steps of power iteration from a fixed start.
pub(super) fn largest_scaled_eigenvalue(k: &BlockMatrix, mass: &[f64]) -> f64 {
    let n = mass.len();
    let s: Vec<f64> = mass.iter().map(|m| 1.0 / m.sqrt()).collect();
    let mut v: Vec<_> = (0..n)
        .map(|i| Vector3::new(1.0, (i % 7) as f64, -((i % 3) as f64)))
        .collect();
    let mut w = vec![Vector3::zeros(); n];
    let mut lambda = 0.0;
    for _ in 0..2000 {
        let scaled: Vec<_> = v.iter().zip(&s).map(|(x, s)| x * *s).collect();
        k.mul(&scaled, &mut w);
        w.iter_mut().zip(&s).for_each(|(x, s)| *x *= *s);
        let norm = w.iter().map(|x| x.norm_squared()).sum::<f64>().sqrt();
        lambda = v.iter().zip(&w).map(|(a, b)| a.dot(b)).sum::<f64>()
            / v.iter().map(|x| x.norm_squared()).sum::<f64>();
        v.iter_mut().zip(&w).for_each(|(a, b)| *a = b / norm);
    }
    lambda
}
