//! Stress recovery for output.

use nalgebra::{Matrix3, Point3, Vector3};

use crate::engine::material::Material;

/// The small strain of a tetrahedron whose vertices are displaced by `u` (m), given
/// its shape-function gradients `g`: linear elements have constant strain,
/// `ε = sym(Σ_k u_k g_kᵀ)`.
pub fn small_strain(g: &[Vector3<f64>; 4], u: [Vector3<f64>; 4]) -> Matrix3<f64> {
    let mut grad = Matrix3::zeros();
    for k in 0..4 {
        grad += u[k] * g[k].transpose();
    }
    0.5 * (grad + grad.transpose())
}

/// Displacements of a tetrahedron's vertices: `x_k − X_k`.
pub fn tet_displacements(
    x: &[Point3<f64>],
    rest: &[Point3<f64>],
    t: [u32; 4],
) -> [Vector3<f64>; 4] {
    t.map(|i| x[i as usize] - rest[i as usize])
}

/// Von Mises equivalent stress (Pa) of a small strain `ε` in `material`:
/// `σ = λ tr(ε) I + 2μ ε`, `σ_vM = √(3/2 s:s)` with `s` the deviator of `σ`. It does
/// not depend on the frame `ε` is written in.
pub fn von_mises_of_strain(eps: &Matrix3<f64>, material: &Material) -> f64 {
    let (lambda, mu) = material.lame();
    let sigma = Matrix3::identity() * (lambda * eps.trace()) + 2.0 * mu * eps;
    let s = sigma - Matrix3::identity() * (sigma.trace() / 3.0);
    (1.5 * s.component_mul(&s).sum()).sqrt()
}
