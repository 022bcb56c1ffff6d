//! The stiffness tensors of one tetrahedron.

use nalgebra::{Matrix3, Point3, Vector3};

use crate::engine::material::Material;

/// Gradients `g_k = ∇N_k` (1/m) of the four linear shape functions of tetrahedron `t`,
/// and its volume `V` (m³).
///
/// With `D = [p₁ − p₀, p₂ − p₀, p₃ − p₀]` (edge vectors as columns), the barycentric
/// coordinates of a point `x` are `(N₁, N₂, N₃) = D⁻¹ (x − p₀)` and `N₀ = 1 − N₁ − N₂ − N₃`,
/// so `g₁, g₂, g₃` are the rows of `D⁻¹` and `g₀ = −(g₁ + g₂ + g₃)`. `V = det D / 6`;
/// tetrahedra are positively oriented after loading, so `det D > 0`.
pub fn shape_gradients(positions: &[Point3<f64>], t: [u32; 4]) -> ([Vector3<f64>; 4], f64) {
    let p = t.map(|i| positions[i as usize]);
    let d = Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]);
    let volume = d.determinant() / 6.0;
    let inv = d
        .try_inverse()
        .expect("mesh loading rejects degenerate tetrahedra");
    let g1 = inv.row(0).transpose();
    let g2 = inv.row(1).transpose();
    let g3 = inv.row(2).transpose();
    ([-(g1 + g2 + g3), g1, g2, g3], volume)
}

/// The 4×4 tensors `K_ab` (N/m) of one linear-elastic tetrahedron.
///
/// With displacement gradient `∇u = Σ_k u_k g_kᵀ`, strain `ε = ½(∇u + ∇uᵀ)` and energy
/// `W = V (½ λ (tr ε)² + μ ε:ε)`, the Hessian block of `W` between vertices `a` and `b` is
///
/// `K_ab = V (λ g_a g_bᵀ + μ g_b g_aᵀ + μ (g_a · g_b) I)`
///
/// (the tensor-mass "edge tensor" of Cotin et al. 1999, written with shape-function
/// gradients instead of face area vectors `m_k = −6V g_k`). `K_ba = K_abᵀ`, and
/// `Σ_b K_ab = 0` because `Σ_b g_b = 0`: a rigid translation costs no energy.
pub fn tet_stiffness(
    g: &[Vector3<f64>; 4],
    volume: f64,
    material: &Material,
) -> [[Matrix3<f64>; 4]; 4] {
    let (lambda, mu) = material.lame();
    let mut k = [[Matrix3::zeros(); 4]; 4];
    for a in 0..4 {
        for b in 0..4 {
            k[a][b] = volume
                * (lambda * g[a] * g[b].transpose()
                    + mu * g[b] * g[a].transpose()
                    + Matrix3::identity() * (mu * g[a].dot(&g[b])));
        }
    }
    k
}
