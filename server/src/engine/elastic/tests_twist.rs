//! The twist ratio against the energy it comes from: the second derivative of the
//! corotated energy along a twist, by finite differences with the rotation
//! extracted afresh at each point; and the closed forms of a uniform stretch and
//! an inverted element.

use nalgebra::{Matrix3, Rotation3, Vector3};

use super::corotational::Element;
use super::rotation::cold_rotation;
use super::twist::{stretch, twist_ratio, twist_ratio_bound};
use crate::engine::material::Material;

/// An element of volume 1 and Lamé coefficients `λ`, `μ`, vertex 0 at the origin
/// and `g_k = e_k` (so `F` is the matrix of the edges from vertex 0).
pub(super) fn element(lambda: f64, mu: f64) -> Element {
    Element {
        tet: [0, 1, 2, 3],
        g: [Vector3::x(), Vector3::y(), Vector3::z()],
        volume: 1.0,
        lambda,
        mu,
        slot: [0; 10],
    }
}

/// Lamé coefficients of E = 1 and Poisson ratio `nu`.
fn lame(nu: f64) -> (f64, f64) {
    Material {
        young_modulus: 1.0,
        poisson_ratio: nu,
        density: 1.0,
    }
    .lame()
}

/// The corotated energy density `ψ = ½ λ tr²ε + μ ε:ε` at `f`.
fn energy(e: &Element, f: &Matrix3<f64>) -> f64 {
    let eps = e.strain(&cold_rotation(f), f);
    0.5 * e.lambda * eps.trace().powi(2) + e.mu * eps.component_mul(&eps).sum()
}

#[test]
fn a_rotation_has_no_twist_stiffness() {
    let (lambda, mu) = lame(0.49);
    let e = element(lambda, mu);
    for turn in [0.0, 0.3, 2.0, 3.1] {
        let r = *Rotation3::new(Vector3::new(0.2, -1.0, 0.5).normalize() * turn).matrix();
        let ratio = twist_ratio(&e, &stretch(&cold_rotation(&r), &r));
        assert!(ratio <= 1e-12, "turn {turn}: {ratio}");
    }
}

#[test]
fn a_uniform_stretch_has_the_closed_form_ratio_at_any_turn() {
    // F = a I: σ = a, s = (3λ + 2μ)(a − 1), twist 2s/2a.
    for nu in [0.3, 0.45, 0.499] {
        let (lambda, mu) = lame(nu);
        let e = element(lambda, mu);
        for a in [0.3, 0.8, 1.0, 1.5] {
            let exact = (3.0 * lambda + 2.0 * mu) * (a - 1.0f64).abs() / (a * (lambda + 2.0 * mu));
            let q = *Rotation3::new(Vector3::new(0.7, 0.1, -0.4)).matrix();
            let f = q * Matrix3::identity() * a;
            let ratio = twist_ratio(&e, &stretch(&cold_rotation(&f), &f));
            assert!(
                (ratio - exact).abs() <= 1e-9 * exact.max(1.0),
                "ν {nu}, a {a}: {ratio} against {exact}"
            );
        }
    }
}

#[test]
fn an_inverted_element_passes_the_linear_bound_as_its_energy_says() {
    // F = diag(1.2, 0.9, −0.4), turned: inverted, its polar rotation keeps the
    // negative stretch. Each twist eigenvalue (s_i + s_j)/(σ_i + σ_j) is checked
    // against the second difference of the energy along that twist,
    // ψ(F + t U T_ij Vᵀ), T_ij = (e_i e_jᵀ − e_j e_iᵀ)/√2.
    let (lambda, mu) = lame(0.45);
    let e = element(lambda, mu);
    let sigma = [1.2, 0.9, -0.4];
    let u = *Rotation3::new(Vector3::new(0.3, 0.5, -0.2)).matrix();
    let v = *Rotation3::new(Vector3::new(-0.6, 0.1, 0.4)).matrix();
    let f = u * Matrix3::from_diagonal(&Vector3::from(sigma)) * v.transpose();
    let trace = sigma.iter().sum::<f64>() - 3.0;
    let s = sigma.map(|x| lambda * trace + 2.0 * mu * (x - 1.0));
    let h = 1e-4;
    let mut largest: f64 = 0.0;
    for (i, j) in [(0, 1), (0, 2), (1, 2)] {
        let mut t = Matrix3::zeros();
        t[(i, j)] = std::f64::consts::FRAC_1_SQRT_2;
        t[(j, i)] = -std::f64::consts::FRAC_1_SQRT_2;
        let dir = u * t * v.transpose();
        let second = (energy(&e, &(f + dir * h)) - 2.0 * energy(&e, &f)
            + energy(&e, &(f - dir * h)))
            / (h * h);
        let twist = (s[i] + s[j]) / (sigma[i] + sigma[j]);
        assert!(
            (second - twist).abs() <= 1e-4 * twist.abs().max(lambda),
            "pair ({i}, {j}): the energy's {second} against the twist {twist}"
        );
        largest = largest.max(twist.abs());
    }
    let ratio = twist_ratio(&e, &stretch(&cold_rotation(&f), &f));
    assert!((ratio - largest / (lambda + 2.0 * mu)).abs() <= 1e-9 * ratio);
    assert!(ratio > 1.0, "inverted at ν 0.45: {ratio}");
}

#[test]
fn the_cheap_bound_is_never_below_the_ratio() {
    // Turned, stretched, sheared and inverted gradients of every kind.
    for nu in [0.3, 0.45, 0.499] {
        let (lambda, mu) = lame(nu);
        let e = element(lambda, mu);
        for k in 0..2000 {
            let x = k as f64;
            let f = Matrix3::new(
                1.0 + 0.6 * (0.37 * x).sin(),
                0.4 * (1.3 * x).cos(),
                0.3 * (0.71 * x).sin(),
                0.3 * (2.1 * x).sin(),
                1.0 + 0.7 * (0.53 * x).cos(),
                0.4 * (0.9 * x).cos(),
                0.2 * (1.7 * x).cos(),
                0.3 * (0.43 * x).sin(),
                0.9 * (0.29 * x).sin(),
            );
            let s = stretch(&cold_rotation(&f), &f);
            let (ratio, bound) = (twist_ratio(&e, &s), twist_ratio_bound(&e, &s));
            assert!(
                bound >= ratio * (1.0 - 1e-12) || ratio.is_nan(),
                "ν {nu}, case {k}: bound {bound} under the ratio {ratio}"
            );
        }
    }
}
