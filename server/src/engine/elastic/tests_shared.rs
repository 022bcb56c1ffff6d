//! The product and the corotational update shared among threads by parts give the
//! sequential results: to the last bit with one part, and to round-off with several,
//! whoever runs each part.

use nalgebra::{Point3, Rotation3, Vector3};

use super::tests_corotational::models;
use super::*;
use crate::engine::mesh::reverse_cuthill_mckee;
use crate::engine::testing::liver_mesh;
use crate::engine::workers::Workers;

/// SOFA's liver renumbered for locality, as a scene on several threads loads it.
pub(super) fn liver() -> TetMesh {
    let file = liver_mesh();
    file.renumbered(&reverse_cuthill_mckee(file.vertex_count(), &file.edges))
}

/// A turned, stretched and wobbled configuration of `mesh` (every element rotated
/// and strained differently).
fn deformed(mesh: &TetMesh, turn: f64) -> Vec<Point3<f64>> {
    let q = Rotation3::new(Vector3::new(0.3, turn, -0.2));
    mesh.positions
        .iter()
        .map(|p| q * (p + 0.04 * Vector3::new((3.0 * p.y).sin(), (2.0 * p.z).cos(), p.x.sin())))
        .collect()
}

/// A vector of `n` entries of every size and sign, and the implicit step's mass
/// term `a_i` and scale `s` for `a ∘ u + s K u`.
pub(super) fn product_case(
    n: usize,
) -> (Vec<Vector3<f64>>, impl Fn(usize) -> f64 + Sync + Copy, f64) {
    let u = (0..n)
        .map(|i| Vector3::new((i as f64).sin(), (0.7 * i as f64).cos(), 1e-3 * i as f64))
        .collect();
    (u, |i: usize| 0.5 + (i % 7) as f64, 0.25)
}

fn max_gap(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max)
}

fn max_norm(a: &[Vector3<f64>]) -> f64 {
    a.iter().map(|a| a.norm()).fold(0.0, f64::max)
}

/// Round-off bound for sums taken in another order: a few ulps of the largest
/// term, which for a row of about fifteen blocks is far below 1e-12 of it.
const REORDERED: f64 = 1e-12;

#[test]
fn the_shared_product_is_the_sequential_one() {
    let mesh = liver();
    let (model, _) = models(&mesh, 0.45);
    let k = &model.stiffness;
    let n = mesh.vertex_count();
    let (u, a, s) = product_case(n);
    // The sequential product and its mass term, as the implicit step formed them.
    let mut sequential = vec![Vector3::zeros(); n];
    k.mul(&u, &mut sequential);
    for (i, o) in sequential.iter_mut().enumerate() {
        *o = a(i) * u[i] + s * *o;
    }
    let crew = Workers::new(3).unwrap();
    for count in [1, 2, 3, 5] {
        let parts = Parts::new(n, count, std::iter::empty());
        let mut alone = vec![Vector3::zeros(); n];
        k.mul_shared(None, &parts, a, s, &u, &mut alone);
        if count == 1 {
            assert_eq!(alone, sequential, "one part is the sequential product");
        }
        let gap = max_gap(&alone, &sequential);
        assert!(
            gap <= REORDERED * max_norm(&sequential),
            "{count} parts: {gap:e}"
        );
        for _ in 0..20 {
            let mut shared = vec![Vector3::repeat(f64::NAN); n];
            k.mul_shared(Some(&crew), &parts, a, s, &u, &mut shared);
            assert_eq!(shared, alone, "{count} parts: the same whoever runs them");
        }
    }
}

#[test]
fn the_shared_update_is_the_sequential_one() {
    let mesh = liver();
    let (_, model) = models(&mesh, 0.45);
    let n = mesh.vertex_count();
    let crew = Workers::new(2).unwrap();
    let tets = || model.elements.iter().map(|e| e.tet);
    // Kept tangent: the second and third configurations turn some elements past
    // the threshold and not others.
    let turn = TANGENT_TURN;
    let states = [
        deformed(&mesh, 0.9),
        deformed(&mesh, 0.9005),
        deformed(&mesh, 0.95),
    ];
    let mut reference = model.corotated().unwrap();
    let mut force_ref = vec![Vector3::zeros(); n];
    let mut runs: Vec<(Corotated, Option<&Workers>)> = [1usize, 2, 4]
        .into_iter()
        .flat_map(|count| {
            let mut c = model.corotated().unwrap();
            c.set_parts(Parts::new(n, count, tets()));
            [(c.clone(), None), (c, Some(&crew))]
        })
        .collect();
    let mut force = vec![Vector3::zeros(); n];
    for x in &states {
        reference.update_tangent_within(&model, x, &mut force_ref, turn);
        let scale_f = max_norm(&force_ref);
        let scale_k = reference
            .tangent
            .block
            .iter()
            .map(|b| b.norm())
            .fold(0.0, f64::max);
        for (k, (c, workers)) in runs.iter_mut().enumerate() {
            c.update_shared(&model, x, &mut force, turn, *workers);
            assert!(
                max_gap(&force, &force_ref) <= REORDERED * scale_f,
                "run {k}: force"
            );
            let gap = c
                .tangent
                .block
                .iter()
                .zip(&reference.tangent.block)
                .map(|(a, b)| (a - b).norm())
                .fold(0.0, f64::max);
            assert!(gap <= REORDERED * scale_k, "run {k}: K̂ off by {gap:e}");
            assert_eq!(c.reassembled(), reference.reassembled(), "run {k}");
            for e in 0..model.elements.len() {
                assert_eq!(c.rotation(e), reference.rotation(e), "run {k}: element {e}");
            }
            let mut f = vec![Vector3::zeros(); n];
            c.force_shared(&model, x, &mut f, *workers);
            assert!(
                max_gap(&f, &force_ref) <= REORDERED * scale_f,
                "run {k}: force()"
            );
        }
    }
    assert!(reference.reassembled() > 0);
}
