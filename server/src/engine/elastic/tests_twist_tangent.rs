//! The implicit step's tangent with the twist modes against the Hessian of the
//! corotated energy, taken by central differences of the force with each rotation
//! extracted afresh: exact where every twist is positive, and positive
//! semi-definite where one is not.

use nalgebra::{Matrix3, Point3, Rotation3, Vector3};

use super::corotational::Element;
use super::rotation::cold_rotation;
use super::twist_tangent::TwistTangent;

/// The element of [`tests_twist`](super::tests_twist) with `λ = 4μ` (ν = 0.4).
fn element() -> Element {
    super::tests_twist::element(4.0, 1.0)
}

/// The vertices of the element with deformation gradient `f`.
fn placed(f: &Matrix3<f64>) -> Vec<Point3<f64>> {
    let mut x = vec![Point3::origin()];
    x.extend((0..3).map(|k| Point3::from(f.column(k).into_owned())));
    x
}

/// The negated elastic force on each vertex at `x`, the rotation extracted there.
fn force(e: &Element, x: &[Point3<f64>]) -> Vec<Vector3<f64>> {
    let f = e.deformation_gradient(x);
    let m = e.force_matrix(&cold_rotation(&f), &f);
    let [g1, g2, g3] = e.g;
    [-(g1 + g2 + g3), g1, g2, g3]
        .iter()
        .map(|g| m * g)
        .collect()
}

/// `H d` by central differences of [`force`], and by the frozen tangent `K̂` alone
/// and with the twist modes.
fn products(f: &Matrix3<f64>, d: &[Vector3<f64>]) -> [Vec<Vector3<f64>>; 3] {
    let e = element();
    let x = placed(f);
    const STEP: f64 = 1e-6;
    let shifted =
        |s: f64| -> Vec<Point3<f64>> { x.iter().zip(d).map(|(x, d)| x + s * d).collect() };
    let (plus, minus) = (force(&e, &shifted(STEP)), force(&e, &shifted(-STEP)));
    let exact = plus
        .iter()
        .zip(&minus)
        .map(|(p, m)| (p - m) / (2.0 * STEP))
        .collect();
    let r = cold_rotation(f);
    let mut frozen = vec![Vector3::zeros(); 4];
    e.add_tangent_product(&r, d, &mut frozen);
    let mut twist = TwistTangent::new(1);
    twist.add(&e, &r, f);
    let mut with_twist = frozen.clone();
    twist.mul_add(1.0, d, &mut with_twist);
    [exact, frozen, with_twist]
}

fn distance(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(a, b)| (a - b).norm_squared())
        .sum::<f64>()
        .sqrt()
}

fn norm(a: &[Vector3<f64>]) -> f64 {
    a.iter().map(Vector3::norm_squared).sum::<f64>().sqrt()
}

/// Directions of the vertices' motion: fixed, of every kind (not only twists).
fn directions() -> Vec<Vec<Vector3<f64>>> {
    (0..6)
        .map(|k| {
            (0..4)
                .map(|a| {
                    let t = (k * 4 + a) as f64;
                    Vector3::new(
                        (1.3 * t).sin(),
                        (2.1 * t + 0.4).cos(),
                        (0.7 * t + 1.1).sin(),
                    )
                })
                .collect()
        })
        .collect()
}

/// A rotated stretch `Q₁ diag(s) Q₂ᵀ`.
fn deformed(s: [f64; 3]) -> Matrix3<f64> {
    let q1 = Rotation3::from_euler_angles(0.4, -0.9, 1.3);
    let q2 = Rotation3::from_euler_angles(-0.2, 0.5, 0.8);
    q1.matrix() * Matrix3::from_diagonal(&Vector3::from(s)) * q2.matrix().transpose()
}

#[test]
fn with_positive_twists_the_tangent_is_the_energys_hessian() {
    // Stretched 1.6, 1.3 and 0.9 (tr ε = 0.8): every s_k > 0 and σ_k > 0, so every
    // twist is positive and `K̂` plus them is the whole Hessian. Central differences
    // of step 1e-6 leave about 1e-10 of it.
    let f = deformed([1.6, 1.3, 0.9]);
    for d in directions() {
        let [exact, frozen, with_twist] = products(&f, &d);
        let scale = norm(&exact);
        assert!(
            distance(&with_twist, &exact) <= 1e-7 * scale,
            "with the twists {:e} of {scale}",
            distance(&with_twist, &exact)
        );
        // What the modes add is not round-off: the frozen tangent alone misses it.
        assert!(
            distance(&frozen, &exact) >= 1e-2 * scale,
            "frozen {:e} of {scale}",
            distance(&frozen, &exact)
        );
    }
}

#[test]
fn through_its_flat_state_the_tangent_leaves_out_only_the_negative_twists() {
    // Pressed through the flat state along one axis, as the elements two crossing
    // instruments squeeze (the negative stretch the smallest in size, where the
    // extraction puts it, see `rotation`). With λ = 4, μ = 1,
    // `s_k = 4 (Σσ − 3) + 2 (σ_k − 1)` and `τ_ij = (s_i + s_j)/(σ_i + σ_j)`:
    // - 4.6, −0.3, 0.7 (stretched as well): s = 15.2, 5.4, 7.4, every twist positive
    //   (4.8, 4.3, 32): K is the whole Hessian;
    // - 1.2, −0.65, 1.45 (squeezed): s = −3.6, −7.3, −3.1, every twist negative
    //   (−19.8, −2.5, −13): K is K̂, and the Hessian is indefinite;
    // - 2.5, −0.2, 0.9: s = 3.8, −1.6, 0.6, twists 0.96 and 1.29 join, −1.43 (the
    //   pair −0.2, 0.9) is left out.
    // So along any direction `d`, `dᵀ (H − K) d ≤ 0` (what is left out is negative)
    // and `dᵀ K d ≥ 0`; where a twist is positive, the frozen tangent alone has
    // `dᵀ (H − K̂) d > 0` along some `d`.
    for (s, positive) in [
        ([4.6, -0.3, 0.7], true),
        ([1.2, -0.65, 1.45], false),
        ([2.5, -0.2, 0.9], true),
    ] {
        let f = deformed(s);
        let mut frozen_misses: f64 = 0.0;
        for d in directions() {
            let [exact, frozen, with_twist] = products(&f, &d);
            let dot = |a: &[Vector3<f64>]| -> f64 { a.iter().zip(&d).map(|(a, d)| a.dot(d)).sum() };
            let scale = norm(&exact) * norm(&d);
            assert!(
                dot(&with_twist) >= -1e-12 * scale,
                "{s:?}: dᵀ K d = {}",
                dot(&with_twist)
            );
            assert!(
                dot(&exact) - dot(&with_twist) <= 1e-7 * scale,
                "{s:?}: dᵀ H d = {} above dᵀ K d = {}",
                dot(&exact),
                dot(&with_twist)
            );
            frozen_misses = frozen_misses.max((dot(&exact) - dot(&frozen)) / scale);
        }
        assert_eq!(
            frozen_misses > 1e-2,
            positive,
            "{s:?}: the frozen tangent misses {frozen_misses:e}"
        );
    }
}
